"""The reference model of what a bridge module outputs, the same for every
backend: the values a producer writes on an IR input (``input_values``,
``topic_values``), the mux values after the converters (``mux_values``), the
message the module must publish, as Bottle items or as named fields
(``expected``), and the matchers: ``assert_matches``, with placeholders for
what changes from message to message (``COUNTER``, ``TIME``, ``SECONDS``,
``Envelope``), and ``assert_close`` (numbers to ``TOL``); the converters'
geometry from an independent implementation (harness/geometry_reference.py).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Optional

from harness import geometry_reference
from ybg.compiler import ir
from ybg.compiler.ir import (Counter, Default, Field, Input, Literal, MessageArray, MuxRef, Program, Seconds,
                             Struct, Timestamp, TypeRef)


@dataclass(frozen=True)
class Changing:
    """A value that changes from message to message: matched by its kind.
    counter: an int >= ``least``; time: (sec, nsec) or a ROS time, and
    seconds: a float, both within the matcher's time window."""
    kind: str  # counter | time | seconds
    least: int = 0


#: the message counter of the third message or later (the tests take the
#: third message a consumer receives, or a later one)
COUNTER = Changing("counter", 2)
TIME = Changing("time")
SECONDS = Changing("seconds")


@dataclass(frozen=True)
class Envelope:
    """The envelope time a producer stamped: YARP sends envelopes as text
    with 15 significant digits (10 microseconds at this epoch)."""
    seconds: float
    tolerance: float = 2e-5


@dataclass(frozen=True)
class Near:
    """A float the reference computes by other means than the module (a
    rotation library): equal to within ``tolerance``."""
    value: float
    tolerance: float = 1e-12


#: what a publisher of a ROS topic input without a declared layout sends:
#: a geometry_msgs/Point, every leaf
POINT = {"x": 0.5, "y": -1.25, "z": 2.0}


def input_values(inp: Input, k: int, offset: float = 0.0) -> list:
    """The values a producer writes on YARP input ``inp``, the ``k``-th
    input of its program: distinct from every other input's, of the input's
    declared element types (undeclared: eight float64). ``offset`` makes a
    later Bottle different from the first."""
    if inp.layout is None:
        return [10.0 * (k + 1) + 1.5 * j + offset for j in range(8)]
    out = []
    for j, t in enumerate(inp.element_types):
        if t in ir.FLOAT_TYPES:
            out.append(5.0 * (k + 1) + 0.25 * j + offset)
        elif t == "string":
            out.append(f"s{k}_{j}")
        elif t == "bool":
            out.append(j % 2)
        else:
            out.append(10 * k + j + int(offset))
    return out


def topic_values(inp: Input) -> list:
    """The values a publisher of the topic input ``inp`` sends, in the
    order of the input's fields (a ROS topic without fields: POINT); for an
    input of the elements of an array of messages, three rows."""
    if inp.each is not None:
        return [[x for path, t in element_fields(inp) for x in _row_part(t, k)] for k in range(3)]
    if not inp.fields:
        return [POINT["x"], POINT["y"], POINT["z"]]
    return [0.5 * (j + 1) - 1.25 for j in range(len(inp.fields))]


def element_fields(inp: Input) -> list[tuple[str, TypeRef]]:
    """(field, type) of each field an input reads of the elements of ``inp.each``."""
    from ybg.compiler.msgtypes import load_store

    store = load_store("ros2", None)
    element = store.resolve(inp.ros_type).field(inp.each).type.base
    out = []
    for path in inp.fields:
        cur, t = store.resolve(element), None
        for part in path.split("."):
            t = cur.field(part).type
            cur = store.resolve(t.base) if t.is_message else None
        out.append((path, t))
    return out


def _row_part(t: TypeRef, k: int) -> list:
    """Row ``k``'s values of a field of type ``t``: a duration as seconds
    (whole nanoseconds), an array as four numbers, a number as one."""
    if t.base in ("builtin_interfaces/Duration", "builtin_interfaces/Time"):
        return [0.5 * (k + 1) + 0.25]  # exact in binary, as sec + nanosec / 1e9 gives it
    if t.array is not None:
        return [0.25 * j - 0.1 * k for j in range(4)]
    return [1.5 + k]


def topic_message(inp: Input, values: list) -> dict:
    """The message (nested dicts) whose fields ``inp.fields`` hold ``values``
    (for ``inp.each``: one row of values per element)."""
    if inp.each is not None:
        elements = []
        for row in values:
            element: dict = {}
            rest = list(row)
            for path, t in element_fields(inp):
                part, rest = rest[:len(_row_part(t, 0))], rest[len(_row_part(t, 0)):]
                if t.base in ("builtin_interfaces/Duration", "builtin_interfaces/Time"):
                    sec, nanosec = divmod(round(part[0] * 1e9), 1000000000)
                    value = {"sec": sec, "nanosec": nanosec}
                else:
                    value = part if t.array is not None else part[0]
                element[path] = value
            elements.append(element)
        return {inp.each: elements}
    msg: dict = {}
    for path, v in zip(inp.fields, values):
        node = msg
        *parents, leaf = path.split(".")
        for p in parents:
            node = node.setdefault(p, {})
        node[leaf] = v
    return msg


def sent_values(program: Program, offset: float = 0.0) -> dict[str, list]:
    """{input name: values} for every input of ``program``: what its
    producers (YARP) or publishers (ROS topics) send."""
    out = {}
    k = 0
    for m in program.muxes:
        for inp in m.inputs:
            out[inp.name] = input_values(inp, k, offset) if inp.kind == "yarp" else topic_values(inp)
            k += 1
    return out


def mux_values(program: Program, sent: dict[str, list]) -> dict[str, list]:
    """The mux values after conversion, for the values ``sent`` on each input
    (a mux of rows: each row converted alike)."""
    out = {}
    for m in program.muxes:
        if m.rows:
            (inp,) = m.inputs
            out[m.name] = [_converted([float(x) for x in row], m.converters) for row in sent[inp.name]]
            continue
        values: list = []
        for inp in m.inputs:
            raw = sent[inp.name]
            types = inp.element_types or ("float64",) * len(raw)
            for x, t in zip(raw, types):
                values.append(float(x) if t in ir.FLOAT_TYPES else (bool(x) if t == "bool" else x))
        out[m.name] = _converted(values, m.converters)
    return out


def _converted(values: list, converters) -> list:
    values = list(values)
    for c in converters:
        if isinstance(c, ir.GeometryConverter):
            part = [float(v) for v in values[c.start:c.start + c.width_in]]
            values[c.start:c.start + c.width_in] = [
                Near(v) for v in geometry_reference.geometry(c.name, part, c.axes, c.degrees)]
            continue
        if isinstance(c, ir.ExprConverter):
            stop = len(values) if c.stop is None else min(c.stop, len(values))
            values[c.start:stop] = [x if isinstance(x, str) else
                                    geometry_reference.evaluate(c.body, float(x)) for x in values[c.start:stop]]
            continue
        if c.scale == 1.0 and c.offset == 0.0 and not c.to_float:
            continue
        stop = len(values) if c.stop is None else min(c.stop, len(values))
        for i in range(c.start, stop):
            x = values[i]
            if isinstance(x, str):
                continue
            y = x * c.scale + c.offset
            values[i] = float(y) if c.to_float or isinstance(x, float) else int(y)
    return values


def envelopes(program: Program, stamps: dict[str, float]) -> dict[str, float]:
    """{mux: envelope time} from the stamps written on its inputs: a mux's
    envelope is the newest of its inputs'."""
    out = {}
    for m in program.muxes:
        have = [stamps[i.name] for i in m.inputs if i.name in stamps]
        if have:
            out[m.name] = max(have)
    return out


def _default(typ: TypeRef, named: bool):
    if typ.array == "sequence":
        return []
    if typ.base in ("time", "duration"):
        return {"secs": 0, "nsecs": 0} if named else [0, 0]
    v = 0.0 if typ.base in ir.FLOAT_TYPES else ("" if typ.base == "string" else 0)
    if typ.base == "bool" and named:
        v = False
    return [v] * typ.size if typ.array == "fixed" else v


def _as(base: Optional[str], v):
    """A named field's value as its ROS type holds it."""
    if isinstance(v, list):
        return [_as(base, x) for x in v]
    if base in ir.FLOAT_TYPES and isinstance(v, (int, float)) and not isinstance(v, bool):
        return float(v)
    if base == "bool" and isinstance(v, int):
        return bool(v)
    return v


def expected(program: Program, muxes: dict[str, list], named: bool,
             stamps: Optional[dict[str, float]] = None):
    """What the message must hold: Bottle items (nested lists, ``named``
    false) or named fields (nested dicts, a ROS message), from the IR and the
    mux values. ``stamps``: {mux: envelope time} the producers stamped."""
    stamps = stamps or {}

    def struct(s: Struct):
        items: list | dict = {} if named else []
        for f in s.fields:
            v = source(f.source, f)
            if named:
                items[f.name] = v
            elif isinstance(f.source, MuxRef) and f.source.splice:
                items.extend(v)
            else:
                items.append(v)
        return items

    def typed(f: Field, v):
        return _as(f.type.base if f.type is not None else None, v) if named else v

    def source(src, f: Field):
        if isinstance(src, Struct):
            return struct(src)
        if isinstance(src, MessageArray):  # each element: a message, or a mux filling its numbers
            element = Field("", None, TypeRef(src.msg_type))
            return [source(e, element) for e in src.elements]
        if isinstance(src, Literal):
            vals = [int(v) if isinstance(v, bool) and not named else v for v in src.values]
            return typed(f, vals if src.is_list else vals[0])
        if isinstance(src, MuxRef):
            v = muxes[src.mux]
            if src.index is not None:
                return typed(f, v[src.index])
            if src.into_fields is not None:
                part = v[src.start:src.start + len(src.into_fields)]
                if not named:  # a Bottle: a list, a list in it for each sub-message (Pose.position)
                    return _nested_lists(src.into_fields, part)
                types = src.into_types or (None,) * len(part)
                out: dict = {}
                for n, t, x in zip(src.into_fields, types, part):  # `position.x`: nested
                    *parents, leaf = n.split(".")
                    node = out
                    for p in parents:
                        node = node.setdefault(p, {})
                    node[leaf] = _as(t, x)
                return out
            return typed(f, v[src.start:src.stop])
        if isinstance(src, Counter):
            return COUNTER
        if isinstance(src, Timestamp):
            if src.clock == "envelope" and src.mux in stamps:
                return Envelope(stamps[src.mux])
            return TIME
        if isinstance(src, Seconds):
            return SECONDS
        if isinstance(src, Default):
            return _default(f.type, named)
        raise AssertionError(src)

    return struct(program.message)


def _nested_lists(paths, values) -> list:
    """Leaf values as the ROS 1 layout nests them: `position.x` ... in a
    list of their own."""
    out: list = []
    heads: list = []
    for path, v in zip(paths, values):
        head, _, rest = path.partition(".")
        if not rest:
            out.append(v)
            heads.append(None)
        elif heads and heads[-1] == head:
            out[-1][0].append(rest)
            out[-1][1].append(v)
        else:
            out.append(([rest], [v]))
            heads.append(head)
    return [_nested_lists(*x) if h is not None else x for h, x in zip(heads, out)]


def _time_of(got) -> tuple:
    """(sec, nsec) of a Bottle's [sec, nsec] or a ROS 1 / ROS 2 time."""
    if isinstance(got, dict):
        return got.get("secs", got.get("sec")), got.get("nsecs", got.get("nanosec"))
    sec, nsec = got
    return sec, nsec


def assert_matches(got, want, window: tuple, path: str = "msg", exact_fields: bool = False) -> None:
    """``got`` (a received message) is ``want`` (from ``expected``): the same
    structure, strings and integers equal and of the same type, floats
    exactly equal (NaN equal to NaN) and floats; a counter an int of at
    least its placeholder's value; a time or seconds within ``window`` =
    (earliest, latest) time.time(). A message's fields may be more than the
    reference's (a ROS message has all of its type's), unless
    ``exact_fields``."""
    if isinstance(want, Changing):
        if want.kind == "counter":
            assert isinstance(got, int) and not isinstance(got, bool) and got >= want.least, (path, got)
        elif want.kind == "seconds":
            assert isinstance(got, float) and window[0] <= got <= window[1], (path, got, window)
        else:
            sec, nsec = _time_of(got)
            assert isinstance(sec, int) and isinstance(nsec, int) and 0 <= nsec < 10 ** 9, (path, got)
            assert window[0] <= sec + nsec / 1e9 <= window[1], (path, got, window)
        return
    if isinstance(want, Near):
        assert isinstance(got, float) and (abs(got - want.value) <= want.tolerance
                                           or (math.isnan(got) and math.isnan(want.value))), (path, want, got)
        return
    if isinstance(want, Envelope):
        sec, nsec = _time_of(got)
        assert isinstance(sec, int) and isinstance(nsec, int) and 0 <= nsec < 10 ** 9, (path, got)
        assert abs(sec + nsec / 1e9 - want.seconds) < want.tolerance, (path, got, want)
        return
    if isinstance(want, dict):
        assert isinstance(got, dict), (path, got)
        if exact_fields:
            assert sorted(got) == sorted(want), (path, sorted(got), sorted(want))
        else:
            assert set(want) <= set(got), (path, sorted(got), sorted(want))
        for k in want:
            assert_matches(got[k], want[k], window, f"{path}.{k}", exact_fields)
        return
    if isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), (path, want, got)
        for i, (g, w) in enumerate(zip(got, want)):
            assert_matches(g, w, window, f"{path}[{i}]", exact_fields)
        return
    if isinstance(want, float):
        assert isinstance(got, float) and (got == want or (math.isnan(got) and math.isnan(want))), \
            (path, want, got)
        return
    assert got == want and type(got) is type(want), (path, want, got)


#: the tolerance of ``assert_close`` (and of a test's own comparisons to it)
TOL = 1e-12


def assert_close(actual, expected, path="msg"):
    """Exact structure and strings; numbers to 1e-12."""
    if isinstance(expected, dict):
        assert isinstance(actual, dict), f"{path}: {actual!r} is not a message"
        assert sorted(actual) == sorted(expected), f"{path}: fields {sorted(actual)} != {sorted(expected)}"
        for k in expected:
            assert_close(actual[k], expected[k], f"{path}.{k}")
    elif isinstance(expected, (list, tuple)):
        assert isinstance(actual, list), f"{path}: {actual!r} is not a list"
        assert len(actual) == len(expected), f"{path}: {len(actual)} values, expected {len(expected)}"
        for k, (a, e) in enumerate(zip(actual, expected)):
            assert_close(a, e, f"{path}[{k}]")
    elif isinstance(expected, float):
        assert isinstance(actual, float), f"{path}: {actual!r} is not a float"
        assert math.isclose(actual, expected, rel_tol=0, abs_tol=TOL), f"{path}: {actual!r} != {expected!r}"
    else:
        assert actual == expected and type(actual) is type(expected), f"{path}: {actual!r} != {expected!r}"


def exactly(a, b) -> bool:
    """Equal values, NaN equal to NaN, int and float told apart."""
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(exactly(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        return (math.isnan(a) and math.isnan(b)) or a == b
    return type(a) is type(b) and a == b


# --------------------------------------------------------------------------
# a module's messages against the reference


def expected_message(program: Program, sent: dict, stamps: dict):
    """The message ``program`` must publish for the values ``sent`` on its
    inputs and the envelope ``stamps`` written with them ({port: time})."""
    return expected(program, mux_values(program, sent), named=True, stamps=envelopes(program, stamps))


def check_message(got, want, t_before):
    """The exact message (every field of its type, no other): numbers and
    strings exactly; header.stamp the node's clock (between the writes and
    the arrival) or the envelope's time, as the reference says."""
    assert_matches(got.msg, want, (t_before - 0.05, got.t + 0.05), exact_fields=True)


def write_all(program, producers, offset=0.0, stamped=False):
    """Each producer writes its input's values (``sent_values``), with an
    envelope stamp of its own when ``stamped``: (sent, {port: stamp}, the
    time before the first write)."""
    sent = sent_values(program, offset)
    stamps = {}
    t_before = time.time()
    for k, p in enumerate(producers):
        stamp = None
        if stamped:
            stamps[p.port] = 1_700_000_000.0 + 12.5 * k + 0.123456789 + offset
            stamp = [k, stamps[p.port]]
        p.write(sent[p.port], stamp=stamp)
    return sent, stamps, t_before


def wait_matching(sub, t_before, expected, timeout=60.0):
    """The first message received after ``t_before`` that is the expected
    one; on a timeout, the mismatch of the last message received."""
    end = time.monotonic() + timeout
    problem = "no message at all"
    while time.monotonic() < end:
        with sub._cond:
            fresh = [m for m in sub.messages if m.t > t_before]
        for m in fresh:
            try:
                check_message(m, expected, t_before)
                return m
            except AssertionError as e:
                problem = f"{e}\nin {m.msg}"
        time.sleep(0.05)
    raise AssertionError(f"no expected message within {timeout} s: {problem}")
