"""Python source for the runtime library, shared by the backends that
write Python (``py``: a YARP module; ``ros2``: an rclpy node).

Every value taken from the config reaches the generated source through
:func:`py_literal` (``repr`` based), the one escaping function of Python
code; the views here hold only text made by it. What both kinds of module
build alike is here: the specs of inputs, muxes and converters, the
imports of the runtime's names, a Bottle output and the Bottle builder
(``build_message`` of a module that writes a YARP port or a ROS 1 topic
through YARP), so that both give the same Bottle.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ybg.compiler import ir
from ybg.lower.errors import Line, LoweringError
from ybg.lower.templates import code_filter, indent_line_filter
from ybg.lower.tree import TIME_TYPES, coerce, default_scalar, nest_fields, time_style

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
    image: str = "None"  # a camera image input: its encoding (a YARP port's), or 'any' (a ROS 2 topic's)


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


# --------------------------------------------------------------------------
# converters

#: expression function -> the runtime's Python function (geometry.py)
_PY_FUNCTIONS = {"abs": "fabs", "min": "min_of", "max": "max_of", "clamp": "clamp", "sqrt": "sqrt",
                 "sin": "sin", "cos": "cos", "atan2": "atan2"}


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
                f"GeometrySpec({py_literal(c.text)}, {py_literal(c.name)}, "
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


class BottleBuilder:
    """Writes the body of ``build_message`` from the message tree: a Bottle
    (a YARP port, or a ROS 1 topic through YARP)."""

    def __init__(self, program: ir.Program):
        self.program = program
        self.lines: list[Line] = []
        self.muxes: list[str] = []
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
        try:
            self._field(f, indent)
        except LoweringError as e:
            raise e.at(f.span)

    def _field(self, f: ir.Field, indent: int) -> None:
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
        if not src.elements:
            self.emit(indent, f"{head}Array({py_literal(src.msg_type)}, ())),")
            return
        self.emit(indent, f"{head}Array({py_literal(src.msg_type)}, (")
        for element in src.elements:
            if isinstance(element, ir.Struct):
                self.struct(element, src.msg_type, indent + 1, "", ",")
            else:
                self.emit(indent + 1, self.expr(element, ir.TypeRef(src.msg_type)) + ",")
        self.emit(indent, "))),")

    def expr(self, src, typ: ir.TypeRef | None) -> str:
        if isinstance(src, ir.Literal):
            values = tuple(coerce(v, src.element_type) for v in src.values)
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
        if self.program.mux(ref.mux).image is not None:
            raise LoweringError(f"mux {ref.mux} holds camera frames, not values of a Bottle")
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
        if base in TIME_TYPES:
            if typ.array is not None:
                raise LoweringError(f"no default for an array of {base}")
            return f"time_msg(0, {py_literal(time_style(base, self.program.ros))})"
        if typ.is_message:
            raise LoweringError(
                f"a default {typ} needs its fields; the checker expands nested messages")
        value = default_scalar(base)
        if typ.array == "fixed":
            return f"Array({py_literal(base)}, {py_literal((value,) * (typ.size or 0))})"
        return f"Scalar({py_literal(base)}, {py_literal(value)})"


def bottle_output(program: ir.Program, backend: str) -> OutputView:
    """The output of a module that writes Bottles: a YARP port, or a ROS 1
    topic through YARP (``port@node``)."""
    out = program.output
    if out.kind == "ros1":
        node = out.node or f"/yarp/{program.module}"
        port = f"{out.name}@{node}"
        desc = f"ROS 1 topic {out.name} (node {node})"
    elif out.kind == "yarp":
        port = out.name
        desc = f"YARP port {out.name}"
    else:
        raise LoweringError(f"the {backend} backend cannot publish to a {out.kind!r} output")
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


def timing_summary(program: ir.Program) -> str:
    """How the module publishes, as its summary says it."""
    timing = ("event-driven (publishes when " +
              ("every needed input has" if program.timing.trigger == "all" else "any needed input has") +
              " new data)") if program.timing.rate is None else (
                  f"at {program.timing.rate:g} Hz" + (", new data only" if program.timing.publish == "new" else ""))
    return (f"publishing {timing}, on_stale={program.policy.on_stale}, "
            f"on_nan={program.policy.on_nan}")


def int_literal_filter(value) -> str:
    """Template filter: an int as a Python literal (anything else is a bug)."""
    if not isinstance(value, int) or isinstance(value, bool):
        raise TypeError(f"expected an int, got {type(value).__name__}")
    return py_literal(value)


#: the template filters of every Python module
PYTHON_FILTERS = {
    "code": code_filter,
    "int_literal": int_literal_filter,
    "indent_line": indent_line_filter,
    "pyliteral": py_literal,
}


__all__ = ["PYTHON_FILTERS", "int_literal_filter", "py_literal", "py_types", "py_expression", "InputView", "ConverterView", "RuntimeImport", "MuxView",
           "OutputView", "converter_views", "runtime_imports", "BottleBuilder",
           "bottle_output", "timing_summary"]
