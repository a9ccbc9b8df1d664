"""The C++ runtime's commands (ybg/runtime/cpp/ybgc_services.*) held to the
Python runtime's (ybg/runtime/services.py), without any middleware: a
reply's or a command's elements (declarations, vocabs as words, the
bool-from-word rule, converters, integers from whole reals, slices into
sequences and fixed arrays, the reasons of what does not fit), the values
Bottles are made of (wire types, wrapping, bools as int32, converted
arrays), a command's first word, the exit totals and `stats`, the reasons
filled at run time, a service's status on /diagnostics. The same cases go through the C++ driver
(tests/runtime/services/test_services_runtime.cpp, built against the
ROS 2 wheels) and the Python runtime; their answers are the same, word for
word, so that the native module and the rclpy node answer alike."""

from __future__ import annotations

import struct
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest

from harness.build import find_once_option
from harness.env import DEFAULT_YARP, VENV
from harness.ros2 import require_ros2
from harness.yarp import require_yarp
from ybg.lower import services as texts

SOURCE = Path(__file__).resolve().parent / "runtime" / "services"

WORDS = "ok ack true yes done"

#: (bottle, start, types or None, converters [(name, scale, offset, to_float, start, stop)], queries)
ELEMENTS = [
    # a reply of one word, declared or not; vocabs are words; the true words
    ("[ok]", 0, None, [], "text word:0 boolean:0 real:0 integer:0"),
    ("ok", 0, ("string",), [], "text word:0 boolean:0"),
    ("[ack]", 0, ("string",), [], "boolean:0 word:0"),
    ("nack", 0, ("string",), [], "boolean:0"),
    ('"two words" done', 0, None, [], "text word:0 boolean:0 boolean:1 word:1"),
    ("OK", 0, None, [], "boolean:0"),
    # numbers into bools, integers and reals; a whole real as an integer
    ("1 0 2.5 0.0 -3", 0, None, [], "boolean:0 boolean:1 boolean:2 boolean:3 boolean:4 integer:4 real:4 "
                                    "integer:2 integer:3 real:2 word:0"),
    ("1e300 -0.0 3", 0, None, [], "real:0 real:1 float32:2 int8:2"),
    # declarations: element counts and types
    ("1 2", 0, ("int32",), [], "integer:0"),
    ("1.5", 0, ("int32",), [], "integer:0"),
    ("1", 0, ("float64",), [], "real:0 integer:0"),
    ("word", 0, ("float64",), [], "real:0"),
    ("3", 0, ("string",), [], "word:0"),
    ("0 1", 0, ("bool", "bool"), [], "boolean:0 boolean:1 integer:1 real:1"),
    ("2", 0, ("bool",), [], "boolean:0"),
    ("(garbage 1.5) 42", 0, ("string",), [], "text"),
    ("(garbage 1.5) 42", 0, None, [], "text real:1 word:0 boolean:0 real:0"),
    ("(1 2)", 0, ("int32",), [], "text"),
    ("1", 0, ("wstring",), [], "text"),
    # a command's arguments: the items after its word
    ("track 1", 1, ("int32",), [], "text integer:0 boolean:0"),
    ("track on", 1, ("int32",), [], "text"),
    ("track", 1, ("int32",), [], "text"),
    ("look 0.1 0.2 0.3 1.5", 1, ("float64",) * 4, [], "text real:0 real:3"),
    ('look (1 2) "a b" [ok]', 1, None, [], "text word:1 word:2 boolean:2"),
    # converters: float64 results, integers kept unless to_float, words refused
    ("90 180 7", 0, None, [("deg_to_rad", 0.017453292519943295, 0.0, True, 0, 2)], "real:0 real:1 integer:2 real:2"),
    ("90 45", 0, ("int32", "int32"), [("scale", 0.5, 0.0, False, 0, None)], "integer:0 integer:1 real:1 text"),
    ("1.5 2.5", 0, None, [("offset", 1.0, -0.25, False, 0, None), ("scale", 3.0, 0.0, True, 1, None)],
     "real:0 real:1"),
    ("ok 2", 0, None, [("scale", 2.0, 0.0, True, 0, None)], "text"),
    ("1 2", 0, None, [("scale", 2.0, 0.0, True, 5, None)], "real:0 real:1"),
    # slices into a sequence (bounded or not) and into a fixed-size array
    ("1 2 3 4", 0, None, [], "reals:0:-:0 reals:1:3:0 reals:2:-:0 reals:4:-:0 reals:5:-:0 reals:0:-:3 reals:1:-:3"),
    ("1 2 3 4", 0, None, [], "fixed3:0 fixed3:1 fixed3:2"),
    ("1 x 3", 0, None, [], "reals:0:-:0 fixed3:0"),
    # beyond the elements
    ("", 0, None, [], "word:0 real:0 boolean:0 reals:0:-:0 text"),
    ("a", 0, None, [], "word:1 reals:0:2:0"),
]

#: (wire, C type, value): a field's value on its wire type (ybg.lower.wire.WIRE_YARP), and wrapping
PUTS = [
    ("int32", "int8", "-128"), ("int32", "uint8", "255"), ("int32", "int16", "-32768"), ("int32", "uint16", "65535"),
    ("int32", "int32", "-2147483648"), ("int64", "uint32", "4294967295"), ("int64", "int64", "-9223372036854775808"),
    ("int64", "uint64", "18446744073709551615"), ("int64", "uint64", "9223372036854775808"),
    ("int32", "bool", "1"), ("int32", "bool", "0"),
    ("float64", "float32", "0.1"), ("float64", "float64", "0.1"), ("float64", "float64", "-0.0"),
    ("float64", "float64", "1e300"), ("string", "string", "tracking on"), ("string", "string", ""),
]

#: (C type of the array, values, scale, offset): an array through a converter
CONVERTED = [
    ("float64", "90,180,-45.5", 0.017453292519943295, 0.0),
    ("int32", "1,2,-3", 0.001, 0.0),
    ("float64", "-0.0,1", 1.0, 0.0),
    ("float64", "1,2", 2.0, -1.5),
]

FIRST = ["home", "[stat]", "3 x", "(a b) c", '"two words" x', "", "1.5"]

TOTALS = [("home", 3, 1, 1, 0, 1), ("look_at", 0, 0, 0, 0, 0), ("track", 10, 2, 3, 4, 1)]

#: (name, timeout, calls, answered, timed out, no server, unfit, its last call failed, why): a service on /diagnostics
STATUSES = [("home", 5.0, 0, 0, 0, 0, 0, False, ""), ("home", 0.5, 2, 2, 0, 0, 0, False, ""),
            ("look_at", 1.25, 3, 1, 1, 1, 0, True, "/gaze/rpc: no server (is the module that serves it running?)")]

REASONS = [("/gaze/rpc replied {reply}: {why}", "(garbage 1.5) 42", "element 0 is a list (garbage 1.5)"),
           ("`track data:int32`: {why}", "", "0 elements, expected 1"),
           ("/x did not answer within 1 s", "r", "w")]


# --------------------------------------------------------------------------
# the Python runtime's answers


def python_answers() -> list[str]:
    import yarp
    from ybg.runtime import services as rt

    def bottle(text: str):
        b = yarp.Bottle()
        b.fromString(text)
        return b

    def unfit(e) -> str:
        return f"unfit:{e}"

    def query(e, q: str) -> str:
        op, *args = q.split(":")
        try:
            if op == "text":
                return e.text()
            k = int(args[0])
            if op == "real":
                return repr(e.float(k))
            if op == "integer":
                return str(e.int(k))
            if op == "word":
                return e.str(k)
            if op == "boolean":
                return str(e.bool(k))
            if op == "int8":
                return str(e.int(k))
            if op == "float32":
                return repr(e.float(k))
            if op == "reals":
                stop = None if args[1] == "-" else int(args[1])
                bound = int(args[2]) or None
                return ",".join(repr(x) for x in e.floats(k, stop, bound=bound, field="f"))
            if op == "fixed3":
                return ",".join(repr(x) for x in e.floats(k, fixed=3, field="f"))
        except rt.Unfit as why:
            return unfit(why)
        raise ValueError(q)

    out = []
    for text, start, types, convs, queries in ELEMENTS:
        convs = [rt.Conv(*c) for c in convs]
        try:
            e = rt.Elements(bottle(text), start, types, convs, WORDS.split())
        except rt.Unfit as why:
            out.append(unfit(why))
            continue
        out.append("\t".join(["ok"] + [query(e, q) for q in queries.split()]))
    for wire, ctype, value in PUTS:
        if ctype == "string":
            x = value
        elif ctype == "bool":
            x = value == "1"
        elif ctype == "float32":
            x = struct.unpack("f", struct.pack("f", float(value)))[0]
        elif ctype == "float64":
            x = float(value)
        else:
            x = int(value)
        b = yarp.Bottle()
        rt.add_value(b, wire, x)
        v = b.get(0)
        tag = ("int32" if v.isInt32() else "int64" if v.isInt64() else "float64" if v.isFloat64()
               else "string" if v.isString() else "?")
        out.append(f"{b.toString()}\t{tag}")
    for ctype, values, scale, offset in CONVERTED:
        b = yarp.Bottle()
        parse = float if ctype == "float64" else int
        rt.add_converted(b, [parse(v) for v in values.split(",")], scale, offset)
        out.append(b.toString())
    for text in FIRST:
        out.append(rt.first_word(bottle(text)))
    for name, calls, answered, timed_out, no_server, unfit_ in TOTALS:
        c = rt.Counts()
        c.calls, c.answered, c.timed_out, c.no_server, c.unfit = calls, answered, timed_out, no_server, unfit_
        line = texts.TOTALS_LINE.format(name=name, **c.as_dict())
        stats = rt.stats_reply(yarp.Bottle(), [SimpleNamespace(name=name)], {name: c})
        out.append(f"{line}\t{stats.toString()}")
    for template, reply, why in REASONS:
        out.append(rt.reason_text(template, reply, why))
    for name, timeout, calls, answered, timed_out, no_server, unfit_, failed, why in STATUSES:
        c = rt.Counts()
        c.calls, c.answered, c.timed_out, c.no_server, c.unfit = calls, answered, timed_out, no_server, unfit_
        c.last = why if failed else None
        level, message, values = rt.service_status(SimpleNamespace(name=name, timeout=timeout), c)
        level = level[0] if isinstance(level, bytes) else int(level)  # a byte in rclpy
        out.append(f"{level}\tnode: service {name}\t{message}\t" + ";".join(f"{k}={v}" for k, v in values))
    return out


def driver_input() -> str:
    lines = []
    for text, start, types, convs, queries in ELEMENTS:
        conv = ";".join(",".join([name, repr(float(scale)), repr(float(offset)), "1" if to_float else "0", str(a),
                                  "-" if b is None else str(b)]) for name, scale, offset, to_float, a, b in convs)
        lines.append("\t".join(["elements", text, str(start), "-" if types is None else " ".join(types), conv, WORDS,
                                queries]))
    lines += ["\t".join(["put", *case]) for case in PUTS]
    lines += ["\t".join(["puteachconv", ctype, values, repr(scale), repr(offset)])
              for ctype, values, scale, offset in CONVERTED]
    lines += [f"first\t{text}" for text in FIRST]
    lines += ["\t".join(["totals", name, *map(str, counts)]) for name, *counts in TOTALS]
    lines += ["\t".join(["reason", *case]) for case in REASONS]
    lines += ["\t".join(["status", name, repr(timeout), *map(str, counts), "1" if failed else "0", why])
              for name, timeout, *counts, failed, why in STATUSES]
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------
# the C++ runtime's


@pytest.fixture(scope="module")
def driver(tmp_path_factory) -> Path:
    require_yarp(DEFAULT_YARP)
    require_ros2()
    build = tmp_path_factory.mktemp("services_runtime") / "build"
    r = subprocess.run(["cmake", "-S", str(SOURCE), "-B", str(build),
                        f"-DCMAKE_PREFIX_PATH={DEFAULT_YARP.cmake_prefix_path()}", find_once_option(),
                        f"-DYBGC_ROS2_PYTHON_ENV={VENV}"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-4000:]
    r = subprocess.run(["cmake", "--build", str(build), "-j2"], capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, r.stdout[-4000:] + r.stderr[-4000:]
    return build / "test_services_runtime"


def test_the_cpp_runtime_answers_as_the_python_runtime(driver):
    run = subprocess.run([str(driver)], input=driver_input(), capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    got = run.stdout.split("\n")[:-1]
    want = python_answers()
    cases = driver_input().split("\n")[:-1]
    assert len(got) == len(want) == len(cases)
    for case, g, w in zip(cases, got, want):
        assert g == w, f"case {case!r}:\n  C++:    {g!r}\n  Python: {w!r}"


def test_a_value_beyond_its_field_does_not_fit(driver):
    """An element beyond the range of its field (an int8, a float32) fails
    the call, said why, rather than wrapping (rclpy refuses such a value when
    the response is sent)."""
    case = "\t".join(["elements", "300 -129 127 -128 1e300 -3.4e38", "0", "-", "", WORDS,
                      "int8:0 int8:1 int8:2 int8:3 float32:4 float32:5"])
    run = subprocess.run([str(driver)], input=case + "\n", capture_output=True, text=True, timeout=60)
    assert run.stdout.rstrip("\n").split("\t") == [
        "ok", "unfit:element 0 is the integer 300, beyond the field's range",
        "unfit:element 1 is the integer -129, beyond the field's range", "127", "-128",
        "unfit:element 4 is the number 1e+300, beyond a float32", repr(struct.unpack("f", struct.pack("f", -3.4e38))[0])]


def test_the_cases_say_what_they_test():
    """A few answers spelled out, so that the comparison above compares something."""
    want = python_answers()
    assert want[0] == "ok\t[ok]\tok\tTrue\tunfit:element 0 is the word ok, not a number\t" \
                      "unfit:element 0 is the word ok, not an integer"
    assert want[15] == "unfit:2 elements, expected 1"
    assert want[16].startswith("ok\t(garbage 1.5) 42\t42.0\tunfit:element 0 is a list (garbage 1.5), not a word\t")
    assert want[19] == "ok\t1\t1\tTrue"
    assert texts.STATS_KEYS == ("calls", "answered", "failed", "timed_out", "no_server", "unfit")
