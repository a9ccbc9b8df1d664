"""Lowering of a program whose output is a ROS 2 topic (``via = ros2``) for
the ``cpp`` backend: the module publishes through the rcl C API with the
runtime's ``ybgc_ros2.hpp`` (docs/ros2-native.md).

The module is the one of :mod:`ybg.backends.cpp.lower` (spec, muxes, gather, compute) with
another message builder: :class:`CStructBuilder` fills the message's C struct
(``<pkg>/msg/<name>.h``) field by field, one call of a ``ybgc::ros2`` helper
a field, converting each value as the Python ROS 2 node does (so that both
publish the same message, bit for bit). Fields the config leaves unset keep
the defaults of the message's definition (the C struct's ``__init``). An
array of messages is sized to the elements the config gives (a sequence
through its package's ``pkg__msg__Name__Sequence__init``, which gives each
element its defaults; a fixed-size array is as it is), and each element is
filled as any nested message.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

from ybg.backends.cpp.escape import comment, cpp_float, cpp_identifier, cpp_int, cpp_std_string, cpp_string
from ybg.backends.cpp.lower import BottleBuilder, ModuleView, index_text
from ybg.backends.cpp.lower import lower as lower_module
from ybg.backends.cpp.rcl import RUNTIME_PACKAGES, c_header, c_struct
from ybg.compiler import ir
from ybg.lower.errors import Line, LoweringError
from ybg.lower.qos import checked_qos
from ybg.lower.rosnames import node_name, split_type, used_packages
from ybg.lower.tree import check_size, slice_stop

_TIME_TYPES = ("builtin_interfaces/Time", "time")


@dataclass(frozen=True)
class CameraInfoView:
    """The CameraInfo published beside a ROS 2 image: its topic and the
    lines of the module's ``cameraInfo()``, which fills the config's fields."""

    topic: str               # string literal
    topic_comment: str
    lines: tuple[Line, ...]


@dataclass(frozen=True)
class Ros2View:
    """What the module and its CMakeLists print of the ROS 2 side."""

    include: str            # <pkg>/msg/<name>.h of the output's message
    element_includes: tuple[str, ...]  # those of the elements of its arrays of messages
    c_type: str             # its C struct, pkg__msg__Name
    type_name: str          # string literal "pkg/msg/Name"
    type_support: str       # ROSIDL_GET_MSG_TYPE_SUPPORT(pkg, msg, Name)
    spec: str               # the ybgc::ros2::Ros2Spec aggregate
    spec_comment: str
    packages: tuple[str, ...]  # the message packages to link
    camera_info: CameraInfoView | None = None  # a ROS 2 image's CameraInfo


def _member(name: str) -> str:
    """A field, or a dotted path of fields (``position.x``), as members of a C struct."""
    try:
        return ".".join(cpp_identifier(part) for part in name.split("."))
    except ValueError as e:
        raise LoweringError(f"field {name!r} cannot be a member of a C struct ({e})") from None


def _all_defaults(struct: ir.Struct) -> bool:
    """Does the config leave every field of this nested message unset?"""
    return all(isinstance(f.source, ir.Default) or (isinstance(f.source, ir.Struct) and _all_defaults(f.source))
               for f in struct.fields)


def array_element_types(struct: ir.Struct) -> tuple[str, ...]:
    """The message types of the arrays of messages in ``struct``, nested ones
    too, in order of appearance."""
    out: list[str] = []

    def walk(src) -> None:
        if isinstance(src, ir.Struct):
            for f in src.fields:
                walk(f.source)
        elif isinstance(src, ir.MessageArray):
            if src.msg_type not in out:
                out.append(src.msg_type)
            for element in src.elements:
                walk(element)

    walk(struct)
    return tuple(out)


def _literal(value, base: str) -> str:
    """A constant of the config as a C++ literal of a ``base`` field's kind."""
    if base in ir.FLOAT_TYPES:
        return cpp_float(float(value))
    if base == "bool":
        return "true" if value else "false"
    if base in ir.NUMERIC_TYPES or base in ("byte", "char"):
        if isinstance(value, float) and not value.is_integer():
            raise LoweringError(f"{value!r} is not an integer, for a {base} field")
        return cpp_int(int(value), 64)
    raise LoweringError(f"no literal of type {base!r}")


#: the C++ type of a list of constants of each kind, for ybgc::ros2::setValues
def _value_type(base: str) -> str:
    if base in ir.FLOAT_TYPES:
        return "double"
    if base == "bool":
        return "bool"
    return "std::int64_t"


class CStructBuilder(BottleBuilder):
    """Writes the body of ``buildMessage`` for the message's C struct: the
    Bottle builder's bookkeeping of the muxes the message reads (``mux``,
    ``needed``, ``need_size``) and lines (``lines``), with statements of its own."""

    def line(self, text: str, indent: int = 1) -> None:
        self.emit(indent, text)

    def struct(self, struct: ir.Struct, target: str, depth: int = 0, indent: int = 1) -> None:
        frame = next((f.source for f in struct.fields
                      if f.name == "data" and isinstance(f.source, ir.ImageFrame)), None)
        for f in struct.fields:
            if frame is not None and f.name in ir.FRAME_FIELDS and isinstance(f.source, ir.Default):
                self.line(f"// {comment(f.name)} ({comment(str(f.type))}): from the frame of {comment(frame.mux)}")
                continue
            self.field(f, target)

    def where(self) -> str:
        """The field being built, as the config writes it (``markers[1].points[0]``)."""
        return ".".join(self.path).replace(".[", "[")

    def field(self, f: ir.Field, target: str) -> None:
        self.path.append(f.name)
        try:
            self._field(f, f"{target}.{_member(f.name)}", self.where())
        except LoweringError as e:
            raise e.at(f.span)
        finally:
            self.path.pop()

    def _field(self, f: ir.Field, target: str, name: str) -> None:
        src, typ = f.source, f.type
        if typ is None:
            raise LoweringError(f"field {name}: a ROS 2 message field needs its type")
        what = f"// {comment(name)} ({comment(str(typ))})"
        if isinstance(src, ir.Default):
            self.line(f"{what}: the definition's default")
            return
        if isinstance(src, ir.Struct):
            if typ.array is not None or not typ.is_message:
                raise LoweringError(f"field {name}: a nested message for a {typ} field")
            if _all_defaults(src):
                self.line(f"{what}: the definition's defaults")
            else:
                self.struct(src, target)
            return
        if isinstance(src, ir.MessageArray):
            self.message_array(src, typ, target, name)
            return
        if isinstance(src, ir.ImageFrame):
            self.image_frame(src, typ, target, name)
            return
        if not typ.is_message and typ.base not in ir.ELEMENT_TYPES and typ.base not in _TIME_TYPES:
            raise LoweringError(f"field {name}: the C++ module cannot fill a {typ.base} field")
        self.line(what)
        if isinstance(src, ir.MuxRef) and src.into_fields is not None:
            self.into_fields(src, typ, target, name)
        elif isinstance(src, ir.Timestamp):
            self.timestamp(src, typ, target, name)
        elif typ.is_message or typ.base in ("time", "duration"):
            raise LoweringError(f"field {name}: cannot fill a {typ} field from {type(src).__name__}")
        elif isinstance(src, ir.Literal):
            self.literal(src, typ, target, name)
        elif isinstance(src, ir.MuxRef):
            self.mux_ref(src, typ, target, name)
        elif isinstance(src, (ir.Counter, ir.Seconds)):
            if typ.array is not None:
                raise LoweringError(f"field {name}: one value for the array field {typ}")
            if isinstance(src, ir.Counter):
                value, text = "ctx.counter", "std::to_string(ctx.counter)"
            else:
                value, text = "ctx.seconds", "ybgc::reprFloat(ctx.seconds)"
            if typ.base == "string":
                self.line(f"ybgc::ros2::setString({target}, {text});")
            else:
                self.line(f"ybgc::ros2::assign({target}, {value});")
        else:
            raise LoweringError(f"field {name}: unknown source {type(src).__name__}")

    def image_frame(self, src: ir.ImageFrame, typ: ir.TypeRef, target: str, name: str) -> None:
        """The `data` of a sensor_msgs/Image from the frame of an image mux,
        which gives its height, width, encoding, is_bigendian and step too."""
        if (name != "data" or typ.base != "uint8" or typ.array != "sequence" or not target.endswith(".data")
                or self.program.mux(src.mux).image != src.encoding or src.encoding not in ir.IMAGE_ENCODINGS):
            raise LoweringError(f"field {name}: the frame of mux {src.mux} fills the data of a sensor_msgs/Image")
        frame = self.mux(src.mux)
        self.line(f"// {comment(name)} ({comment(str(typ))}): the frame of {comment(src.mux)}, "
                  f"{comment(src.encoding)}, its rows without YARP's padding")
        self.line(f"if (!ybgc::images::setImage({target[:-len('.data')]}, {frame}, {cpp_string(src.encoding)})) {{")
        self.line("return false;", 2)
        self.line("}")

    def message_array(self, src: ir.MessageArray, typ: ir.TypeRef, target: str, name: str) -> None:
        """A sequence sized to the elements the config gives (kept when it has
        them: the count is the config's), a fixed-size array as it is; then
        each element, a nested message or a mux filling one."""
        if typ.array is None or not typ.is_message or typ.base != src.msg_type:
            raise LoweringError(f"field {name}: an array of {src.msg_type} for a {typ} field")
        check_size(typ, len(src.elements), f"field {name}")
        n = len(src.elements)
        self.line(f"// {comment(name)} ({comment(str(typ))}): {n:d} element{'' if n == 1 else 's'}")
        if typ.array == "fixed":
            items = [f"{target}[{k:d}]" for k in range(n)]
        else:
            seq = c_struct(src.msg_type) + "__Sequence"
            self.line(f"ybgc::ros2::resize({target}, {n:d}, &{seq}__init,")
            self.line(f"                   &{seq}__fini);")
            items = [f"{target}.data[{k:d}]" for k in range(n)]
        element_type = ir.TypeRef(src.msg_type)
        for k, (element, item) in enumerate(zip(src.elements, items)):
            self.path.append(f"[{k:d}]")
            try:
                if isinstance(element, ir.Struct):
                    self.struct(element, item)
                elif isinstance(element, ir.MuxRef) and element.into_fields is not None:
                    self.line(f"// {comment(self.where())} ({comment(src.msg_type)})")
                    self.into_fields(element, element_type, item, self.where())
                else:
                    raise LoweringError(f"field {self.where()}: an element is a message or a mux filling one")
            finally:
                self.path.pop()

    def into_fields(self, ref: ir.MuxRef, typ: ir.TypeRef, target: str, name: str) -> None:
        if typ.array is not None or not typ.is_message:
            raise LoweringError(f"field {name}: mux fields into a {typ} field")
        leaves = ref.into_fields or ()
        if ref.stop is not None and ref.stop - ref.start != len(leaves):
            raise LoweringError(f"field {name}: {ref.stop - ref.start} values for {len(leaves)} fields")
        values = self.mux(ref.mux, ref.start + len(leaves))
        for k, leaf in enumerate(leaves):
            self.line(f"ybgc::ros2::set({target}.{_member(leaf)}, {values}[{ref.start + k:d}]);")

    def timestamp(self, src: ir.Timestamp, typ: ir.TypeRef, target: str, name: str) -> None:
        if typ.base not in _TIME_TYPES or typ.array is not None:
            raise LoweringError(f"field {name}: a timestamp into a {typ} field")
        self.line(f"ybgc::ros2::setTime({target}, {self.stamp_ns(src)});")

    def literal(self, lit: ir.Literal, typ: ir.TypeRef, target: str, name: str) -> None:
        if not lit.is_list:
            if len(lit.values) != 1:
                raise LoweringError(f"field {name}: a scalar literal holds exactly one value")
            if typ.array is not None:
                raise LoweringError(f"field {name}: one value for the array field {typ}")
            if typ.base == "string":
                self.line(f"ybgc::ros2::setString({target}, {cpp_std_string(str(lit.values[0]))});")
            else:
                self.line(f"ybgc::ros2::assign({target}, {_literal(lit.values[0], typ.base)});")
            return
        if typ.array is None:
            raise LoweringError(f"field {name}: a list for the scalar field {typ}")
        check_size(typ, len(lit.values), f"field {name}")
        if not lit.values:
            self.line(f"ybgc::ros2::resize({target}, 0);")
        elif typ.base == "string":
            items = ", ".join(cpp_std_string(str(v)) for v in lit.values)
            self.line(f"ybgc::ros2::setStrings({target}, {{{items}}});")
        else:
            items = ", ".join(_literal(v, typ.base) for v in lit.values)
            self.line(f"ybgc::ros2::setValues<{_value_type(typ.base)}>({target}, {{{items}}});")

    def mux_ref(self, ref: ir.MuxRef, typ: ir.TypeRef, target: str, name: str) -> None:
        if ref.index is not None:
            if typ.array is not None:
                raise LoweringError(f"field {name}: one value for the array field {typ}")
            values = self.mux(ref.mux, ref.index + 1)
            self.line(f"ybgc::ros2::set({target}, {values}[{ref.index:d}]);")
            return
        if typ.array is None:
            raise LoweringError(f"field {name}: a list of mux values for the scalar field {typ}")
        slice_stop(self.program, ref, typ, name)
        # a slice needs its end (or, open-ended, its start) within the mux: never shortened
        values = self.mux(ref.mux, ref.start if ref.stop is None else ref.stop)
        bound = typ.size if typ.array == "sequence" and typ.size is not None else 0
        self.line(f"if (!ybgc::ros2::setRange({target}, {values}, {index_text(ref.start)}, "
                  f"{index_text(ref.stop)}, {bound:d})) {{")
        self.line("return false;", 2)
        self.line("}")


def ros2_view(program: ir.Program) -> Ros2View:
    out = program.output
    msg_type = out.msg_type or program.message.msg_type
    if not msg_type:
        raise LoweringError("a ROS 2 output needs its message type", out.type_span)
    try:
        pkg, name = split_type(msg_type)
        # the packages of the elements of its arrays of messages (the module calls their functions)
        elements = array_element_types(program.message)
        # and those of the runtime: builtin_interfaces (stamps), rosgraph_msgs (/clock, use_sim_time),
        # diagnostic_msgs and std_msgs (/diagnostics)
        packages = tuple(sorted(set(used_packages(program)) | {split_type(t)[0] for t in elements}
                                | set(RUNTIME_PACKAGES)))
    except LoweringError as e:
        raise e.at(out.type_span)
    qos = checked_qos(out.qos or ir.QoS(), out.span)
    node = node_name(program)
    spec = (f"{{{cpp_string(out.name)}, {cpp_string(node)}, {'true' if qos.reliability == 'reliable' else 'false'}, "
            f"{'true' if qos.durability == 'transient_local' else 'false'}, {int(qos.depth):d}}}")
    return Ros2View(
        include=c_header(msg_type),
        element_includes=tuple(sorted({c_header(t) for t in elements} - {c_header(msg_type)})),
        c_type=c_struct(msg_type),
        type_name=cpp_string(f"{pkg}/msg/{name}"),
        type_support=f"ROSIDL_GET_MSG_TYPE_SUPPORT({pkg}, msg, {name})",
        spec=spec,
        spec_comment=(f"{{topic, node, reliable, transient_local, depth}}: {qos.reliability}, "
                      f"{qos.durability}, depth {int(qos.depth):d}"),
        packages=packages,
    )


def camera_info_view(program: ir.Program) -> CameraInfoView | None:
    """The CameraInfo beside a ROS 2 image (``[camera_info]``): its fields
    are constants of the config, its header the image's (left to the runtime)."""
    info = program.output.camera_info
    if info is None:
        return None
    if program.output.msg_type != ir.IMAGE_TYPE or not any(
            f.name == "data" and isinstance(f.source, ir.ImageFrame) for f in program.message.fields):
        raise LoweringError("a CameraInfo goes beside a sensor_msgs/Image filled from a frame", info.span)
    fields = tuple(f for f in info.message.fields if f.name != "header")
    b = CStructBuilder(program, {}, {})
    try:
        b.struct(ir.Struct(fields, info.message.msg_type), "info")
    except LoweringError as e:
        raise e.at(info.span)
    if b.needed:
        raise LoweringError("the fields of a CameraInfo are constants", info.span)
    return CameraInfoView(cpp_string(info.topic), comment(info.topic), tuple(b.lines))


def lower(program: ir.Program) -> ModuleView:
    """The view-model of the module generated for ``program``, whose output is a ROS 2 topic."""
    if program.output.kind != "ros2":
        raise LoweringError(f"not a ROS 2 output: {program.output.kind!r}")
    view = lower_module(program, builder=CStructBuilder)
    ros_args = cpp_string("ROS arguments after --ros-args (-p use_sim_time:=true: stamps from /clock)")
    ros2 = dataclasses.replace(ros2_view(program), camera_info=camera_info_view(program))
    return dataclasses.replace(view, ros2=ros2, message_cpp="Message", description=view.description + (ros_args,))


__all__ = ["CStructBuilder", "CameraInfoView", "Ros2View", "array_element_types", "lower", "ros2_view"]
