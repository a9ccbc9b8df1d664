"""Lowering of a checked :class:`~ybg.compiler.ir.Program` to the view-model
that the ROS 2 templates print.

The generated node reuses the Python runtime of the ``py`` backend (inputs,
freshness, converters, timing, shutdown) and adds the ROS 2 side: topics
read as mux inputs, and a typed message filled field by field. This module
decides, for every field of the message, which Python expression fills it
and with which Python type (``float`` for float fields, ``int``, ``bool``,
``str``, lists for arrays, nested messages assigned member by member), and
whether a size check is needed at run time. A Bottle output (ROS 2 topics to
a YARP port) is built exactly as the ``py`` backend builds it, by its own
lowering, so that both give the same Bottle.

Every value from the config reaches the generated source through
:func:`~ybg.backends.py.lower.py_literal`; every identifier made from a
config name is checked (:func:`_identifier`) or used only inside a literal.
"""

from __future__ import annotations

import keyword
import os
import re
from dataclasses import dataclass

from ybg.backends import Line
from ybg.backends.py.lower import (WIRE_YARP, InputView, LoweringError, MuxView, OutputView, RuntimeImport,
                                   converter_views, py_literal, runtime_imports)
from ybg.backends.py.lower import _Builder as BottleBuilder
from ybg.compiler import ir

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
_PKG = re.compile(r"[a-z][a-z0-9_]*\Z")
_MSG_NAME = re.compile(r"[A-Za-z][A-Za-z0-9]*\Z")


# --------------------------------------------------------------------------
# view-model


@dataclass(frozen=True)
class MsgImport:
    """``from <module> import <name> as <alias>``."""

    module: str
    name: str
    alias: str


@dataclass(frozen=True)
class TopicInputView:
    """A ROS 2 topic read by a mux: its message class and numeric leaves."""

    mux: str
    index: int
    msg_class: str
    leaves: str
    each: str = "None"  # the array of messages whose elements give one row each


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


@dataclass(frozen=True)
class PackageView:
    """The ament_python package around the node. Raw values: the package
    templates escape each one for its file (XML, Python)."""

    config: str
    package: str
    node_module: str
    executable: str
    node_name: str
    description: str
    depends: tuple[str, ...]
    launch_file: str
    parameters: tuple[tuple[str, object], ...]


# --------------------------------------------------------------------------
# names


def _identifier(name: str, what: str) -> str:
    """``name`` if it is a Python identifier that is no keyword."""
    if not name.isidentifier() or keyword.iskeyword(name) or not name.isascii():
        raise LoweringError(f"{what} {name!r} is not a Python identifier")
    return name


def split_type(msg_type: str) -> tuple[str, str]:
    """``pkg/Name`` or ``pkg/msg/Name`` -> (pkg, Name), both checked."""
    parts = msg_type.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        parts = [parts[0], parts[2]]
    if len(parts) != 2 or not _PKG.match(parts[0]) or not _MSG_NAME.match(parts[1]) \
            or keyword.iskeyword(parts[0]):
        raise LoweringError(f"{msg_type!r} is not a ROS message type name (pkg/Name)")
    return parts[0], parts[1]


def ros2_type_name(msg_type: str) -> str:
    pkg, name = split_type(msg_type)
    return f"{pkg}/msg/{name}"


def msg_alias(msg_type: str) -> str:
    """The name the node imports a message class as: ``ros_<pkg>_<Name>``;
    the prefix keeps it clear of every name of the runtime."""
    pkg, name = split_type(msg_type)
    return _identifier(f"ros_{pkg}_{name}", "message class")


def package_name(module: str) -> str:
    """A ROS package name (REP 144: lower case, digits, single `_`) for ``module``."""
    name = re.sub(r"_+", "_", re.sub(r"[^a-z0-9_]", "_", module.lower())).strip("_")
    if not name or not name[0].isalpha():
        name = "ybg_" + name
    return name


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


def _check_size(typ: ir.TypeRef, n: int, what: str) -> None:
    if typ.array == "fixed" and typ.size is not None and n != typ.size:
        raise LoweringError(f"{what}: {n} values for the fixed-size field {typ}")
    if typ.array == "sequence" and typ.size is not None and n > typ.size:
        raise LoweringError(f"{what}: {n} values for the bounded field {typ}")


def slice_stop(program: ir.Program, ref: ir.MuxRef, typ: ir.TypeRef, name: str) -> int | None:
    """The end of the mux slice ``ref`` into the array field ``name`` of type
    ``typ`` when the mux's width is known (else None: it is known at run
    time); the slice is checked against the mux and the field's size."""
    width = program.mux(ref.mux).width
    if width is None:
        if ref.stop is not None:
            _check_size(typ, ref.stop - ref.start, f"field {name}")
        return None
    stop = width if ref.stop is None else ref.stop
    if stop > width or ref.start > stop:
        raise LoweringError(f"field {name}: elements [{ref.start}, {stop}) of a mux of {width}")
    _check_size(typ, stop - ref.start, f"field {name}")
    return stop


class _MessageBuilder:
    """Writes the body of ``build_message`` for a typed ROS 2 message: one
    assignment per field that the config sets (the others keep the
    message's defaults)."""

    def __init__(self, program: ir.Program):
        self.program = program
        self.lines: list[Line] = []
        self.muxes: list[str] = []
        self.element_types: list[str] = []  # of the arrays of messages, to import

    def emit(self, text: str) -> None:
        self.lines.append(Line(1, text))

    def mux_values(self, name: str) -> str:
        self.program.mux(name)  # KeyError for an unknown mux: the IR is broken
        if name not in self.muxes:
            self.muxes.append(name)
        return f"v[{py_literal(name)}]"

    def message(self, struct: ir.Struct, msg_class: str) -> None:
        self.emit(f"msg = {msg_class}()")
        self.fields(struct, "msg", "")
        self.emit("return msg")

    def fields(self, struct: ir.Struct, target: str, prefix: str) -> None:
        for f in struct.fields:
            self.field(f, target, prefix)

    def field(self, f: ir.Field, target: str, prefix: str) -> None:
        try:
            self._field(f, target, prefix)
        except LoweringError as e:
            raise e.at("field", prefix + f.name)

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
        self.emit(_assign(target, f.name, self.value(src, typ, name)))

    def message_array(self, src: ir.MessageArray, typ: ir.TypeRef, target: str, field: str, name: str) -> None:
        """One new message per element, then each element's fields."""
        if typ.array is None or not typ.is_message or typ.base != src.msg_type:
            raise LoweringError(f"field {name}: an array of {src.msg_type} for a {typ} field")
        _check_size(typ, len(src.elements), f"field {name}")
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
        values = self.mux_values(ref.mux)
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
                return f"stamps.envelope({py_literal(src.mux)})"
            return "stamps.now()"
        if typ.is_message or base in ("time", "duration"):
            raise LoweringError(f"field {name}: cannot fill a {typ} field from {type(src).__name__}")
        if isinstance(src, ir.Literal):
            return self.literal(src, typ, name)
        if isinstance(src, ir.MuxRef):
            return self.mux_ref(src, typ, name)
        if isinstance(src, ir.Counter):
            if base in ir.INTEGER_TYPES and typ.array is None:
                # wrapped like an integer of the field's type, as on every backend
                return self.scalar(typ, f"ctx.count({py_literal(base)})", name)
            return self.scalar(typ, "ctx.counter", name)
        if isinstance(src, ir.Seconds):
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
        _check_size(typ, len(lit.values), f"field {name}")
        return "[" + ", ".join(_literal_text(v, typ.base) for v in lit.values) + "]"

    def mux_ref(self, ref: ir.MuxRef, typ: ir.TypeRef, name: str) -> str:
        values = self.mux_values(ref.mux)
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


def _message_types(struct: ir.Struct, out: set[str]) -> None:
    if struct.msg_type:
        out.add(struct.msg_type)
    for f in struct.fields:
        if f.type is not None and f.type.is_message:
            out.add(f.type.base)
        if isinstance(f.source, ir.Struct):
            _message_types(f.source, out)


def used_packages(program: ir.Program) -> tuple[str, ...]:
    """The ROS packages whose messages the node uses, sorted."""
    types: set[str] = set()
    if program.output.kind == "ros2":
        if program.output.msg_type:
            types.add(program.output.msg_type)
        _message_types(program.message, types)
    for m in program.muxes:
        for i in m.inputs:
            if i.kind == "ros2" and i.ros_type:
                types.add(i.ros_type)
    return tuple(sorted({split_type(t)[0] for t in types if t not in ("time", "duration")}))


def node_name(program: ir.Program) -> str:
    node = (program.output.node or "").strip("/") if program.output.kind == "ros2" else ""
    if node and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", node):
        return node
    return _identifier(program.module, "module name")


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
            if i.kind == "ros2":
                if not i.ros_type:
                    raise LoweringError(f"the ROS 2 input {i.name} has no message type", ("input", m.name, i.name))
                if not i.fields:
                    raise LoweringError(f"the ROS 2 input {i.name} names no numeric field", ("input", m.name, i.name))
                try:
                    for leaf in i.fields:
                        for part in leaf.split("."):
                            _identifier(part, f"field of {i.ros_type}")
                except LoweringError as e:
                    raise e.at("input", m.name, i.name)
                alias = msg_alias(i.ros_type)
                pkg, name = split_type(i.ros_type)
                imports[alias] = MsgImport(f"{pkg}.msg", name, alias)
                if i.each is not None:
                    _identifier(i.each, f"field of {i.ros_type}")
                topics.append(TopicInputView(py_literal(m.name), k, alias, py_literal(tuple(i.fields)),
                                             py_literal(i.each)))
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
                raise LoweringError(f"the ros2 backend cannot read a {i.kind!r} input ({i.name})",
                                    ("input", m.name, i.name))
            inputs.append(InputView(
                mux=py_literal(m.name), index=k, source=py_literal(i.name), kind=py_literal(i.kind),
                types=py_literal(types), timeout=py_literal(float(i.timeout)),
                description=py_literal(desc), reads=py_literal(i.reads),
                accepts=py_literal(tuple(i.accepts))))
        convs = converter_views(m, used)
        muxes.append(MuxView(py_literal(m.name), tuple(inputs), convs, py_literal(bool(m.verbose)),
                             py_literal(m.element_types), m.rows))
    return tuple(muxes), tuple(topics), imports, runtime_imports(used)


def _lower_yarp_output(program: ir.Program) -> OutputView:
    out = program.output
    desc = f"YARP port {out.name}"
    if out.connect_to:
        desc += f", connected to {out.connect_to}"
    desc = (f"{out.msg_type} on the " if out.msg_type else "untyped Bottles on the ") + desc
    return OutputView(kind=py_literal("yarp"), port=py_literal(out.name),
                      connect_to=py_literal(out.connect_to), msg_type=py_literal(out.msg_type),
                      description=py_literal(desc))


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
            raise e.at("type")
        imports[alias] = MsgImport(f"{pkg}.msg", name, alias)
        qos = out.qos or ir.QoS()
        if qos.reliability not in RELIABILITY or qos.durability not in DURABILITY or qos.depth < 1:
            raise LoweringError(f"unsupported QoS {qos}")
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
    elif out.kind == "yarp":
        yarp_output = _lower_yarp_output(program)
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
    timing = ("event-driven (publishes when " +
              ("every needed input has" if program.timing.trigger == "all" else "any needed input has") +
              " new data)") if program.timing.rate is None else (
                  f"at {program.timing.rate:g} Hz" + (", new data only" if program.timing.publish == "new" else ""))
    name = node_name(program)
    summary = (
        py_literal(f"ROS 2 node {name}: {n_in} input(s) in {len(program.muxes)} mux(es)"),
        py_literal(desc),
        py_literal(f"publishing {timing}, on_stale={program.policy.on_stale}, "
                   f"on_nan={program.policy.on_nan}"),
    )
    config_name = os.path.basename(program.source) if program.source else program.module
    rate = program.timing.rate
    return NodeView(
        filename=f"{_identifier(program.module, 'module name')}_node.py",
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
    )


def node_parameters(program: ir.Program) -> tuple[tuple[str, object], ...]:
    """The node's parameters a launch file gives, with their defaults from the
    config (the rclpy node's and the native C++ module's alike)."""
    rate = program.timing.rate
    return (
        ("rate", 0.0 if rate is None else float(rate)),
        ("timeout", 0.0),
        ("prefix", "/" + program.module),
        ("verbose", False),
        ("diagnostics", True),
    )


def lower_package(program: ir.Program, view: NodeView) -> PackageView:
    """The view-model of the ament_python package around the node."""
    pkg = package_name(program.module)
    config_name = os.path.basename(program.source) if program.source else program.module
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
