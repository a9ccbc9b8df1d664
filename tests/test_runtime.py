"""The runtime library (ybg/runtime/), tested as code.

- The Python logic (``ybg.runtime.core``) with no middleware at all: the
  converters, slices, counters, times, and the bridge's matching of Bottles
  into messages, its queues and its freshness, driven by hand with the
  arrival times and envelopes a test chooses (nothing waits on a clock).
- The reading of input Bottles (``ybg.runtime.yarp_inputs.parse_bottle``) on
  real YARP Bottles, with no name server.
- How the runtime reaches a module: its files beside the module (the
  library's own, under a banner), its version, a module refusing a runtime of another
  version (Python at start, C++ at build), ``--single-file``.

The C++ runtime's own unit tests are tests/runtime/test_runtime.cpp, built
and run by tests/test_runtime_cpp.py.
"""

from __future__ import annotations

import argparse
import math
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import ybg
import ybg.runtime
from harness.bridges import hand_bridge
from harness.generated import module_file, ybgc
from harness.procs import wait_until
from ybg.backends import RenderOptions, get_backend
from ybg.backends.runtime import CPP_DIR, cpp_files, python_files, python_inline
from ybg.compiler.pipeline import compile_path
from ybg.runtime import core
from ybg.runtime.core import (Array, BridgeSpec, ConverterSpec, Context, InputSpec, Msg, MuxSpec, Scalar,
                              convert, seconds_to_ns, take, time_msg)

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "yarp_to_yarp_end_effector.ini"


# --------------------------------------------------------------------------
# converters, slices, counters, times


def conv(scale=1.0, offset=0.0, to_float=False, start=0, stop=None):
    return ConverterSpec("c", scale=scale, offset=offset, to_float=to_float, start=start, stop=stop)


def test_converter_is_scale_then_offset_on_its_range():
    deg = math.pi / 180
    assert convert([180.0, 90.0, 45.0], (conv(deg, start=1),)) == [180.0, 90.0 * deg, 45.0 * deg]
    assert convert([1.0, 2.0], (conv(2.0, 1.0),)) == [3.0, 5.0]
    # applied in order, each on its own range; a range past the end is cut
    assert convert([1.0, 1.0, 1.0], (conv(10.0, stop=2), conv(offset=1.0, start=1, stop=99))) == [10.0, 11.0, 2.0]
    # an empty range changes nothing; no converter returns the same list
    values = [1.0, 2.0]
    assert convert(values, (conv(5.0, start=2),)) == values
    assert convert(values, ()) is values


def test_geometry_and_expression_converters():
    """As the C++ runtime (tests/runtime/test_runtime.cpp): a geometry
    converter replaces its range by its results, a mux too short for it is
    left as it is; an expression makes each number of its range a float64."""
    from ybg.runtime.core import EachSpec, GeometrySpec
    from ybg.runtime.geometry import clamp

    out = convert(["id", 0.0, 0.0, 90, 7.0], (GeometrySpec("e", "euler_to_quat", ("xyz", True), 1),))
    h = 90.0 * (math.pi / 180.0) * 0.5
    assert out == ["id", 0.0, 0.0, math.sin(h), math.cos(h), 7.0]
    assert convert([1.0, 2.0], (GeometrySpec("n", "quat_normalize", (), 0),)) == [1.0, 2.0]
    out = convert([3, "s", -5.0, 9.0], (EachSpec("c", lambda x: clamp(x, -1.0, 1.0) * 0.5, 0, 3),))
    assert out == [0.5, "s", -0.5, 9.0] and type(out[0]) is float


def test_converter_keeps_integers_unless_told():
    out = convert([3, 7, 2.5], (conv(0.5),))
    assert out == [1, 3, 1.25] and isinstance(out[0], int) and isinstance(out[1], int)
    out = convert([3, 7], (conv(0.5, to_float=True),))
    assert out == [1.5, 3.5] and all(isinstance(x, float) for x in out)
    # the identity converter with to_float turns integers into floats
    assert [type(x) for x in convert([1, 2], (conv(to_float=True),))] == [float, float]


def test_slices_are_never_silently_shortened():
    assert take([1, 2, 3, 4], 1, 3) == [2, 3]
    assert take([1, 2, 3], 0, None) == [1, 2, 3]
    assert take([1, 2, 3], 3, None) == []
    for start, stop in ((0, 4), (4, None), (2, 5)):
        with pytest.raises(IndexError, match="slice"):
            take([1, 2, 3], start, stop)


@pytest.mark.parametrize("type_,counter,want", [
    ("uint32", 2**32 + 3, 3), ("uint32", 7, 7), ("int32", 2**31, -2**31), ("int8", 130, -126),
    ("uint8", 256, 0), ("char", 300, 44), ("int64", 2**63, -2**63), ("float64", 12345, 12345),
])
def test_counter_wraps_like_its_ros_type(type_, counter, want):
    assert Context({}, counter, {}).count(type_) == want


def test_times_in_both_ros_styles():
    ros1 = time_msg(1_500_000_123, "ros1")
    assert ros1.type == "time"
    assert [(n, s.type, s.value) for n, s in ros1.fields] == [("secs", "uint32", 1), ("nsecs", "uint32", 500_000_123)]
    ros2 = time_msg(2_000_000_001, "ros2")
    assert ros2.type == "builtin_interfaces/Time"
    assert [(n, s.value) for n, s in ros2.fields] == [("sec", 2), ("nanosec", 1)]


def test_envelope_time_of_a_mux_else_the_wall_clock():
    ctx = Context({}, 0, {"a": 12.25, "b": None})
    assert [s.value for _, s in ctx.envelope_time("a", "ros2").fields] == [12, 250_000_000]
    wall = [s.value for _, s in ctx.envelope_time("b", "ros2").fields]
    assert wall == [s.value for _, s in ctx.wall_time("ros2").fields]
    assert abs(wall[0] - ctx.seconds) <= 1
    # an envelope of today's epoch keeps its nanoseconds (t * 1e9 alone: 249999872)
    ctx = Context({}, 0, {"a": 1700000000.25, "n": math.nan})
    assert [s.value for _, s in ctx.envelope_time("a", "ros2").fields] == [1700000000, 250_000_000]
    assert [s.value for _, s in ctx.envelope_time("n", "ros2").fields] == [s.value for _, s in ctx.wall_time("ros2").fields]


def test_a_context_at_a_given_time_is_that_time_everywhere():
    """A ROS 2 node gives its clock's time (simulated with use_sim_time):
    `time`, `timestamp` and an envelope's fallback are all that time."""
    ctx = Context({}, 0, {"a": None}, now_ns=4242_500_000_001)
    assert ctx.seconds == 4242.500000001
    assert [s.value for _, s in ctx.wall_time("ros2").fields] == [4242, 500_000_001]
    assert [s.value for _, s in ctx.envelope_time("a", "ros1").fields] == [4242, 500_000_001]
    assert [s.value for _, s in Context({}, 0, {}, now_ns=0).wall_time("ros2").fields] == [0, 0]


def test_seconds_to_ns_is_exact_to_the_nanosecond():
    from fractions import Fraction
    import random

    assert seconds_to_ns(1700000000.25) == 1_700_000_000_250_000_000
    assert seconds_to_ns(0.5) == 500_000_000 and seconds_to_ns(-0.25) == -250_000_000
    assert seconds_to_ns(-1.0) == -1_000_000_000 and seconds_to_ns(0.0) == 0
    assert seconds_to_ns(math.inf) is None and seconds_to_ns(math.nan) is None
    rng = random.Random(7)
    for _ in range(2000):
        t = rng.uniform(-2e9, 2e9)
        exact = Fraction(t) * 10**9  # the double's own value, in nanoseconds
        assert abs(seconds_to_ns(t) - exact) <= Fraction(1, 2) + Fraction(1, 10**6), t


# --------------------------------------------------------------------------
# the bridge's logic, driven by hand


class Recorder:
    """An output that keeps what it is given."""

    port_name = "/test/out:o"

    def __init__(self):
        self.messages = []

    def publish(self, tree):
        self.messages.append(tree)


def bridge(muxes=("a", "b"), rate=None, trigger="all", queue=64, on_stale="skip", timeout=0.5,
           needed=None, build=None):
    specs = tuple(MuxSpec(m, (InputSpec(m, 0, f"/src/{m}:o", "yarp", types=None, timeout=timeout),),
                          (), False, None) for m in muxes)
    spec = BridgeSpec("test", "test.ini", ("test",), specs, tuple(needed if needed is not None else muxes),
                      rate, trigger, queue, on_stale, "pass")
    options = argparse.Namespace(prefix="/test", rate=None, timeout=None, verbose=False)
    out = Recorder()

    def default_build(ctx):
        return {m: list(ctx.values[m]) for m in muxes}

    return hand_bridge(spec, options, out, build or default_build), out


def arrive(b, mux, values, now, envelope=None, reason=None):
    inp = b.mux_inputs[mux][0]
    b.on_bottle(inp, values, reason, now, envelope)
    return inp


def test_event_driven_trigger_all_pairs_bottles_by_envelope():
    """Each message takes one Bottle of every needed input, matched by
    envelope stamp to the newest of the oldest: a Bottle of tick 2 that
    arrives before tick 1's partner is paired with tick 2's."""
    b, out = bridge()
    b.publishing = True
    arrive(b, "a", [1.0], now=10.0, envelope=1.0)
    arrive(b, "a", [2.0], now=10.1, envelope=2.0)
    assert out.messages == []  # b has delivered nothing
    arrive(b, "b", [20.0], now=10.2, envelope=2.0)
    # reference: the newest of the oldest = b's 2.0; a's nearest is 2.0, its 1.0 unused
    assert out.messages == [{"a": [2.0], "b": [20.0]}]
    assert b.mux_inputs["a"][0].unused == 1
    arrive(b, "b", [30.0], now=10.3, envelope=3.0)
    arrive(b, "a", [3.0], now=10.35, envelope=3.0)
    assert out.messages[-1] == {"a": [3.0], "b": [30.0]}
    assert b.published == 2


def test_event_driven_without_envelopes_matches_by_arrival():
    b, out = bridge()
    b.publishing = True
    arrive(b, "a", [1.0], now=1.00)
    arrive(b, "a", [2.0], now=1.50)
    arrive(b, "b", [9.0], now=1.45)
    assert out.messages == [{"a": [2.0], "b": [9.0]}]  # 1.50 is nearer to 1.45 than 1.00


def test_trigger_any_publishes_each_bottle_once_with_the_others_newest():
    b, out = bridge(trigger="any")
    b.publishing = True
    arrive(b, "a", [1.0], now=1.0)
    assert out.messages == []  # b never delivered: skip holds nothing back, b is waiting
    arrive(b, "b", [5.0], now=1.1)
    arrive(b, "a", [2.0], now=1.2)
    assert out.messages == [{"a": [1.0], "b": [5.0]}, {"a": [2.0], "b": [5.0]}]


def test_queue_is_bounded_and_counts_what_it_drops():
    b, out = bridge(queue=3)
    for k in range(10):
        arrive(b, "a", [float(k)], now=float(k), envelope=float(k))
    inp = b.mux_inputs["a"][0]
    assert [e[0] for e in inp.queue] == [[7.0], [8.0], [9.0]]
    assert (inp.received, inp.unused) == (10, 7)
    assert out.messages == []  # nothing published before the output is open


def test_queue_of_one_keeps_the_newest():
    b, _ = bridge(queue=1)
    for k in range(3):
        arrive(b, "a", [float(k)], now=float(k))
    inp = b.mux_inputs["a"][0]
    assert [e[0] for e in inp.queue] == [[2.0]] and inp.unused == 2


def test_dropped_bottles_are_counted_and_reported_once():
    b, out = bridge()
    b.publishing = True
    for k in range(3):
        arrive(b, "a", None, now=float(k), reason="element 0 is a string, expected float64")
    inp = b.mux_inputs["a"][0]
    assert (inp.received, inp.dropped, len(inp.queue)) == (3, 3, 0)
    assert [t for t in b.logged if "dropped" in t] == [
        "input /src/a:o: dropped a Bottle (element 0 is a string, expected float64); "
        "further drops are only counted"]


def test_a_bottle_wider_than_the_message_reads_is_said_once():
    """An undeclared port that a nested message cuts (W511, InputSpec.reads):
    the first Bottle bringing more values than the message reads is said,
    once; every Bottle is still used whole by the mux."""
    b, out = bridge(muxes=("a",))
    inp = b.mux_inputs["a"][0]
    inp.spec = inp.spec._replace(reads=3)
    b.publishing = True
    arrive(b, "a", [1.0, 2.0, 3.0], now=0.0)
    assert b.logged == []
    arrive(b, "a", [float(k) for k in range(7)], now=1.0)
    arrive(b, "a", [float(k) for k in range(9)], now=2.0)
    assert b.logged == [
        "input /src/a:o: a Bottle of 7 values, of which the message reads the first 3; the other 4 are "
        "dropped (declare the port's elements in the config to check its width); said once"]
    assert [len(m["a"]) for m in out.messages] == [3, 7, 9]


def test_a_port_the_message_reads_whole_says_nothing_of_its_width():
    b, out = bridge(muxes=("a",))
    b.publishing = True
    arrive(b, "a", [float(k) for k in range(9)], now=0.0)
    assert b.logged == [] and len(out.messages) == 1


def test_freshness_transitions_are_reported_once_each():
    b, _ = bridge(timeout=0.5)
    b._check_freshness(0.0)
    b._check_freshness(0.1)
    assert b.logged == ["waiting for /src/a:o", "waiting for /src/b:o"]
    arrive(b, "a", [1.0], now=1.0)
    assert b._check_freshness(1.2) == 1.5  # the next deadline: when a would go stale
    b._check_freshness(1.6)
    b._check_freshness(1.7)
    assert [t for t in b.logged if "stale" in t] == ["input /src/a:o is stale (no data for 0.6 s)"]
    arrive(b, "a", [2.0], now=2.0)
    arrive(b, "a", [3.0], now=2.1)
    assert [t for t in b.logged if "fresh again" in t] == ["input /src/a:o is fresh again"]
    assert b.mux_inputs["a"][0].stale_periods == 1


def test_on_stale_skip_waits_for_every_needed_input_to_be_fresh():
    b, out = bridge(rate=10.0, on_stale="skip")
    arrive(b, "a", [1.0], now=0.0)
    arrive(b, "b", [2.0], now=0.0)
    assert b._ready(False)
    b._check_freshness(1.0)  # both stale
    assert not b._ready(False)


def test_on_stale_hold_publishes_the_last_values():
    b, out = bridge(rate=10.0, on_stale="hold")
    assert not b._ready(False)  # nothing delivered yet
    arrive(b, "a", [1.0], now=0.0)
    assert not b._ready(False)  # b still waiting
    arrive(b, "b", [2.0], now=0.0)
    b._check_freshness(5.0)
    assert b._ready(False)
    raw, envelopes = b._snapshot(False)
    b._publish(raw, envelopes)
    assert out.messages == [{"a": [1.0], "b": [2.0]}]


def test_fixed_rate_takes_the_newest_and_leaves_the_rest_unused():
    b, out = bridge(rate=100.0)
    for k in range(4):
        arrive(b, "a", [float(k)], now=float(k) / 100)
    arrive(b, "b", [9.0], now=0.0)
    raw, _ = b._snapshot(False)
    assert raw == {"a": [3.0], "b": [9.0]}
    assert b.mux_inputs["a"][0].unused == 3


def test_fixed_rate_publishing_new_data_only():
    """publish = new: a cycle publishes only when the trigger holds (a
    command goes out once, not at every cycle); always: every cycle."""
    b, out = bridge(rate=50.0)
    b.spec = b.spec._replace(publish="new", trigger="any")
    arrive(b, "a", [1.0], now=0.0)
    arrive(b, "b", [2.0], now=0.0)
    assert b._ready(False)
    b._publish(*b._snapshot(False))
    assert not b._ready(False)  # nothing new since: the cycle publishes nothing
    arrive(b, "b", [3.0], now=0.1)
    assert b._ready(False)  # any: one new Bottle is enough
    b._publish(*b._snapshot(False))
    assert out.messages == [{"a": [1.0], "b": [2.0]}, {"a": [1.0], "b": [3.0]}]
    b.spec = b.spec._replace(trigger="all")
    arrive(b, "b", [4.0], now=0.2)
    assert not b._ready(False)  # all: a has nothing new
    always, _ = bridge(rate=50.0)
    arrive(always, "a", [1.0], now=0.0)
    arrive(always, "b", [2.0], now=0.0)
    always._snapshot(False)
    assert always._ready(False)  # every cycle, with the newest values


def test_inputs_not_needed_are_sampled_not_waited_for():
    b, out = bridge(needed=("a",))
    b.publishing = True
    arrive(b, "b", [7.0], now=0.0)
    assert out.messages == []
    arrive(b, "a", [1.0], now=0.1)
    arrive(b, "a", [2.0], now=0.2)
    assert out.messages == [{"a": [1.0], "b": [7.0]}, {"a": [2.0], "b": [7.0]}]


def test_a_message_that_cannot_be_built_is_counted_not_raised():
    def short(ctx):
        return take(ctx.values["a"], 0, 3)

    b, out = bridge(muxes=("a",), build=short)
    b.publishing = True
    arrive(b, "a", [1.0], now=0.0)
    arrive(b, "a", [2.0], now=0.1)
    assert out.messages == [] and b.build_errors == 2
    assert len([t for t in b.logged if "cannot build the message" in t]) == 1


def test_converters_and_compute_run_before_the_builder():
    spec_conv = (ConverterSpec("x10", 10.0, 0.0, False, 0, None),)
    b, out = bridge(muxes=("a",))
    b.spec = b.spec._replace(muxes=(b.spec.muxes[0]._replace(converters=spec_conv),))
    b.compute = lambda v: v["a"].append(-1.0)
    b.publishing = True
    arrive(b, "a", [1.5], now=0.0)
    assert out.messages == [{"a": [15.0, -1.0]}]


def test_message_tree_nodes():
    tree = Msg("geometry_msgs/Point", (("x", Scalar("float64", 1.0)), ("v", Array("int32", (1, 2)))))
    assert tree.fields[1][1].values == (1, 2)
    assert "Scalar('float64', 1.0)" in repr(tree)


def test_command_line_options():
    spec = BridgeSpec("m", "m.ini", ("about m",), (), (), 10.0, "all", 64, "skip", "pass")
    o = core.parse_options(spec, ["--rate", "0", "--prefix", "/x", "--timeout", "2"], "/m")
    assert (o.prefix, o.rate, o.timeout, o.verbose) == ("/x", 0.0, 2.0, False)
    for bad in (["--rate", "-1"], ["--prefix", "x"], ["--timeout", "0"]):
        with pytest.raises(SystemExit):
            core.parse_options(spec, bad, "/m")


def test_core_imports_no_middleware():
    """The logic imports only the standard library (run in a fresh process:
    this one has YARP and rclpy loaded by other tests)."""
    code = ("import sys; import ybg.runtime.core; "
            "print(' '.join(sorted(m for m in ('yarp', 'rclpy') if m in sys.modules)))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                       env={**os.environ, "PYTHONPATH": str(ROOT)})
    assert r.stdout.strip() == ""


# --------------------------------------------------------------------------
# input Bottles, on real YARP Bottles (no name server)


def bottle(text):
    import yarp
    b = yarp.Bottle()
    b.fromString(text)
    return b


def test_parse_bottle_layouts():
    from ybg.runtime.yarp_inputs import parse_bottle

    # undeclared: any number of numbers, each as it came (an integer stays one)
    values, why = parse_bottle(bottle("1 2.5 -3"), None, False, False)
    assert values == [1, 2.5, -3] and [type(x) for x in values] == [int, float, int] and why is None
    values, why = parse_bottle(bottle("1 hello"), None, False, False)
    assert values is None and why == "element 1 is a string, not a number"
    # declared: count and type of every element
    assert parse_bottle(bottle('7 2.5 "x" 1'), ("int32", "float64", "string", "bool"), False, False) == \
        ([7, 2.5, "x", True], None)
    assert parse_bottle(bottle("1 2"), ("float64",), False, False) == (None, "2 elements, expected 1")
    assert parse_bottle(bottle("1.5"), ("int32",), False, False) == \
        (None, "element 0 is a float, expected int32")
    assert parse_bottle(bottle("2"), ("bool",), False, False)[1] == "element 0 is an integer, expected a bool (0 or 1)"
    # NaN dropped only when told
    assert parse_bottle(bottle("1.0 nan"), None, False, True) == (None, "element 1 is NaN")
    assert math.isnan(parse_bottle(bottle("1.0 nan"), None, False, False)[0][1])
    # a ROS 1 message read as a Bottle: nested lists, flattened or picked
    nested = bottle("(1 2) 3.5 (4 (5 6))")
    assert parse_bottle(nested, None, True, False) == ([1, 2, 3.5, 4, 5, 6], None)
    assert parse_bottle(nested, ("float64", "float64"), False, False, positions=((1,), (2, 1, 0)))[0] == [3.5, 5.0]
    assert parse_bottle(nested, ("float64",), False, False, positions=((9,),))[1] == \
        "not laid out as its message type (a field is missing)"


def test_undeclared_values_go_on_as_they_came():
    """`set pos 3 45.0` from an undeclared port: the integer stays an int32,
    a big integer an int64, a real a float64 (docs/runtime.md)."""
    import yarp

    from ybg.runtime.core import Splice
    from ybg.runtime.yarp_io import fill_bottle
    from ybg.lower.wire import WIRE_YARP

    values, _ = parse_bottle_of("3 45.0 1099511627776")
    out = fill_bottle(yarp.Bottle(), Msg(None, (("cmd", Scalar("string", "set")), ("v", Splice("number", values)))),
                      WIRE_YARP)
    assert out.toString() == "set 3 45.0 1099511627776"
    assert out.get(1).isInt32() and out.get(2).isFloat64() and out.get(3).isInt64()


def test_arrays_of_messages_and_rows_in_a_bottle():
    """An Array of messages: a nested list of one nested list per message;
    Rows (a mux read from an array of messages): a nested list per row,
    appended one by one or, nested, inside one list of their own."""
    import yarp

    from ybg.runtime.core import Rows
    from ybg.runtime.yarp_io import fill_bottle
    from ybg.lower.wire import WIRE_YARP

    point = lambda x: Msg("geometry_msgs/Point", (("x", Scalar("float64", x)), ("n", Scalar("int32", 2))))
    tree = Msg(None, (("points", Array("geometry_msgs/Point", (point(1.5), point(-2.0)))),
                      ("none", Array("geometry_msgs/Point", ())),
                      ("rows", Rows("number", [[0.5, 1], [1.25, 2.0]])),
                      ("nested", Rows("float64", [[1.0]], nested=True))))
    out = fill_bottle(yarp.Bottle(), tree, WIRE_YARP)
    assert out.toString() == "((1.5 2) (-2.0 2)) () (0.5 1) (1.25 2.0) ((1.0))"
    assert out.get(2).asList().get(1).isInt32() and out.get(3).asList().get(1).isFloat64()


def test_rows_are_converted_alike():
    """A mux of rows: the converters apply to each row, on the row's range."""
    b, out = bridge(muxes=("a",))
    mux = b.spec.muxes[0]._replace(rows=True, converters=(ConverterSpec("x10", 10.0, 0.0, True, 1, None),))
    b.spec = b.spec._replace(muxes=(mux,))
    b.publishing = True
    arrive(b, "a", [[0.5, 1.0, 2.0], [1.5, 3.0]], now=0.0)
    assert out.messages == [{"a": [[0.5, 10.0, 20.0], [1.5, 30.0]]}]


def test_a_ros2_duration_is_read_as_seconds():
    from types import SimpleNamespace

    ros2_io = pytest.importorskip("ybg.runtime.ros2_io")
    element = SimpleNamespace(time_from_start=SimpleNamespace(sec=1, nanosec=250000000), positions=[0.5, 1])
    getters = tuple((p, lambda m, p=p: getattr(m, p)) for p in ("time_from_start", "positions"))
    assert ros2_io.message_values(element, getters, None, False) == ([1.25, 0.5, 1.0], None)


def parse_bottle_of(text):
    from ybg.runtime.yarp_inputs import parse_bottle
    return parse_bottle(bottle(text), None, False, False)


# --------------------------------------------------------------------------
# how the runtime reaches a module


def test_versions_agree():
    assert ybg.runtime.VERSION == ybg.__version__
    header = (CPP_DIR / "ybgc_runtime.hpp").read_text()
    assert f'#define YBGC_RUNTIME_VERSION "{ybg.__version__}"' in header


def runtime_files() -> dict[str, str]:
    # every part of the C++ library: its ROS 2 side, images, commands, composition ...
    import inspect

    return {**python_files(), **cpp_files(**{part: True for part in inspect.signature(cpp_files).parameters})}


def test_runtime_files_are_the_library_verbatim():
    """The runtime written beside a module is the library's own files, each
    under its two-line banner (so no golden copy of them is kept)."""
    # every file of the library, and nothing else
    library = {p.name for p in CPP_DIR.iterdir() if p.suffix in (".hpp", ".cpp")}
    library |= {p.name for p in Path(ybg.runtime.__file__).parent.glob("*.py")}
    assert {Path(name).name for name in runtime_files()} == library
    for name, text in runtime_files().items():
        first, second, rest = text.split("\n", 2)
        assert first.endswith(f"ybgc runtime {ybg.__version__}, generated by ybgc beside the modules it writes:")
        assert "do not edit" in second
        source = CPP_DIR / name if name.endswith("pp") else Path(ybg.runtime.__file__).parent / Path(name).name
        assert rest == source.read_text(encoding="utf-8")


@pytest.mark.parametrize("backend", ["cpp", "py", "ros2"])
def test_every_backend_writes_the_runtime_beside_or_inlines_it(backend):
    path = ROOT / "examples" / ("vizzy_rviz_joint_states.ini" if backend == "ros2" else EXAMPLE.name)
    program = compile_path(path).program
    files = get_backend(backend).render(program)
    expected = cpp_files() if backend == "cpp" else python_files()
    assert {k: v for k, v in files.items() if k in expected} == expected
    single = get_backend(backend).render(program, RenderOptions(single_file=True))
    assert not set(single) & set(expected)
    suffix = ".cpp" if backend == "cpp" else ".py"
    _, text = module_file(single, suffix)
    assert f"ybgc runtime {ybg.__version__}, inlined (--single-file)" in text
    if backend != "cpp":
        assert "ybgc:runtime-import" not in text and "from ." not in text
        compile(text, "single", "exec")


def test_inlined_python_runtime_defines_what_the_modules_import():
    text = python_inline()
    namespace_names = set(re.findall(r"^(?:class|def) (\w+)", text, re.M))
    for name in ("BridgeSpec", "Msg", "take", "YarpOutput", "run", "Ros2Output", "run_node", "floats"):
        assert name in namespace_names or re.search(rf"^{name} = ", text, re.M), name


def _generate(tmp_path: Path, backend: str, config: Path = EXAMPLE) -> Path:
    r = ybgc(config, "--backend", backend, "-o", tmp_path)
    assert r.returncode == 0, r.stderr + r.stdout
    return tmp_path


def test_python_module_refuses_a_runtime_of_another_version(tmp_path):
    folder = _generate(tmp_path, "py")
    module = folder / "end_effector_compare.py"
    ok = subprocess.run([sys.executable, str(module), "--help"], capture_output=True, text=True, cwd="/")
    assert ok.returncode == 0 and "usage" in ok.stdout, ok.stderr
    init = folder / "ybgc_runtime" / "__init__.py"
    init.write_text(init.read_text().replace(f'VERSION = "{ybg.__version__}"', 'VERSION = "0.1.9"'))
    bad = subprocess.run([sys.executable, str(module), "--help"], capture_output=True, text=True, cwd="/")
    assert bad.returncode == 1 and "Traceback" not in bad.stderr
    assert f"needs ybgc's runtime library {ybg.__version__} beside it" in bad.stderr
    assert "found: 0.1.9" in bad.stderr and "generate the module again" in bad.stderr
    # and with no runtime at all
    for f in (folder / "ybgc_runtime").iterdir():
        f.unlink()
    (folder / "ybgc_runtime").rmdir()
    gone = subprocess.run([sys.executable, str(module), "--help"], capture_output=True, text=True, cwd="/")
    assert gone.returncode == 1 and "found: none" in gone.stderr and "Traceback" not in gone.stderr


def test_regenerating_brings_the_runtime_of_this_version(tmp_path):
    folder = _generate(tmp_path, "py")
    core_file = folder / "ybgc_runtime" / "core.py"
    core_file.write_text(core_file.read_text().replace("ybgc runtime " + ybg.__version__, "ybgc runtime 0.1.9"))
    _generate(tmp_path, "py")
    assert core_file.read_text() == python_files()["ybgc_runtime/core.py"]


def test_thesis_demonstrations_give_thin_modules():
    """The module files of the thesis' three demonstrations are at most 200
    lines in every backend, and docs/runtime.md shows their measured table."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("module_lines", ROOT / "scripts" / "module_lines.py")
    lines = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(lines)
    for demo in lines.DEMOS:
        for backend in lines.BACKENDS:
            name, count = lines.module_lines(demo, backend)
            assert 40 < count <= lines.LIMIT, (demo, backend, name, count)
    assert lines.table() in (ROOT / "docs" / "runtime.md").read_text(encoding="utf-8")


WATCHER_SCRIPT = r"""
import sys, yarp
from ybg.runtime.connections import Watcher
yarp.Network.init()
port = yarp.BufferedPortBottle()
assert port.open("/rt/own:i")
watcher = Watcher([], lambda text: print(text, flush=True), [port])
watcher.start()
print("ready", flush=True)
sys.stdin.readline()
watcher.stop()
port.close()
"""


def test_watcher_registers_the_ports_again_with_a_restarted_name_server(yarp_server, tmp_path):
    """A name server killed and started again knows no port: the watcher
    registers the module's own ports again (at their address, said once),
    so that sources started since can be connected to them."""
    env = dict(yarp_server.env)
    env["PYTHONPATH"] = os.pathsep.join(p for p in (str(ROOT), env.get("PYTHONPATH")) if p)
    log = tmp_path / "watcher.log"
    with open(log, "w") as out:
        proc = subprocess.Popen([sys.executable, "-c", WATCHER_SCRIPT], env=env, stdin=subprocess.PIPE,
                                stdout=out, stderr=subprocess.STDOUT, text=True)
    try:
        wait_until(lambda: "ready" in log.read_text(), 30, "the watcher")
        before = yarp_server.yarp("name", "query", "/rt/own:i").stdout
        assert "registration name /rt/own:i" in before
        yarp_server.proc.kill()
        yarp_server.proc.start()
        wait_until(lambda: yarp_server.exists("/root"), 30, "the name server again")
        wait_until(lambda: yarp_server.exists("/rt/own:i"), 30, "/rt/own:i registered again")
        assert yarp_server.yarp("name", "query", "/rt/own:i").stdout == before  # the same address
        proc.communicate("\n", timeout=30)
    finally:
        proc.kill()
    text = log.read_text()
    assert proc.returncode == 0, text
    assert text.count("registered them again") == 1, text
