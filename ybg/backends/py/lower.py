"""Lowering of a checked :class:`~ybg.compiler.ir.Program` to the view-model
that the Python templates print.

Every decision is taken here: which wire type each ROS primitive gets, how
each node of the message tree is built, which inputs the message needs.
Every value taken from the config reaches the generated source through
:func:`py_literal` (``repr`` based), the one escaping function of this
backend; the templates only print what this module hands them.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass

from ybg.backends import Line, LoweringError, nest_fields
from ybg.backends.wire import WIRE_ROS1, WIRE_YARP
from ybg.compiler import ir


_TIME_TYPES = ("time", "duration", "builtin_interfaces/Time", "builtin_interfaces/Duration")


# --------------------------------------------------------------------------
# the escaping function


def py_literal(value) -> str:
    """Python source text for ``value``: a str, int, float, bool, None, or a
    tuple of them. ``repr`` based, so any string (quotes, backslashes,
    newlines, non-ASCII text) becomes one valid literal that evaluates back
    to exactly the same value, on one line."""
    if value is None or isinstance(value, bool):
        return repr(value)
    if isinstance(value, int):
        return repr(int(value))
    if isinstance(value, float):
        if math.isnan(value):
            return "float('nan')"
        if math.isinf(value):
            return "float('inf')" if value > 0 else "float('-inf')"
        return repr(value)
    if isinstance(value, str):
        text = repr(value)
        # repr() escapes every non-printable character (newlines, U+2028 ...),
        # so the literal stays on one line; check it, never trust it.
        if "\n" in text or "\r" in text:
            raise AssertionError("multi-line literal")
        return text
    if isinstance(value, tuple):
        items = [py_literal(v) for v in value]
        if len(items) == 1:
            return "(" + items[0] + ",)"
        return "(" + ", ".join(items) + ")"
    raise TypeError(f"no Python literal for {type(value).__name__}")


def py_types(types) -> str:
    """Python source for a tuple of element type names (or None), with runs
    written compactly: ``('float64',) * 16 + ('int32',) * 3``."""
    if types is None:
        return "None"
    if not types:
        return "()"
    runs: list[list] = []
    for t in types:
        if runs and runs[-1][0] == t:
            runs[-1][1] += 1
        else:
            runs.append([t, 1])
    parts = [py_literal((t,)) + (f" * {n:d}" if n > 1 else "") for t, n in runs]
    return " + ".join(parts)


# --------------------------------------------------------------------------
# view-model


@dataclass(frozen=True)
class InputView:
    mux: str
    index: int
    source: str
    kind: str
    types: str
    timeout: str
    description: str
    positions: str = "None"
    reads: str = "None"
    accepts: str = "()"  # the other ports whose Bottles it takes too


@dataclass(frozen=True)
class ConverterView:
    """A linear converter's fields, or, for the others, ``spec``: the whole
    constructor (``GeometrySpec(...)``, ``EachSpec(...)``) on one line."""

    name: str
    scale: str = ""
    offset: str = ""
    to_float: str = ""
    start: str = ""
    stop: str = ""
    spec: str = ""


@dataclass(frozen=True)
class RuntimeImport:
    """``from <runtime>.<module> import <names>`` (a module's runtime
    names beyond the ones every module imports)."""

    module: str
    names: str


@dataclass(frozen=True)
class MuxView:
    name: str
    inputs: tuple[InputView, ...]
    converters: tuple[ConverterView, ...]
    verbose: str
    types: str
    rows: bool = False  # one row per element of an array of messages (ros2 inputs)


@dataclass(frozen=True)
class OutputView:
    kind: str
    port: str
    connect_to: str
    msg_type: str
    description: str


@dataclass(frozen=True)
class ModuleView:
    filename: str
    config: str
    module: str
    default_prefix: str
    summary: tuple[str, ...]
    muxes: tuple[MuxView, ...]
    needed: str
    rate: str
    trigger: str
    queue: str
    on_stale: str
    on_nan: str
    publish: str
    output: OutputView
    wire: tuple[tuple[str, str], ...]
    builder: tuple[Line, ...]
    runtime_imports: tuple[RuntimeImport, ...] = ()


# --------------------------------------------------------------------------
# converters

#: expression function -> the runtime's Python function (geometry.py)
_PY_FUNCTIONS = {"abs": "fabs", "min": "min_of", "max": "max_of", "clamp": "clamp", "sqrt": "sqrt",
                 "sin": "sin", "cos": "cos", "atan2": "atan2"}
#: the Geometry names of the runtime, by converter
GEOMETRY_SPEC_NAMES = {name: name for name in ir.GEOMETRY_WIDTHS}


def py_expression(node: ir.ExprNode, used: set[str], top: bool = True) -> str:
    """Python source of a checked expression of ``x`` (a float): IEEE
    arithmetic as in C++, the runtime's functions where Python would raise
    (``div``, ``sqrt``, ``sin``, ``cos``); names it uses go to ``used``."""
    op = node.op
    if op == "number":
        return py_literal(float(node.value))  # type: ignore[arg-type]
    if op == "x":
        return "x"
    if op == "pi":
        return py_literal(math.pi)
    if op == "neg":
        inner = node.args[0]
        text = py_expression(inner, used)
        return f"-{text}" if inner.op in ("x", "pi", "number") else f"-({text})"
    if op == "/":
        used.add("div")
        return f"div({py_expression(node.args[0], used)}, {py_expression(node.args[1], used)})"
    if op in ("+", "-", "*"):
        text = f"{py_expression(node.args[0], used, False)} {op} {py_expression(node.args[1], used, False)}"
        return text if top else f"({text})"
    if op not in _PY_FUNCTIONS:
        raise LoweringError(f"unknown expression function {op!r}")
    used.add(_PY_FUNCTIONS[op])
    return f"{_PY_FUNCTIONS[op]}({', '.join(py_expression(a, used) for a in node.args)})"


def converter_views(mux: ir.Mux, used: set[str]) -> tuple[ConverterView, ...]:
    """The converters of ``mux`` as the runtime's specs; the runtime names
    they need go to ``used`` (``GeometrySpec``, ``clamp`` ...)."""
    out = []
    for c in mux.converters:
        if isinstance(c, ir.GeometryConverter):
            used.add("GeometrySpec")
            args = (c.axes, c.degrees) if c.axes is not None else ()
            out.append(ConverterView(py_literal(c.text), spec=(
                f"GeometrySpec({py_literal(c.text)}, {py_literal(GEOMETRY_SPEC_NAMES[c.name])}, "
                f"{py_literal(args)}, start={py_literal(int(c.start))})")))
        elif isinstance(c, ir.ExprConverter):
            used.add("EachSpec")
            body = py_expression(c.body, used)
            out.append(ConverterView(py_literal(c.text), spec=(
                f"EachSpec({py_literal('expr(' + c.text + ')')}, lambda x: {body}, "
                f"start={py_literal(int(c.start))}, stop={py_literal(None if c.stop is None else int(c.stop))})")))
        else:
            out.append(ConverterView(
                name=py_literal(c.name),
                scale=py_literal(float(c.scale)),
                offset=py_literal(float(c.offset)),
                to_float=py_literal(bool(c.to_float)),
                start=py_literal(int(c.start)),
                stop=py_literal(None if c.stop is None else int(c.stop)),
            ))
    return tuple(out)


def runtime_imports(used: set[str]) -> tuple[RuntimeImport, ...]:
    """The imports of the runtime names in ``used``, by runtime module."""
    core = sorted(n for n in used if n in ("GeometrySpec", "EachSpec"))
    geometry = sorted(used - set(core))
    out = []
    if core:
        out.append(RuntimeImport("core", ", ".join(core)))
    if geometry:
        out.append(RuntimeImport("geometry", ", ".join(geometry)))
    return tuple(out)


# --------------------------------------------------------------------------
# lowering


def _default_scalar(base: str):
    if base in ir.FLOAT_TYPES:
        return 0.0
    if base == "bool":
        return False
    if base == "string":
        return ""
    if base in ir.NUMERIC_TYPES:
        return 0
    raise LoweringError(f"no default for type {base!r}")


def _coerce(value, element_type: str):
    if element_type in ir.FLOAT_TYPES:
        return float(value)
    if element_type == "bool":
        return bool(value)
    if element_type == "string":
        return str(value)
    if element_type in ir.NUMERIC_TYPES:
        return int(value)
    raise LoweringError(f"unknown element type {element_type!r}")


def _time_style(base: str, ros: str | None) -> str:
    if base.startswith("builtin_interfaces/") or ros == "ros2":
        return "ros2"
    return "ros1"


class _Builder:
    """Writes the body of ``build_message`` from the message tree."""

    def __init__(self, program: ir.Program):
        self.program = program
        self.lines: list[Line] = []
        self.muxes: list[str] = []
        self.path: list[str] = []  # the field being built, as a path
        self.uses_rows = False  # a mux of rows in the message: the runtime's Rows

    def emit(self, indent: int, text: str) -> None:
        self.lines.append(Line(indent, text))

    def mux_values(self, name: str) -> str:
        self.program.mux(name)  # KeyError for an unknown mux: the IR is broken
        if name not in self.muxes:
            self.muxes.append(name)
        return f"v[{py_literal(name)}]"

    def struct(self, struct: ir.Struct, msg_type: str | None, indent: int, head: str, tail: str) -> None:
        self.emit(indent, f"{head}Msg({py_literal(msg_type)}, (")
        for f in struct.fields:
            self.field(f, indent + 1)
        self.emit(indent, f")){tail}")

    def field(self, f: ir.Field, indent: int) -> None:
        self.path.append(f.name)
        try:
            self._field(f, indent)
        except LoweringError as e:
            raise e.at("field", ".".join(self.path).replace(".[", "["))
        finally:
            self.path.pop()

    def _field(self, f: ir.Field, indent: int) -> None:
        if self.program.output.kind == "ros1" and f.type is not None and f.type.array == "fixed":
            raise LoweringError(
                f"a fixed-size array ({f.type}) cannot reach ROS 1 from Python: YARP's Bottle translation "
                "sends a length before it, which ROS 1 reads as its first values, and YARP's Python bindings "
                "cannot promise the type that would let the module send the message serialized itself "
                "(the cpp backend does)")
        head = f"({py_literal(f.name)}, "
        src = f.source
        if isinstance(src, ir.Struct):
            msg_type = src.msg_type or (f.type.base if f.type is not None and f.type.is_message else None)
            self.struct(src, msg_type, indent, head, "),")
            return
        if isinstance(src, ir.MessageArray):
            self.message_array(src, indent, head)
            return
        self.emit(indent, head + self.expr(src, f.type) + "),")

    def message_array(self, src: ir.MessageArray, indent: int, head: str) -> None:
        """An Array of messages: each element a Msg."""
        if self.program.output.kind == "ros1":
            raise LoweringError(
                "an array of messages cannot reach ROS 1 from Python: YARP translates a Bottle to "
                "ROS 1 by a map that has no arrays of messages, and YARP's Python bindings cannot "
                "promise the type that would let the module send the message serialized itself "
                "(the cpp backend does)")
        if not src.elements:
            self.emit(indent, f"{head}Array({py_literal(src.msg_type)}, ())),")
            return
        self.emit(indent, f"{head}Array({py_literal(src.msg_type)}, (")
        for k, element in enumerate(src.elements):
            self.path.append(f"[{k}]")
            try:
                if isinstance(element, ir.Struct):
                    self.struct(element, src.msg_type, indent + 1, "", ",")
                else:
                    self.emit(indent + 1, self.expr(element, ir.TypeRef(src.msg_type)) + ",")
            finally:
                self.path.pop()
        self.emit(indent, "))),")

    def expr(self, src, typ: ir.TypeRef | None) -> str:
        if isinstance(src, ir.Literal):
            values = tuple(_coerce(v, src.element_type) for v in src.values)
            if src.is_list:
                return f"Array({py_literal(src.element_type)}, {py_literal(values)})"
            if len(values) != 1:
                raise LoweringError("a scalar literal holds exactly one value")
            return f"Scalar({py_literal(src.element_type)}, {py_literal(values[0])})"
        if isinstance(src, ir.MuxRef):
            return self.mux_ref(src, typ)
        if isinstance(src, ir.Counter):
            etype = py_literal(src.element_type)
            return f"Scalar({etype}, ctx.count({etype}))"
        if isinstance(src, ir.Timestamp):
            if src.clock == "envelope":
                if src.mux is None:
                    raise LoweringError("an envelope timestamp names its mux")
                self.mux_values(src.mux)
                return f"ctx.envelope_time({py_literal(src.mux)}, {py_literal(src.style)})"
            return f"ctx.wall_time({py_literal(src.style)})"
        if isinstance(src, ir.Seconds):
            return "Scalar('float64', ctx.seconds)"
        if isinstance(src, ir.Default):
            return self.default(typ, src.value)
        raise LoweringError(f"unknown source {type(src).__name__}")

    def mux_ref(self, ref: ir.MuxRef, typ: ir.TypeRef | None) -> str:
        values = self.mux_values(ref.mux)
        etype = py_literal(ref.element_type)
        if self.program.mux(ref.mux).rows:  # one nested list per row, whole
            if ref.index is not None or ref.start != 0 or ref.stop is not None or ref.into_fields:
                raise LoweringError(f"a part of mux {ref.mux}, which holds rows")
            self.uses_rows = True
            return f"Rows({etype}, {values}{'' if ref.splice else ', nested=True'})"
        if ref.index is not None:
            return f"Scalar({etype}, {values}[{ref.index:d}])"
        if ref.start == 0 and ref.stop is None:
            part = values
        else:
            stop = "None" if ref.stop is None else f"{ref.stop:d}"
            part = f"take({values}, {ref.start:d}, {stop})"
        if ref.into_fields is not None:
            types = ref.into_types or (ref.element_type,) * len(ref.into_fields)
            msg_type = typ.base if typ is not None and typ.is_message else None
            tree = nest_fields([(name, f"Scalar({py_literal(t)}, {values}[{ref.start + k:d}])")
                                for k, (name, t) in enumerate(zip(ref.into_fields, types))])

            def msg(type_name, items) -> str:  # a sub-message (Pose.position) is a nested list
                return "Msg(%s, (%s,))" % (py_literal(type_name), ", ".join(
                    f"({py_literal(n)}, {msg(None, x) if isinstance(x, list) else x})" for n, x in items))
            return msg(msg_type, tree)
        # per-element types when the mux mixes them (a spliced legacy mux of ints and floats)
        mux = self.program.mux(ref.mux)
        et = mux.element_types
        if et is not None:
            stop_i = len(et) if ref.stop is None else ref.stop
            sliced = tuple(et[ref.start:stop_i])
            if sliced and len(set(sliced)) > 1:
                etype = py_literal(sliced)
        kind = "Splice" if ref.splice else "Array"
        return f"{kind}({etype}, {part})"

    def default(self, typ: ir.TypeRef | None, value=None) -> str:
        if typ is None:
            raise LoweringError("a default value needs a typed field")
        base = typ.base
        if value is not None:  # the .msg's own default (ROS 2 `float64 w 1.0`)
            if typ.array is not None:
                return f"Array({py_literal(base)}, {py_literal(tuple(value))})"
            return f"Scalar({py_literal(base)}, {py_literal(value)})"
        if typ.array == "sequence":
            return f"Array({py_literal(base)}, ())"
        if base in _TIME_TYPES:
            if typ.array is not None:
                raise LoweringError(f"no default for an array of {base}")
            return f"time_msg(0, {py_literal(_time_style(base, self.program.ros))})"
        if typ.is_message:
            raise LoweringError(
                f"a default {typ} needs its fields; the checker expands nested messages")
        value = _default_scalar(base)
        if typ.array == "fixed":
            return f"Array({py_literal(base)}, {py_literal((value,) * (typ.size or 0))})"
        return f"Scalar({py_literal(base)}, {py_literal(value)})"


def _lower_output(program: ir.Program) -> OutputView:
    out = program.output
    if out.kind == "ros1":
        node = out.node or f"/yarp/{program.module}"
        port = f"{out.name}@{node}"
        desc = f"ROS 1 topic {out.name} (node {node})"
    elif out.kind == "yarp":
        port = out.name
        desc = f"YARP port {out.name}"
    else:
        raise LoweringError(f"the py backend cannot publish to a {out.kind!r} output")
    if out.connect_to:
        desc += f", connected to {out.connect_to}"
    if out.msg_type:
        desc = f"{out.msg_type} on the " + desc
    else:
        desc = "untyped Bottles on the " + desc
    return OutputView(
        kind=py_literal(out.kind),
        port=py_literal(port),
        connect_to=py_literal(out.connect_to),
        msg_type=py_literal(out.msg_type),
        description=py_literal(desc),
    )


def lower(program: ir.Program) -> ModuleView:
    """The view-model of the module generated for ``program``."""
    output = _lower_output(program)
    muxes = []
    used: set[str] = set()
    for m in program.muxes:
        inputs = []
        for k, i in enumerate(m.inputs):
            if i.kind not in ("yarp", "ros1"):
                raise LoweringError(f"the py backend cannot read a {i.kind!r} input ({i.name})",
                                    ("input", m.name, i.name))
            types = i.element_types
            width = "any number of numbers" if types is None else f"{len(types)} elements"
            if i.reads is not None:
                width += f"; the message reads the first {i.reads} (W511)"
            if i.accepts:
                width += f"; also from {', '.join(i.accepts)}"
            inputs.append(InputView(
                mux=py_literal(m.name),
                index=k,
                source=py_literal(i.name),
                kind=py_literal(i.kind),
                types=py_types(types),
                timeout=py_literal(float(i.timeout)),
                description=py_literal(f"{i.kind} {i.name}: {width}"),
                positions=py_literal(i.positions),
                reads=py_literal(i.reads),
                accepts=py_literal(tuple(i.accepts)),
            ))
        convs = converter_views(m, used)
        muxes.append(MuxView(
            name=py_literal(m.name),
            inputs=tuple(inputs),
            converters=convs,
            verbose=py_literal(bool(m.verbose)),
            types=py_types(m.element_types),
        ))

    b = _Builder(program)
    top_type = program.message.msg_type or program.output.msg_type
    b.struct(program.message, top_type, 1, "return ", "")
    needed = tuple(b.muxes)

    wire_map = WIRE_ROS1 if program.output.kind == "ros1" else WIRE_YARP
    wire = tuple((py_literal(k), py_literal(v)) for k, v in sorted(wire_map.items()))

    n_in = sum(len(m.inputs) for m in program.muxes)
    timing = ("event-driven (publishes when " +
              ("every needed input has" if program.timing.trigger == "all" else "any needed input has") +
              " new data)") if program.timing.rate is None else (
                  f"at {program.timing.rate:g} Hz" + (", new data only" if program.timing.publish == "new" else ""))
    summary = (
        py_literal(f"module {program.module}: {n_in} input(s) in {len(program.muxes)} mux(es)"),
        output.description,
        py_literal(f"publishing {timing}, on_stale={program.policy.on_stale}, "
                   f"on_nan={program.policy.on_nan}"),
    )
    config_name = os.path.basename(program.source) if program.source else program.module
    rate = program.timing.rate
    return ModuleView(
        filename=f"{program.module}.py",
        config=py_literal(config_name),
        module=py_literal(program.module),
        default_prefix=py_literal("/" + program.module),
        summary=summary,
        muxes=tuple(muxes),
        needed=py_literal(needed),
        rate=py_literal(None if rate is None else float(rate)),
        trigger=py_literal(program.timing.trigger),
        queue=py_literal(int(program.timing.queue)),
        on_stale=py_literal(program.policy.on_stale),
        on_nan=py_literal(program.policy.on_nan),
        publish=py_literal(program.timing.publish),
        output=output,
        wire=wire,
        builder=tuple(b.lines),
        runtime_imports=runtime_imports(used),
    )
