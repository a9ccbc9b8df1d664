"""Lowering of a checked :class:`~ybg.compiler.ir.Program` to the view-model
that the ROS 2 templates print.

The generated node runs on the Python runtime library (inputs, freshness,
converters, timing, shutdown), as the ``py`` backend's module does, and
adds the ROS 2 side: topics read as mux inputs, and a typed message filled
field by field. This module
decides, for every field of the message, which Python expression fills it
and with which Python type (``float`` for float fields, ``int``, ``bool``,
``str``, lists for arrays, nested messages assigned member by member), and
whether a size check is needed at run time. A Bottle output (ROS 2 topics to
a YARP port) is built by the lowering library's Bottle builder
(:mod:`ybg.lower.python`), as the ``py`` backend's is, so that both give the
same Bottle.

Every value from the config reaches the generated source through
:func:`~ybg.lower.python.py_literal`; every identifier made from a
config name is checked (:func:`~ybg.lower.rosnames.identifier`) or used only inside a literal.
"""

from __future__ import annotations

import keyword
from dataclasses import dataclass

from ybg.compiler import ir
from ybg.lower.errors import Line, LoweringError
from ybg.lower.package import PackageView
from ybg.lower.qos import checked_qos
from ybg.lower.python import (BottleBuilder, InputView, MuxView, OutputView, RuntimeImport, bottle_output,
                              converter_views, py_literal, runtime_imports, timing_summary)
from ybg.lower.rosnames import (identifier, node_name, node_parameters, package_name, ros2_type_name, split_type,
                                used_packages)
from ybg.lower.tree import check_size, slice_stop
from ybg.lower.wire import WIRE_YARP
from ybg.lower.compose import config_file

#: Python conversion of one value of a ROS primitive field (the name of a
#: helper of the generated node, or a builtin)
SCALAR_CONVERSION: dict[str, str] = {
    "float32": "float", "float64": "float",
    "int8": "int", "uint8": "int", "int16": "int", "uint16": "int",
    "int32": "int", "uint32": "int", "int64": "int", "uint64": "int",
    "char": "int", "byte": "byte", "bool": "bool", "string": "str",
}

#: Python conversion of the values of an array field of a ROS primitive
ARRAY_CONVERSION: dict[str, str] = {
    "float32": "floats", "float64": "floats",
    "int8": "ints", "uint8": "ints", "int16": "ints", "uint16": "ints",
    "int32": "ints", "uint32": "ints", "int64": "ints", "uint64": "ints",
    "char": "ints", "byte": "byte_list", "bool": "bools", "string": "strs",
}

#: ROS 2 QoS policies of the IR, as rclpy enum members
RELIABILITY = {"reliable": "RELIABLE", "best_effort": "BEST_EFFORT"}
DURABILITY = {"volatile": "VOLATILE", "transient_local": "TRANSIENT_LOCAL"}

_TIME_TYPES = ("builtin_interfaces/Time", "time")

#: the message published beside a camera image
CAMERA_INFO_TYPE = "sensor_msgs/CameraInfo"


# --------------------------------------------------------------------------
# view-model


@dataclass(frozen=True)
class MsgImport:
    """``from <module> import <name> as <alias>``."""

    module: str
    name: str
    alias: str


def _qos_profile(qos: ir.QoS | None, span) -> str:
    """The QoSProfile of a topic input whose mux asks one (Python source), else "None"."""
    if qos is None:
        return "None"
    qos = checked_qos(qos, span)
    return (f"QoSProfile(history=HistoryPolicy.KEEP_LAST, depth={int(qos.depth)}, "
            f"reliability=ReliabilityPolicy.{RELIABILITY[qos.reliability]}, "
            f"durability=DurabilityPolicy.{DURABILITY[qos.durability]})")


@dataclass(frozen=True)
class TopicInputView:
    """A ROS 2 topic read by a mux: its message class and numeric leaves."""

    mux: str
    index: int
    msg_class: str
    leaves: str
    each: str = "None"  # the array of messages whose elements give one row each
    qos: str = "None"  # the QoS its mux asks (a QoSProfile expression), else the runtime's INPUT_QOS


@dataclass(frozen=True)
class QosView:
    reliability: str
    durability: str
    depth: int


@dataclass(frozen=True)
class RosOutputView:
    msg_class: str
    type_name: str
    topic: str
    qos: QosView


@dataclass(frozen=True)
class CameraInfoView:
    """The CameraInfo published beside each image: its topic, its message
    class and the body of the function that builds it (constants only)."""

    topic: str
    msg_class: str
    builder: tuple[Line, ...]


@dataclass(frozen=True)
class ImageOutputView:
    """A YARP port of camera images."""

    port: str
    connect_to: str


@dataclass(frozen=True)
class NodeView:
    """Everything the node template prints."""

    filename: str
    config: str
    module: str
    node_name: str
    default_prefix: str
    summary: tuple[str, ...]
    imports: tuple[MsgImport, ...]
    muxes: tuple[MuxView, ...]
    topic_inputs: tuple[TopicInputView, ...]
    needed: str
    rate: str
    default_rate: str
    trigger: str
    queue: str
    on_stale: str
    on_nan: str
    publish: str
    output_kind: str
    ros_output: RosOutputView | None
    yarp_output: OutputView | None
    wire: tuple[tuple[str, str], ...]
    builder: tuple[Line, ...]
    uses_rows: bool = False  # the message holds a mux of rows: import the runtime's Rows
    runtime_imports: tuple[RuntimeImport, ...] = ()
    camera_info: CameraInfoView | None = None  # beside a ROS 2 image
    image_output: ImageOutputView | None = None  # a YARP port of camera images

    @property
    def topic_qos(self) -> bool:
        """Does a mux of ROS 2 topics ask its own QoS?"""
        return any(t.qos != "None" for t in self.topic_inputs)


# --------------------------------------------------------------------------
# names


def msg_alias(msg_type: str) -> str:
    """The name the node imports a message class as: ``ros_<pkg>_<Name>``;
    the prefix keeps it clear of every name of the runtime."""
    pkg, name = split_type(msg_type)
    return identifier(f"ros_{pkg}_{name}", "message class")


def _attr(expr: str, name: str) -> str:
    """``expr.name``, or ``getattr(expr, 'name')`` for a name that is not
    a plain identifier (a field named like a Python keyword)."""
    if name.isidentifier() and name.isascii() and not keyword.iskeyword(name):
        return f"{expr}.{name}"
    return f"getattr({expr}, {py_literal(name)})"


def _path(expr: str, dotted: str) -> str:
    for part in dotted.split("."):
        expr = _attr(expr, part)
    return expr


def _assign(expr: str, dotted: str, value: str) -> str:
    *parents, last = dotted.split(".")
    for part in parents:
        expr = _attr(expr, part)
    if last.isidentifier() and last.isascii() and not keyword.iskeyword(last):
        return f"{expr}.{last} = {value}"
    return f"setattr({expr}, {py_literal(last)}, {value})"


# --------------------------------------------------------------------------
# values


def _coerce(value, base: str):
    """A literal of the config as the Python value a ``base`` field holds."""
    if base in ir.FLOAT_TYPES:
        return float(value)
    if base == "bool":
        return bool(value)
    if base == "string":
        return str(value)
    if base in ir.NUMERIC_TYPES:
        if isinstance(value, float) and not value.is_integer():
            raise LoweringError(f"{value!r} is not an integer, for a {base} field")
        return int(value)
    raise LoweringError(f"no literal of type {base!r}")


def _literal_text(value, base: str) -> str:
    v = _coerce(value, base)
    if base == "byte":
        if not 0 <= v <= 255:
            raise LoweringError(f"{v} is not a byte")
        return f"bytes(({v:d},))"
    return py_literal(v)


class _MessageBuilder:
    """Writes the body of ``build_message`` for a typed ROS 2 message: one
    assignment per field that the config sets (the others keep the
    message's defaults)."""

    def __init__(self, program: ir.Program):
        self.program = program
        self.lines: list[Line] = []
        self.muxes: list[str] = []
        self.element_types: list[str] = []  # of the arrays of messages, to import
        self.uses_images = False  # a camera frame fills an Image: the runtime's fill_image
        self.uses_context = False  # a counter, a clock, a stamp: not a constant message

    def emit(self, text: str) -> None:
        self.lines.append(Line(1, text))

    def mux_values(self, name: str) -> str:
        self.program.mux(name)  # KeyError for an unknown mux: the IR is broken
        if name not in self.muxes:
            self.muxes.append(name)
        return f"v[{py_literal(name)}]"

    def mux_numbers(self, name: str) -> str:
        """The values of a mux of numbers (not camera frames)."""
        if self.program.mux(name).image is not None:
            raise LoweringError(f"mux {name} holds camera frames, not numbers: it fills the data of a "
                                f"{ir.IMAGE_TYPE}")
        return self.mux_values(name)

    def message(self, struct: ir.Struct, msg_class: str) -> None:
        self.emit(f"msg = {msg_class}()")
        self.fields(struct, "msg", "")
        self.emit("return msg")

    def fields(self, struct: ir.Struct, target: str, prefix: str) -> None:
        if any(isinstance(f.source, ir.ImageFrame) for f in struct.fields):
            self.check_image(struct, prefix)
        for f in struct.fields:
            self.field(f, target, prefix)

    def check_image(self, struct: ir.Struct, prefix: str) -> None:
        """A sensor_msgs/Image whose data is a frame: the frame gives the
        size, encoding, endianness and step too, which the config leaves."""
        if struct.msg_type != ir.IMAGE_TYPE:
            raise LoweringError(f"a camera frame fills a {ir.IMAGE_TYPE}, not {prefix or 'a '}{struct.msg_type}",
                                struct.span)
        for f in struct.fields:
            if f.name in ir.FRAME_FIELDS and not isinstance(f.source, ir.Default):
                raise LoweringError(f"field {prefix}{f.name}: the frame gives it", f.span)
            if isinstance(f.source, ir.ImageFrame) and f.name != "data":
                raise LoweringError(f"field {prefix}{f.name}: a camera frame goes into data", f.span)

    def field(self, f: ir.Field, target: str, prefix: str) -> None:
        try:
            self._field(f, target, prefix)
        except LoweringError as e:
            raise e.at(f.span)

    def _field(self, f: ir.Field, target: str, prefix: str) -> None:
        name = prefix + f.name
        src, typ = f.source, f.type
        if typ is None:
            raise LoweringError(f"field {name}: a ROS 2 message field needs its type")
        if isinstance(src, ir.Default):
            return  # the message's own default
        if isinstance(src, ir.Struct):
            if typ.array is not None or not typ.is_message:
                raise LoweringError(f"field {name}: a nested message for a {typ} field")
            self.fields(src, _attr(target, f.name), name + ".")
            return
        if isinstance(src, ir.MuxRef) and src.into_fields is not None:
            self.into_fields(src, typ, _attr(target, f.name), name)
            return
        if isinstance(src, ir.MessageArray):
            self.message_array(src, typ, target, f.name, name)
            return
        if isinstance(src, ir.ImageFrame):
            mux = self.program.mux(src.mux)
            if mux.image != src.encoding:
                raise LoweringError(f"field {name}: mux {src.mux} holds no camera frames in {src.encoding}")
            self.uses_images = True
            self.emit(f"fill_image({target}, {self.mux_values(src.mux)}, {py_literal(src.encoding)})")
            return
        self.emit(_assign(target, f.name, self.value(src, typ, name)))

    def message_array(self, src: ir.MessageArray, typ: ir.TypeRef, target: str, field: str, name: str) -> None:
        """One new message per element, then each element's fields."""
        if typ.array is None or not typ.is_message or typ.base != src.msg_type:
            raise LoweringError(f"field {name}: an array of {src.msg_type} for a {typ} field")
        check_size(typ, len(src.elements), f"field {name}")
        if src.msg_type not in self.element_types:
            self.element_types.append(src.msg_type)
        cls = msg_alias(src.msg_type)
        n = len(src.elements)
        self.emit(_assign(target, field, f"[{cls}() for _ in range({n:d})]" if n else "[]"))
        element_type = ir.TypeRef(src.msg_type)
        for k, element in enumerate(src.elements):
            item, where = f"{_attr(target, field)}[{k:d}]", f"{name}[{k:d}]"
            if isinstance(element, ir.Struct):
                self.fields(element, item, where + ".")
            elif isinstance(element, ir.MuxRef) and element.into_fields is not None:
                self.into_fields(element, element_type, item, where)
            else:
                raise LoweringError(f"field {where}: an element is a message or a mux filling one")

    def into_fields(self, ref: ir.MuxRef, typ: ir.TypeRef, target: str, name: str) -> None:
        if typ.array is not None or not typ.is_message:
            raise LoweringError(f"field {name}: mux fields into a {typ} field")
        values = self.mux_numbers(ref.mux)
        types = ref.into_types or (ref.element_type,) * len(ref.into_fields or ())
        if len(types) != len(ref.into_fields or ()):
            raise LoweringError(f"field {name}: {len(types)} types for {len(ref.into_fields)} fields")
        if ref.stop is not None and ref.stop - ref.start != len(types):
            raise LoweringError(f"field {name}: {ref.stop - ref.start} values for {len(types)} fields")
        for k, (leaf, t) in enumerate(zip(ref.into_fields or (), types)):
            conv = SCALAR_CONVERSION.get(t)
            if conv is None:
                raise LoweringError(f"field {name}.{leaf}: no conversion to {t}")
            self.emit(_assign(target, leaf, f"{conv}({values}[{ref.start + k:d}])"))

    def value(self, src, typ: ir.TypeRef, name: str) -> str:
        base = typ.base
        if isinstance(src, ir.Timestamp):
            if base not in _TIME_TYPES or typ.array is not None:
                raise LoweringError(f"field {name}: a timestamp into a {typ} field")
            if src.clock == "envelope":
                if src.mux is None:
                    raise LoweringError(f"field {name}: an envelope timestamp names its mux")
                self.mux_values(src.mux)
                self.uses_context = True
                return f"stamps.envelope({py_literal(src.mux)})"
            self.uses_context = True
            return "stamps.now()"
        if typ.is_message or base in ("time", "duration"):
            raise LoweringError(f"field {name}: cannot fill a {typ} field from {type(src).__name__}")
        if isinstance(src, ir.Literal):
            return self.literal(src, typ, name)
        if isinstance(src, ir.MuxRef):
            return self.mux_ref(src, typ, name)
        if isinstance(src, ir.Counter):
            self.uses_context = True
            if base in ir.INTEGER_TYPES and typ.array is None:
                # wrapped like an integer of the field's type, as on every backend
                return self.scalar(typ, f"ctx.count({py_literal(base)})", name)
            return self.scalar(typ, "ctx.counter", name)
        if isinstance(src, ir.Seconds):
            self.uses_context = True
            return self.scalar(typ, "stamps.seconds", name)
        raise LoweringError(f"field {name}: unknown source {type(src).__name__}")

    def scalar(self, typ: ir.TypeRef, expr: str, name: str) -> str:
        if typ.array is not None:
            raise LoweringError(f"field {name}: one value for the array field {typ}")
        conv = SCALAR_CONVERSION.get(typ.base)
        if conv is None:
            raise LoweringError(f"field {name}: no conversion to {typ.base}")
        return f"{conv}({expr})"

    def literal(self, lit: ir.Literal, typ: ir.TypeRef, name: str) -> str:
        if not lit.is_list:
            if len(lit.values) != 1:
                raise LoweringError(f"field {name}: a scalar literal holds exactly one value")
            if typ.array is not None:
                raise LoweringError(f"field {name}: one value for the array field {typ}")
            return _literal_text(lit.values[0], typ.base)
        if typ.array is None:
            raise LoweringError(f"field {name}: a list for the scalar field {typ}")
        check_size(typ, len(lit.values), f"field {name}")
        return "[" + ", ".join(_literal_text(v, typ.base) for v in lit.values) + "]"

    def mux_ref(self, ref: ir.MuxRef, typ: ir.TypeRef, name: str) -> str:
        values = self.mux_numbers(ref.mux)
        if ref.index is not None:
            return self.scalar(typ, f"{values}[{ref.index:d}]", name)
        if typ.array is None:
            raise LoweringError(f"field {name}: a list of mux values for the scalar field {typ}")
        conv = ARRAY_CONVERSION.get(typ.base)
        if conv is None:
            raise LoweringError(f"field {name}: no conversion to {typ.base}[]")
        stop = slice_stop(self.program, ref, typ, name)
        if stop is not None:
            if ref.start == 0 and stop == self.program.mux(ref.mux).width:
                part = values
            else:
                part = f"{values}[{ref.start:d}:{stop:d}]"
            return f"{conv}({part})"
        # the width is known only at run time: the runtime's take() refuses a
        # slice beyond the mux's current width (never shortened), as in every backend
        if ref.stop is not None:
            part = f"take({values}, {ref.start:d}, {ref.stop:d})"
        elif ref.start:
            part = f"take({values}, {ref.start:d}, None)"
        else:
            part = values
        expr = f"{conv}({part})"
        if typ.array == "fixed" and typ.size is not None and ref.stop is None:
            expr = f"sized({expr}, {typ.size:d}, {py_literal(name)})"
        elif typ.array == "sequence" and typ.size is not None and ref.stop is None:
            expr = f"bounded({expr}, {typ.size:d}, {py_literal(name)})"
        return expr


# --------------------------------------------------------------------------
# the node


def _image_input(m: ir.Mux, i: ir.Input, k: int, topics: list, imports: dict) -> str:
    """A camera image input (a YARP port of frames, or a ROS 2 topic of
    sensor_msgs/Image): the mux's one input, no converters; its description."""
    if len(m.inputs) != 1 or m.converters:
        raise LoweringError(f"mux {m.name}: a camera image is the mux's one input, with no converter", m.span)
    if i.kind == "yarp":
        if i.image not in ir.IMAGE_ENCODINGS:
            raise LoweringError(f"the YARP port {i.name}: no pixel type {i.image!r}", i.span)
        desc = f"yarp {i.name}: camera images, {i.image} (YARP {ir.IMAGE_ENCODINGS[i.image]})"
        if i.accepts:
            desc += f"; also from {', '.join(i.accepts)}"
        return desc
    if i.kind != "ros2" or i.ros_type != ir.IMAGE_TYPE or i.image != ir.ANY_ENCODING:
        raise LoweringError(f"the input {i.name}: camera images come from a YARP port or a ROS 2 "
                            f"{ir.IMAGE_TYPE} topic", i.span)
    alias = msg_alias(i.ros_type)
    pkg, name = split_type(i.ros_type)
    imports[alias] = MsgImport(f"{pkg}.msg", name, alias)
    topics.append(TopicInputView(py_literal(m.name), k, alias, py_literal(()), qos=_qos_profile(i.qos, i.span)))
    return (f"ROS 2 topic {i.name} ({ros2_type_name(i.ros_type)}): camera images of any encoding YARP "
            f"has a pixel type for")


def _lower_inputs(program: ir.Program):
    muxes: list[MuxView] = []
    topics: list[TopicInputView] = []
    imports: dict[str, MsgImport] = {}
    used: set[str] = set()
    for m in program.muxes:
        inputs = []
        for k, i in enumerate(m.inputs):
            types = i.element_types
            width = "any number of numbers" if types is None else f"{len(types)} elements"
            if i.image is not None:
                desc = _image_input(m, i, k, topics, imports)
            elif i.kind == "ros2":
                if not i.ros_type:
                    raise LoweringError(f"the ROS 2 input {i.name} has no message type", i.span)
                if not i.fields:
                    raise LoweringError(f"the ROS 2 input {i.name} names no numeric field", i.span)
                try:
                    for leaf in i.fields:
                        for part in leaf.split("."):
                            identifier(part, f"field of {i.ros_type}")
                except LoweringError as e:
                    raise e.at(i.span)
                alias = msg_alias(i.ros_type)
                pkg, name = split_type(i.ros_type)
                imports[alias] = MsgImport(f"{pkg}.msg", name, alias)
                if i.each is not None:
                    identifier(i.each, f"field of {i.ros_type}")
                topics.append(TopicInputView(py_literal(m.name), k, alias, py_literal(tuple(i.fields)),
                                             py_literal(i.each), _qos_profile(i.qos, i.span)))
                desc = f"ROS 2 topic {i.name} ({ros2_type_name(i.ros_type)} {', '.join(i.fields)}): {width}"
                if i.each is not None:
                    desc = (f"ROS 2 topic {i.name} ({ros2_type_name(i.ros_type)}): a row of {width} for each "
                            f"element of {i.each} ({', '.join(i.fields)})")
            elif i.kind == "yarp":
                desc = f"yarp {i.name}: {width}"
                if i.reads is not None:
                    desc += f"; the message reads the first {i.reads} (W511)"
                if i.accepts:
                    desc += f"; also from {', '.join(i.accepts)}"
            else:
                raise LoweringError(f"the ros2 backend cannot read a {i.kind!r} input ({i.name})", i.span)
            inputs.append(InputView(
                mux=py_literal(m.name), index=k, source=py_literal(i.name), kind=py_literal(i.kind),
                types=py_literal(types), timeout=py_literal(float(i.timeout)),
                description=py_literal(desc), reads=py_literal(i.reads),
                accepts=py_literal(tuple(i.accepts)), image=py_literal(i.image)))
        convs = converter_views(m, used)
        muxes.append(MuxView(py_literal(m.name), tuple(inputs), convs, py_literal(bool(m.verbose)),
                             py_literal(m.element_types), m.rows))
    return tuple(muxes), tuple(topics), imports, runtime_imports(used)


def lower(program: ir.Program) -> NodeView:
    """The view-model of the node generated for ``program``."""
    muxes, topics, imports, rt_imports = _lower_inputs(program)
    out = program.output
    uses_yarp = out.kind == "yarp" or any(i.kind == "yarp" for m in program.muxes for i in m.inputs)
    if not uses_yarp:
        raise LoweringError("the ros2 backend bridges YARP and ROS 2: this program has no YARP "
                            "port (every input and the output are ROS 2 topics)")
    ros_output = None
    yarp_output = None
    camera_info = None
    image_output = None
    uses_rows = False
    wire: tuple[tuple[str, str], ...] = ()
    if out.kind == "ros2":
        msg_type = out.msg_type or program.message.msg_type
        if not msg_type:
            raise LoweringError("a ROS 2 output needs a message type")
        try:
            alias = msg_alias(msg_type)
            pkg, name = split_type(msg_type)
        except LoweringError as e:
            raise e.at(out.type_span)
        imports[alias] = MsgImport(f"{pkg}.msg", name, alias)
        qos = checked_qos(out.qos or ir.QoS(), out.span)
        ros_output = RosOutputView(
            msg_class=alias, type_name=py_literal(ros2_type_name(msg_type)),
            topic=py_literal(out.name),
            qos=QosView(RELIABILITY[qos.reliability], DURABILITY[qos.durability], int(qos.depth)))
        mb = _MessageBuilder(program)
        mb.message(program.message, alias)
        for element_type in mb.element_types:
            pkg, name = split_type(element_type)
            imports[msg_alias(element_type)] = MsgImport(f"{pkg}.msg", name, msg_alias(element_type))
        builder, needed = tuple(mb.lines), tuple(mb.muxes)
        desc = f"{ros2_type_name(msg_type)} on the ROS 2 topic {out.name}"
        if out.camera_info is not None:
            if not mb.uses_images:
                raise LoweringError("a CameraInfo goes beside a camera image", out.camera_info.span)
            camera_info = _camera_info(program, out.camera_info, imports)
            desc += f", with {ros2_type_name(CAMERA_INFO_TYPE)} on {out.camera_info.topic}"
        if mb.uses_images:
            names = "CameraInfoOutput, fill_image" if camera_info is not None else "fill_image"
            rt_imports += (RuntimeImport("ros2_io", names),)
    elif out.kind == "yarp" and out.image is not None:
        mux = program.mux(out.image)
        if mux.image is None:
            raise LoweringError(f"mux {out.image} holds no camera images", out.span)
        image_output = ImageOutputView(py_literal(out.name), py_literal(out.connect_to))
        builder = (Line(1, f"return frame_out(v[{py_literal(out.image)}], ctx)"),)
        needed = (out.image,)
        rt_imports += (RuntimeImport("images", "YarpImageOutput, frame_out"),)
        desc = f"camera images on the YARP port {out.name}"
        if out.connect_to:
            desc += f", connected to {out.connect_to}"
    elif out.kind == "yarp":
        yarp_output = bottle_output(program, "ros2")
        bb = BottleBuilder(program)
        bb.struct(program.message, program.message.msg_type or out.msg_type, 1, "return ", "")
        builder, needed = tuple(bb.lines), tuple(bb.muxes)
        uses_rows = bb.uses_rows
        wire = tuple((py_literal(k), py_literal(v)) for k, v in sorted(WIRE_YARP.items()))
        desc = f"untyped Bottles on the YARP port {out.name}" if not out.msg_type else \
            f"{out.msg_type} Bottles on the YARP port {out.name}"
        if out.connect_to:
            desc += f", connected to {out.connect_to}"
    else:
        raise LoweringError(f"the ros2 backend cannot publish to a {out.kind!r} output")

    n_in = sum(len(m.inputs) for m in program.muxes)
    name = node_name(program)
    summary = (
        py_literal(f"ROS 2 node {name}: {n_in} input(s) in {len(program.muxes)} mux(es)"),
        py_literal(desc),
        py_literal(timing_summary(program)),
    )
    config_name = config_file(program)
    rate = program.timing.rate
    return NodeView(
        filename=f"{identifier(program.module, 'module name')}_node.py",
        config=py_literal(config_name),
        module=py_literal(program.module),
        node_name=py_literal(name),
        default_prefix=py_literal("/" + program.module),
        summary=summary,
        imports=tuple(imports[k] for k in sorted(imports)),
        muxes=muxes,
        topic_inputs=topics,
        needed=py_literal(needed),
        rate=py_literal(None if rate is None else float(rate)),
        default_rate=py_literal(0.0 if rate is None else float(rate)),
        trigger=py_literal(program.timing.trigger),
        queue=py_literal(int(program.timing.queue)),
        on_stale=py_literal(program.policy.on_stale),
        on_nan=py_literal(program.policy.on_nan),
        publish=py_literal(program.timing.publish),
        output_kind=py_literal(out.kind),
        ros_output=ros_output,
        yarp_output=yarp_output,
        wire=wire,
        builder=builder,
        uses_rows=uses_rows,
        runtime_imports=rt_imports,
        camera_info=camera_info,
        image_output=image_output,
    )


def _camera_info(program: ir.Program, info: ir.CameraInfo, imports: dict) -> CameraInfoView:
    """The CameraInfo beside the image: a message of constants (the runtime
    gives it the image's header and fits it to each frame's size)."""
    if info.message.msg_type not in (None, CAMERA_INFO_TYPE):
        raise LoweringError(f"a CameraInfo is a {CAMERA_INFO_TYPE}, not {info.message.msg_type}", info.span)
    alias = msg_alias(CAMERA_INFO_TYPE)
    pkg, name = split_type(CAMERA_INFO_TYPE)
    imports[alias] = MsgImport(f"{pkg}.msg", name, alias)
    mb = _MessageBuilder(program)
    try:
        mb.message(info.message, alias)
    except LoweringError as e:
        raise e.at(info.span)
    if mb.muxes or mb.uses_context or mb.uses_images or mb.element_types:
        raise LoweringError("the fields of a CameraInfo are constants (its header is the image's)", info.span)
    return CameraInfoView(topic=py_literal(info.topic), msg_class=alias, builder=tuple(mb.lines))


def lower_package(program: ir.Program, view: NodeView) -> PackageView:
    """The view-model of the ament_python package around the node."""
    pkg = package_name(program.module)
    config_name = config_file(program)
    out = program.output
    if out.kind == "ros2":
        what = f"{ros2_type_name(out.msg_type or program.message.msg_type or '')} on {out.name}"
    else:
        what = f"the YARP port {out.name}"
    return PackageView(
        config=config_name,
        package=pkg,
        node_module=view.filename[: -len(".py")],
        executable=view.filename[: -len(".py")],
        node_name=node_name(program),
        description=f"Bridge between YARP and ROS 2 ({what}), generated by ybgc from {config_name}.",
        depends=("rclpy", "diagnostic_msgs") + tuple(p for p in used_packages(program)
                                                     if p not in ("rclpy", "diagnostic_msgs")),
        launch_file=f"{program.module}.launch.py",
        parameters=node_parameters(program),
    )
