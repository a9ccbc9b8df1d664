"""Lowering of a checked :class:`~ybg.compiler.ir.Program` to the view-model
that the C++ templates print.

Every decision is taken here: the C++ name of each mux, the Bottle tag of
every value (which differs between an untyped YARP output and a ROS 1
topic), the statements that build the message, which muxes gate publishing,
where each field of a ROS 1 input sits in the Bottle YARP reads. Every value
taken from the config reaches the C++ text through :mod:`.escape`; the
templates only print what this module hands them.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ybg.backends.cpp import ros2_inputs as readers
from ybg.backends.cpp.escape import (comment, cpp_float, cpp_identifier, cpp_int, cpp_std_string, cpp_string,
                                     mangle)
from ybg.compiler import ir
from ybg.lower.errors import Line, LoweringError
from ybg.lower.tree import TIME_TYPES, coerce, default_scalar, nest_fields, time_style
from ybg.lower.wire import WIRE_ROS1 as _WIRE_ROS1
from ybg.lower.wire import WIRE_YARP as _WIRE_YARP
from ybg.lower.wire import has_fixed_array, has_message_array, ros1_shape
from ybg.lower.compose import config_file

if TYPE_CHECKING:
    from ybg.backends.cpp.ros2 import Ros2View

#: The runtime's `Wire` enumerator of each element type (the shared tables of
#: ybg.backends, in C++ spelling: "float64" -> "Float64").
WIRE_YARP: dict[str, str] = {k: v.capitalize() for k, v in _WIRE_YARP.items()}
WIRE_ROS1: dict[str, str] = {k: v.capitalize() for k, v in _WIRE_ROS1.items()}

#: C++ type a counter is cast to before it is written (it wraps like the ROS type)
CPP_INT_TYPES: dict[str, str] = {
    "int8": "std::int8_t", "uint8": "std::uint8_t", "int16": "std::int16_t",
    "uint16": "std::uint16_t", "int32": "std::int32_t", "uint32": "std::uint32_t",
    "int64": "std::int64_t", "uint64": "std::uint64_t", "byte": "std::int8_t",
    "char": "std::uint8_t", "bool": "bool",
}

_WIRE_BITS = {"Int8": 8, "Int16": 16, "Int32": 32, "Int64": 64}
#: target names CMake keeps for itself
_CMAKE_RESERVED = frozenset({"all", "clean", "help", "install", "test", "package", "package_source",
                             "edit_cache", "rebuild_cache", "list_install_components", "depend",
                             "preinstall", "install_strip", "install_local"})


# --------------------------------------------------------------------------
# view-model


@dataclass(frozen=True)
class InputView:
    index: int           # position in BridgeSpec::inputs
    initializer: str     # the InputSpec aggregate
    comment: str


@dataclass(frozen=True)
class MuxView:
    member: str               # C++ member of struct Muxes
    name: str                 # string literal of the mux name
    comment: str
    gather: tuple[Line, ...]  # statements of gather()
    verbose: bool
    cpp_type: str = "ybgc::Mux"  # ybgc::Rows: a row for each element of an array of messages


@dataclass(frozen=True)
class ModuleView:
    filename: str
    target: str
    executable: str
    config_comment: str
    header: tuple[str, ...]          # comment lines (already safe)
    spec_module: str
    spec_config: str
    description: tuple[str, ...]     # string literals
    default_prefix: str
    muxes: tuple[MuxView, ...]
    inputs: tuple[InputView, ...]
    needed: str
    output: str
    output_comment: str
    rate: str
    rate_comment: str
    trigger_all: str
    queue: str
    hold: str
    drop_nan: str
    new_only: str
    msg_comment: str
    builder: tuple[Line, ...]
    sizes: str
    ros1: bool                       # uses YARP's ROS 1 support (output or an input)
    ros2: "Ros2View | None" = None   # publishes to ROS 2 through rcl (.ros2)
    message_cpp: str = "yarp::os::Bottle"  # the C++ type buildMessage fills
    ros2_inputs: "readers.Ros2InputsView | None" = None  # reads ROS 2 topics through rcl (.ros2_inputs)
    images: bool = False             # reads or writes camera images (the runtime's ybgc_images.hpp)
    image_output: str | None = None  # a YARP port of images: the index of the input whose frames it writes

    @property
    def uses_ros2(self) -> bool:
        """Does the module use rcl (a ROS 2 output or input)?"""
        return self.ros2 is not None or self.ros2_inputs is not None or self.images

    @property
    def ros2_packages(self) -> tuple[str, ...]:
        """The message packages to link (those of the output's message, the inputs' and the runtime's)."""
        return self.ros2.packages if self.ros2 is not None else self.ros2_inputs.packages if self.ros2_inputs else ()


# --------------------------------------------------------------------------
# helpers


def geometry_enumerator(name: str) -> str:
    """The runtime's ``ybgc::Geometry`` enumerator of a geometry converter:
    its name in CamelCase (``quat_normalize`` -> ``QuatNormalize``)."""
    return "".join(part.capitalize() for part in name.split("_"))


#: expression function -> C++ function (the runtime's where C++ has none)
_CPP_FUNCTIONS = {"abs": "std::fabs", "min": "ybgc::minOf", "max": "ybgc::maxOf", "clamp": "ybgc::clamp",
                  "sqrt": "std::sqrt", "sin": "std::sin", "cos": "std::cos", "atan2": "std::atan2"}


def cpp_expression(node: ir.ExprNode, top: bool = True) -> str:
    """C++ source of a checked expression of ``double x``: the operations of
    the Python module's, in the same order (every operation parenthesised)."""
    op = node.op
    if op == "number":
        return cpp_float(float(node.value))  # type: ignore[arg-type]
    if op == "x":
        return "x"
    if op == "pi":
        return cpp_float(math.pi)
    if op == "neg":  # `-(-x)`, never `--x` (a decrement)
        inner = node.args[0]
        text = cpp_expression(inner)
        return f"-{text}" if inner.op in ("x", "pi", "number") else f"-({text})"
    if op in ("+", "-", "*", "/"):
        text = f"{cpp_expression(node.args[0], False)} {op} {cpp_expression(node.args[1], False)}"
        return text if top else f"({text})"
    if op not in _CPP_FUNCTIONS:
        raise LoweringError(f"unknown expression function {op!r}")
    return f"{_CPP_FUNCTIONS[op]}({', '.join(cpp_expression(a) for a in node.args)})"


def _converter(target: str, c) -> str:
    """The call of converter ``c`` on the mux (or row) ``target``."""
    if isinstance(c, ir.GeometryConverter):
        axes = cpp_string(c.axes or "xyz")
        return (f"ybgc::convertGeometry({target}, ybgc::Geometry::{geometry_enumerator(c.name)}, {index_text(c.start)}, "
                f"{axes}, {'true' if c.degrees else 'false'});  // {comment(c.text)}")
    if isinstance(c, ir.ExprConverter):
        return (f"ybgc::convertEach({target}, []([[maybe_unused]] double x) {{ return {cpp_expression(c.body)}; }}, "
                f"{index_text(c.start)}, {index_text(c.stop)});  // {comment('expr(' + c.text + ')')}")
    if c.start < 0 or (c.stop is not None and c.stop < c.start):
        raise LoweringError(f"converter {c.name} has the range [{c.start}:{c.stop}]")
    stop = "" if c.stop is None else str(c.stop)
    return (f"ybgc::convert({target}, {cpp_float(float(c.scale))}, {cpp_float(float(c.offset))}, "
            f"{'true' if c.to_float else 'false'}, {index_text(c.start)}, {index_text(c.stop)});"
            f"  // {comment(c.name)}[{c.start}:{stop}]")


def index_text(n: int | None) -> str:
    if n is None:
        return "ybgc::kToEnd"
    if n < 0:
        raise LoweringError(f"negative index {n}")
    return str(int(n))


# --------------------------------------------------------------------------
# the message builder


class BottleBuilder:
    """Writes the body of ``buildMessage`` from the message tree."""

    def __init__(self, program: ir.Program, members: dict[str, str], input_ids: dict[str, list[int]]):
        self.program = program
        self.members = members
        self.input_ids = input_ids
        self.wire = WIRE_ROS1 if program.output.kind == "ros1" else WIRE_YARP
        self.lines: list[Line] = []
        self.needed: list[str] = []
        self.need_size: dict[str, int] = {}
        self.path: list[str] = []  # the field being built, as a path

    def emit(self, indent: int, text: str) -> None:
        if "\n" in text or "\r" in text:
            raise AssertionError("a generated line holds a line break")
        self.lines.append(Line(indent, text))

    def wire_of(self, element_type: str) -> str:
        try:
            return "Wire::" + self.wire[element_type]
        except KeyError:
            raise LoweringError(f"no Bottle tag for element type {element_type!r}") from None

    def mux(self, name: str, need: int = 0) -> str:
        try:
            self.program.mux(name)
            member = self.members[name]
        except KeyError:
            raise LoweringError(f"the message reads an unknown mux {name!r}") from None
        if name not in self.needed:
            self.needed.append(name)
        self.need_size[name] = max(self.need_size.get(name, 0), need)
        return f"mux.{member}"

    # -- values
    def add_value(self, var: str, value, element_type: str) -> str:
        """A statement appending one literal value to ``var``."""
        wire = self.wire.get(element_type)
        if wire is None:
            raise LoweringError(f"no Bottle tag for element type {element_type!r}")
        value = coerce(value, element_type)
        if wire == "String":
            return f"{var}.addString({cpp_std_string(str(value))});"
        if wire == "Float64":
            return f"{var}.addFloat64({cpp_float(float(value))});"
        if wire == "Float32":
            return f"{var}.addFloat32(static_cast<float>({cpp_float(float(value))}));"
        bits = _WIRE_BITS[wire]
        if isinstance(value, float):
            raise LoweringError(f"a float literal for an integer field ({element_type})")
        return f"{var}.add{wire}({cpp_int(int(value), bits)});"

    def struct(self, struct: ir.Struct, parent: str, depth: int, indent: int) -> None:
        for f in struct.fields:
            self.field(f, parent, depth, indent)

    def field(self, f: ir.Field, parent: str, depth: int, indent: int) -> None:
        self.path.append(f.name)
        try:
            self._field(f, parent, depth, indent)
        except LoweringError as e:
            raise e.at(f.span)
        finally:
            self.path.pop()

    def _field(self, f: ir.Field, parent: str, depth: int, indent: int) -> None:
        typ = "" if f.type is None else f" ({comment(str(f.type))})"
        src = f.source
        self.emit(indent, f"// {comment(f.name)}{typ}{self.describe(src)}")
        if isinstance(src, ir.Struct):
            var = f"b{depth + 1}"
            self.emit(indent, "{")
            self.emit(indent + 1, f"yarp::os::Bottle& {var} = {parent}.addList();")
            self.struct(src, var, depth + 1, indent + 1)
            self.emit(indent, "}")
            return
        if isinstance(src, ir.MessageArray):
            self.message_array(src, parent, depth, indent)
            return
        self.source(src, f.type, parent, depth, indent)

    def message_array(self, src: ir.MessageArray, parent: str, depth: int, indent: int) -> None:
        """A list holding one nested list per element."""
        if not src.elements:
            self.emit(indent, f"{parent}.addList();")
            return
        var = f"b{depth + 1}"
        self.emit(indent, "{")
        self.emit(indent + 1, f"yarp::os::Bottle& {var} = {parent}.addList();")
        for k, element in enumerate(src.elements):
            self.field(ir.Field(f"[{k}]", element, ir.TypeRef(src.msg_type)), var, depth + 1, indent + 1)
        self.emit(indent, "}")

    def describe(self, src) -> str:
        if isinstance(src, ir.Counter):
            return ": counter"
        if isinstance(src, ir.Timestamp):
            if src.clock == "envelope":
                return f": envelope stamp of mux {comment(src.mux or '')}"
            return ": wall clock"
        if isinstance(src, ir.Seconds):
            return ": wall clock, seconds"
        if isinstance(src, ir.Default):
            return ": default"
        if isinstance(src, ir.MuxRef):
            if src.index is not None:
                return f": {comment(src.mux)}[{src.index}]"
            stop = "" if src.stop is None else str(src.stop)
            rng = "" if src.start == 0 and src.stop is None else f"[{src.start}:{stop}]"
            return f": {comment(src.mux)}{rng}" + (" (spliced)" if src.splice else "")
        return ""

    def source(self, src, typ: ir.TypeRef | None, parent: str, depth: int, indent: int) -> None:
        if isinstance(src, ir.Literal):
            if not src.is_list:
                if len(src.values) != 1:
                    raise LoweringError("a scalar literal holds exactly one value")
                self.emit(indent, self.add_value(parent, src.values[0], src.element_type))
                return
            self.list_of(parent, depth, indent, [
                (lambda var, v=v: self.add_value(var, v, src.element_type)) for v in src.values])
            return
        if isinstance(src, ir.MuxRef):
            self.mux_ref(src, parent, depth, indent)
            return
        if isinstance(src, ir.Counter):
            ctype = CPP_INT_TYPES.get(src.element_type)
            if ctype is None:
                raise LoweringError(f"a counter cannot be a {src.element_type}")
            self.emit(indent, f"ybgc::putInteger({parent}, static_cast<{ctype}>(ctx.counter), "
                              f"{self.wire_of(src.element_type)});")
            return
        if isinstance(src, ir.Timestamp):
            self.time(parent, self.stamp_ns(src), src.style, indent)
            return
        if isinstance(src, ir.Seconds):
            self.emit(indent, f"{parent}.addFloat64(ctx.seconds);")
            return
        if isinstance(src, ir.Default):
            self.default(typ, parent, depth, indent)
            return
        if isinstance(src, ir.ImageFrame):
            raise LoweringError(f"the frames of mux {src.mux} go to a ROS 2 sensor_msgs/Image, not into a Bottle")
        raise LoweringError(f"unknown source {type(src).__name__}")

    def stamp_ns(self, src: ir.Timestamp) -> str:
        """The C++ expression of a timestamp, in nanoseconds since the epoch."""
        if src.clock == "envelope":
            if src.mux is None:
                raise LoweringError("an envelope timestamp names its mux")
            self.mux(src.mux)
            ids = ", ".join(str(i) for i in self.input_ids[src.mux])
            return f"ctx.envelopeNs({{{ids}}})"
        if src.clock == "wall":
            return "ctx.wallNs"
        raise LoweringError(f"unknown clock {src.clock!r}")

    def time(self, parent: str, ns: str, style: str, indent: int) -> None:
        if style == "ros2":
            sec, nsec = self.wire_of("int32"), self.wire_of("uint32")
        elif style == "ros1":
            sec, nsec = self.wire_of("uint32"), self.wire_of("uint32")
        else:
            raise LoweringError(f"unknown time style {style!r}")
        self.emit(indent, f"ybgc::putTime({parent}, {ns}, {sec}, {nsec});")

    def list_of(self, parent: str, depth: int, indent: int, statements: list) -> None:
        """A nested list: ``statements`` are functions of the list's variable
        name, each giving the statement that appends one item."""
        if not statements:
            self.emit(indent, f"{parent}.addList();")
            return
        var = f"b{depth + 1}"
        self.emit(indent, "{")
        self.emit(indent + 1, f"yarp::os::Bottle& {var} = {parent}.addList();")
        for statement in statements:
            self.emit(indent + 1, statement(var))
        self.emit(indent, "}")

    def nested(self, parent: str, depth: int, indent: int, tree: list) -> None:
        """A message filled from mux elements (``nest_fields``): a list, and a
        list in it for each sub-message (Pose: position, orientation)."""
        var = f"b{depth + 1}"
        self.emit(indent, "{")
        self.emit(indent + 1, f"yarp::os::Bottle& {var} = {parent}.addList();")
        for _, item in tree:
            if isinstance(item, list):
                self.nested(var, depth + 1, indent + 1, item)
            else:
                values, k, t, path = item
                self.emit(indent + 1, f"ybgc::put({var}, {values}[{k:d}], {self.wire_of(t)});  // {comment(path)}")
        self.emit(indent, "}")

    def mux_ref(self, ref: ir.MuxRef, parent: str, depth: int, indent: int) -> None:
        rows = self.mux(ref.mux)
        if self.program.mux(ref.mux).rows:  # one nested list per row, whole
            if ref.index is not None or ref.start != 0 or ref.stop is not None or ref.into_fields:
                raise LoweringError(f"a part of mux {ref.mux}, which holds rows")
            target = parent if ref.splice else f"{parent}.addList()"
            self.emit(indent, f"ybgc::putRows({target}, {rows}, {self.wire_of(ref.element_type)});")
            return
        if ref.index is not None:
            values = self.mux(ref.mux, ref.index + 1)
            self.emit(indent, f"ybgc::put({parent}, {values}[{ref.index:d}], {self.wire_of(ref.element_type)});")
            return
        if ref.into_fields is not None:
            n = len(ref.into_fields)
            values = self.mux(ref.mux, ref.start + n)
            types = ref.into_types or (ref.element_type,) * n
            self.nested(parent, depth, indent, nest_fields([
                (name, (values, ref.start + k, t, name)) for k, (name, t) in enumerate(zip(ref.into_fields, types))]))
            return
        # a slice needs its end (or, open-ended, its start) within the mux: never shortened
        values = self.mux(ref.mux, ref.start if ref.stop is None else ref.stop)
        mux = self.program.mux(ref.mux)
        et = mux.element_types
        sliced: tuple[str, ...] = ()
        if et is not None:
            stop_i = len(et) if ref.stop is None else min(ref.stop, len(et))
            sliced = tuple(et[ref.start:stop_i])
        if sliced and len(set(sliced)) > 1:
            # a mux that mixes types: each element with its own tag
            statements = [(lambda var, k=k, t=t: f"ybgc::put({var}, {values}[{ref.start + k:d}], {self.wire_of(t)});")
                          for k, t in enumerate(sliced)]
            self.need_size[ref.mux] = max(self.need_size[ref.mux], ref.start + len(sliced))
            if ref.splice:
                for statement in statements:
                    self.emit(indent, statement(parent))
            else:
                self.list_of(parent, depth, indent, statements)
            return
        target = parent if ref.splice else f"{parent}.addList()"
        self.emit(indent, f"ybgc::putRange({target}, {values}, {index_text(ref.start)}, {index_text(ref.stop)}, "
                          f"{self.wire_of(ref.element_type)});")

    def default(self, typ: ir.TypeRef | None, parent: str, depth: int, indent: int) -> None:
        if typ is None:
            raise LoweringError("a default value needs a typed field")
        base = typ.base
        if typ.array == "sequence":
            self.emit(indent, f"{parent}.addList();")
            return
        if base in TIME_TYPES:
            if typ.array is not None:
                raise LoweringError(f"no default for an array of {base}")
            self.time(parent, "0", time_style(base, self.program.ros), indent)
            return
        if typ.is_message:
            raise LoweringError(f"a default {typ} needs its fields; the checker expands nested messages")
        value = default_scalar(base)
        if typ.array == "fixed":
            self.list_of(parent, depth, indent,
                         [lambda var: self.add_value(var, value, base)] * (typ.size or 0))
            return
        self.emit(indent, self.add_value(parent, value, base))


# --------------------------------------------------------------------------
# the module


def _members(program: ir.Program) -> dict[str, str]:
    """C++ member name of each mux: its own name when that is a usable
    identifier, else a mangled ``mux_<name>``; unique."""
    out: dict[str, str] = {}
    used: set[str] = set()
    for m in program.muxes:
        try:
            member = cpp_identifier(m.name)
        except ValueError:
            member = mangle("mux_", m.name)
        base, k = member, 2
        while member in used:
            member = f"{base}_{k}"
            k += 1
        used.add(member)
        out[m.name] = member
    return out


def _layout(inp: ir.Input) -> str:
    if inp.layout is None:
        return "false, {}"
    groups = ", ".join(f"{{{cpp_string(g.type)}, {int(g.count)}}}" for g in inp.layout)
    return f"true, {{{groups}}}"


def _fields(inp: ir.Input, distro: str | None) -> str:
    if inp.kind != "ros1" or not inp.fields:
        return "{}"
    if inp.positions is None or len(inp.positions) != len(inp.fields):
        raise LoweringError(f"input {inp.name}: no Bottle positions for its fields")
    paths = zip(inp.fields, inp.positions)
    items = ", ".join(f"{{{cpp_string(name)}, {{{', '.join(str(int(i)) for i in at)}}}}}" for name, at in paths)
    return f"{{{items}}}"


def _input_comment(mux: str, k: int, inp: ir.Input) -> str:
    if inp.image is not None:
        what = ("camera images, each of its own encoding" if inp.image == ir.ANY_ENCODING
                else f"camera images, {comment(inp.image)}")
    elif inp.layout is None:
        what = "any number of numbers"
    else:
        what = ", ".join(f"{g.type} x{g.count}" for g in inp.layout)
    kind = {"ros1": "ROS 1 topic", "ros2": "ROS 2 topic"}.get(inp.kind, "port")
    extra = f" ({comment(inp.ros_type)})" if inp.ros_type else ""
    reads = "" if inp.reads is None else f"; the message reads the first {inp.reads} (W511)"
    if inp.accepts:
        reads += f"; also from {', '.join(comment(a) for a in inp.accepts)}"
    return f"mux {comment(mux)}, input {k}: {kind} {comment(inp.name)}{extra}, {what}{reads}"


def _encoding(inp: ir.Input) -> str:
    """The encoding of a camera image input's frames, as the runtime's table knows it."""
    if inp.image != ir.ANY_ENCODING and inp.image not in ir.IMAGE_ENCODINGS:
        raise LoweringError(f"input {inp.name}: no YARP pixel type for the encoding {inp.image!r}", inp.span)
    if inp.image == ir.ANY_ENCODING and (inp.kind != "ros2" or inp.ros_type != ir.IMAGE_TYPE):
        raise LoweringError(f"input {inp.name}: images of any encoding come from a ROS 2 sensor_msgs/Image topic",
                            inp.span)
    if inp.image != ir.ANY_ENCODING and inp.kind != "yarp":
        raise LoweringError(f"input {inp.name}: camera images of one encoding come from a YARP port", inp.span)
    return inp.image or ""


def _executable(module: str) -> tuple[str, str]:
    """(CMake target, executable name) for the module."""
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", module):
        raise LoweringError(f"module name {module!r} cannot name an executable")
    target = f"{module}_module" if module.lower() in _CMAKE_RESERVED else module
    return target, module


def lower(program: ir.Program, builder=BottleBuilder) -> ModuleView:
    """The view-model of the module generated for ``program``; ``builder``
    writes the message (a ROS 2 output's: :mod:`.ros2`)."""
    out = program.output
    if out.kind not in ("yarp", "ros1") and builder is BottleBuilder:
        raise LoweringError(f"the cpp backend cannot publish to a {out.kind!r} output")
    target, executable = _executable(program.module)
    members = _members(program)

    # inputs, in mux order; their position is their index in BridgeSpec::inputs
    inputs: list[InputView] = []
    input_ids: dict[str, list[int]] = {}
    mux_views = []
    for mi, m in enumerate(program.muxes):
        ids = []
        # the mux of a camera image holds its one input's frame (ybgc::Frame), assigned by append
        gather = [] if m.image is not None else [Line(1, f"mux.{members[m.name]}.clear();")]
        for k, i in enumerate(m.inputs):
            if i.kind not in ("yarp", "ros1", "ros2"):
                raise LoweringError(f"the cpp backend cannot read a {i.kind!r} input ({i.name})", i.span)
            if not i.timeout > 0:
                raise LoweringError(f"input {i.name} has a timeout of {i.timeout!r}", i.span)
            n = len(inputs)
            ids.append(n)
            kind = {"ros1": "ybgc::InputKind::Ros1", "ros2": "ybgc::InputKind::Ros2"}.get(
                i.kind, "ybgc::InputKind::Yarp")
            reads = ("" if i.reads is None and not i.accepts and i.image is None
                     else f", {-1 if i.reads is None else int(i.reads)}")
            accepts = (f", {{{', '.join(cpp_string(a) for a in i.accepts)}}}" if i.accepts or i.image is not None
                       else "")
            image = "" if i.image is None else f", {cpp_string(_encoding(i))}"
            init = (f"{{{mi}, {k}, {cpp_string(i.name)}, {kind}, {cpp_float(float(i.timeout))}, "
                    f"{_layout(i)}, {_fields(i, program.distro)}{reads}{accepts}{image}}}")
            inputs.append(InputView(n, init, _input_comment(m.name, k, i)))
            gather.append(Line(1, f"ybgc::append(mux.{members[m.name]}, in[{n}]);  // {comment(i.name)}"))
        if m.rows and m.converters:  # each row converted alike
            gather.append(Line(1, f"for (ybgc::Mux& row : mux.{members[m.name]}) {{"))
            gather += [Line(2, _converter("row", c)) for c in m.converters]
            gather.append(Line(1, "}"))
        else:
            gather += [Line(1, _converter(f"mux.{members[m.name]}", c)) for c in m.converters]
        input_ids[m.name] = ids
        srcs = ", ".join(comment(i.name) for i in m.inputs)
        if m.rows:
            srcs += ": a row for each element of its array of messages"
        if m.image is not None:
            if len(m.inputs) != 1 or m.converters:
                raise LoweringError(f"mux {m.name} of camera images reads one input, unconverted", m.span)
            srcs += ": its frame"
        mux_views.append(MuxView(members[m.name], cpp_string(m.name), srcs, tuple(gather), bool(m.verbose),
                                 "ybgc::Frame" if m.image is not None else "ybgc::Rows" if m.rows else "ybgc::Mux"))

    ros2_inputs = None
    if any(i.kind == "ros2" for m in program.muxes for i in m.inputs):
        ros2_inputs = readers.lower(program, members)

    b = builder(program, members, input_ids)
    b.struct(program.message, "msg", 0, 1)
    if out.image is not None:
        b.mux(out.image)  # the port of images writes its frames
    checks: list[Line] = []
    for name in b.needed:
        need = b.need_size.get(name, 0)
        if need > 0:
            checks += [Line(1, f"if (mux.{members[name]}.size() < {need}) {{"),
                       Line(2, "return false;"), Line(1, "}")]
    builder = tuple(checks) + tuple(b.lines)
    needed = [next(k for k, m in enumerate(program.muxes) if m.name == name) for name in b.needed]

    rate = program.timing.rate
    if rate is not None and not rate > 0:
        raise LoweringError(f"rate {rate!r} is not positive")
    if program.timing.trigger not in ("all", "any"):
        raise LoweringError(f"unknown trigger {program.timing.trigger!r}")
    if rate is None and not inputs:
        raise LoweringError("an event-driven bridge needs at least one input (set a rate)")

    image_output = None
    if out.image is not None:  # a YARP port of the frames of an image mux
        if out.kind != "yarp" or out.image not in input_ids or program.mux(out.image).image is None:
            raise LoweringError(f"the output writes the frames of {out.image!r}, which is no mux of camera images",
                                out.span)
        image_output = str(input_ids[out.image][0])
    if out.kind == "ros1":
        node = out.node or f"/yarp/{program.module}"
        port = f"{out.name}@{node}"
        where = f"the ROS 1 topic {comment(out.name)} (port {comment(port)})"
        kind = "ybgc::OutputKind::Ros1"
        plain_where = f"the ROS 1 topic {out.name} (port {port})"
    elif out.kind == "ros2":
        port = out.name
        where = f"the ROS 2 topic {comment(port)}"
        kind = "ybgc::OutputKind::Ros2"
        plain_where = f"the ROS 2 topic {port}"
    else:
        port = out.name
        where = f"the YARP port {comment(port)}"
        kind = "ybgc::OutputKind::Yarp"
        plain_where = f"the YARP port {port}"
    if out.connect_to:
        where += f", connected to {comment(out.connect_to)}"
        plain_where += f", connected to {out.connect_to}"
    what = out.msg_type or "untyped Bottles"
    what_comment = comment(out.msg_type) if out.msg_type else "untyped Bottles"
    if out.image is not None:
        what = f"the camera images of mux {out.image}"
        what_comment = f"the camera images of mux {comment(out.image)}"
    shape = ""
    if out.kind == "ros1" and (has_message_array(program.message) or has_fixed_array(program.message)):
        shape = f", {cpp_string(ros1_shape(program.message))}"
        what_comment += (", serialized by the runtime (YARP's Bottle translation has no arrays of messages "
                         "and puts a length before a fixed-size array)")
    output = (f"{{{kind}, {cpp_string(port)}, {cpp_string(out.msg_type or '')}, "
              f"{cpp_string(out.connect_to or '')}{shape}}}")

    n_in = len(inputs)
    timing = ("event-driven (publishes when " +
              ("every needed input has" if program.timing.trigger == "all" else "any needed input has") +
              " new data)") if rate is None else (
                  f"at {rate:g} Hz" + (", new data only" if program.timing.publish == "new" else ""))
    policy = f"on_stale={program.policy.on_stale}, on_nan={program.policy.on_nan}"
    if program.policy.on_stale not in ("skip", "hold") or program.policy.on_nan not in ("pass", "drop"):
        raise LoweringError(f"unknown policy {policy}")
    description = (
        f"module {program.module}: {n_in} input(s) in {len(program.muxes)} mux(es)",
        f"publishes {what} on {plain_where}",
        f"publishing {timing}, {policy}",
    )
    if out.kind != "ros2" and any(i.kind == "ros2" for m in program.muxes for i in m.inputs):
        description += ("ROS arguments after --ros-args (remappings, the node's name)",)
    header = (
        (f"Module {comment(program.module)}: {n_in} input(s) in {len(program.muxes)} mux(es), "
         f"publishing {what_comment} on {where},"),
        f"{timing}, {policy}.",
    )
    config_name = config_file(program)
    sizes = " + \", \" + ".join(
        f"{cpp_string(m.name + ' has ')} + ybgc::images::describe(mux.{members[m.name]})" if m.image is not None else
        f"{cpp_string(m.name + ' has ')} + std::to_string(mux.{members[m.name]}.size())" for m in program.muxes
    ) or '""'
    return ModuleView(
        filename=f"{executable}.cpp",
        target=target,
        executable=executable,
        config_comment=comment(config_name),
        header=header,
        spec_module=cpp_string(program.module),
        spec_config=cpp_string(config_name),
        description=tuple(cpp_string(d) for d in description),
        default_prefix=cpp_string("/" + program.module),
        muxes=tuple(mux_views),
        inputs=tuple(inputs),
        needed="{" + ", ".join(str(k) for k in needed) + "}",
        output=output,
        output_comment=f"{what_comment} on {where}",
        rate=cpp_float(float(rate)) if rate is not None else "0.0",
        rate_comment="Hz" if rate is not None else "event-driven",
        trigger_all="true" if program.timing.trigger == "all" else "false",
        queue=str(int(program.timing.queue)),
        hold="true" if program.policy.on_stale == "hold" else "false",
        drop_nan="true" if program.policy.on_nan == "drop" else "false",
        new_only="true" if program.timing.publish == "new" else "false",
        msg_comment=(comment(program.message.msg_type or out.msg_type)
                     if program.message.msg_type or out.msg_type else "an untyped Bottle"),
        builder=builder,
        sizes=sizes,
        ros1=out.kind == "ros1" or any(i.kind == "ros1" for m in program.muxes for i in m.inputs),
        ros2_inputs=ros2_inputs,
        images=any(m.image is not None for m in program.muxes),
        image_output=image_output,
    )


__all__ = ["WIRE_ROS1", "WIRE_YARP", "LoweringError", "ModuleView", "comment", "lower"]
