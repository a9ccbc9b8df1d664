"""The values tests of the behaviour harness (harness/behaviour.py): what a
module makes of the Bottles it reads, in order, nested, converted, and what
it drops (wrong sizes or types, NaN) and counts. ``BridgeBehaviour`` takes
them from ``ValuesBehaviour``, its base, so that a backend's test class has
them as its own."""
from __future__ import annotations

import math
import signal
import time

import pytest

from harness.module import assert_clean_exit, totals
from harness.programs import DEG
from harness.reference import exactly
from harness.yarp import YarpProducer, YarpReader

#: for a test that counts an input's stale periods (0) but is not about
#: staleness: an input stale only after 30 s without data, so that the time a
#: loaded machine takes between the test's steps cannot make one
NEVER_STALE = ("--timeout", "30")


class ValuesBehaviour:
    """What every backend's module makes of the values it reads (the part of
    ``BridgeBehaviour`` about values; the fixtures ``modules``, ``env`` and
    ``yarp_server`` are the backend's test class's)."""


    def test_values_order_nesting_counter_and_stamps(self, modules, yarp_server, env):
        """Every kind of source in order, nested, of its wire type: trigger =
        all waits for both muxes; the counter counts messages; the stamps
        are the module's clock and the envelope of sens."""
        arm = [0.0, 90.0, 180.0, -45.0, 30.5, 1e-7, 30]  # 30: an int32 on an undeclared input
        sens = [7, -3, 0.25, "abc", 1]
        with modules.module("values_bridge", env, *NEVER_STALE) as module, \
                YarpReader(env, "/test/values:i", source="/values_bridge/out:o") as reader, \
                YarpProducer(env, "/t/arm:o") as p_arm, YarpProducer(env, "/t/sens:o") as p_sens:
            module.wait_log("connected /t/sens:o -> /values_bridge/sens/in0:i")
            module.wait_log("connected /t/arm:o -> /values_bridge/arm/in0:i")
            reader.wait_connected()
            p_arm.write(arm)
            time.sleep(0.3)
            assert reader.bottles == []  # trigger = all: sens has not delivered yet
            t_write = time.time()
            p_sens.write(sens, stamp=[5, 1234.5678])
            (got,) = reader.wait_for(1)
            d, types = got.data, got.types
            rad = [x * DEG + 0.0 for x in arm]
            assert d[0] == "hello"
            assert d[1] == 0  # counter
            # the module's clock when it built the message: after the write that
            # completed it, before the reader had it (one machine, one clock)
            assert t_write <= d[2] <= got.t, (t_write, d[2], got.t)  # seconds
            sec, nsec = d[3]
            assert t_write <= sec + nsec / 1e9 <= got.t and 0 <= nsec < 1_000_000_000, (t_write, d[3], got.t)
            assert d[4] == [1234, 567800000]  # the envelope stamp of sens
            assert exactly(d[5], rad)
            assert all(abs(a - math.radians(b)) <= 1e-12 for a, b in zip(d[5], arm))
            assert d[5][1] == pytest.approx(math.pi / 2, abs=1e-12)
            assert d[5][2] == pytest.approx(math.pi, abs=1e-12)
            assert exactly(d[6], rad[0])
            assert d[7:9] == [7, -1]  # -3 * 0.5 = -1.5, an int32 stays an integer: truncated to -1
            assert exactly(d[9], 0.25 * 2.0 + 1.0)
            assert d[10:12] == ["abc", 1]
            assert exactly(d[12], [1.5, [1, 2, 3], [], rad[0:3]])
            assert d[13:15] == [2 ** 40, 4000000000]
            assert exactly(d[15], 0.1)  # a float32 goes as a float64 on a YARP output
            assert d[16:] == [[], [0, 0], [0, 0, 0]]  # defaults of float64[], time, int32[3]
            assert types == ["string", "int32", "float64", ["int64", "int64"], ["int64", "int64"],
                             ["float64"] * 7, "float64", "int32", "int32", "float64", "string", "int32",
                             ["float64", ["int64"] * 3, [], ["float64"] * 3], "int64", "int64", "float64",
                             [], ["int64", "int64"], ["int32"] * 3]
            # the next message only when both inputs have new data; the counter counts messages
            p_arm.write([1.0, 2.0, 3.0])
            time.sleep(0.3)
            assert len(reader.bottles) == 1
            p_sens.write([8, 9, -0.25, "x", 0])
            (_, second) = reader.wait_for(2)
            assert second.data[1] == 1
            assert exactly(second.data[5], [DEG, 2 * DEG, 3 * DEG])
            assert second.data[7:12] == [8, 4, -0.25 * 2.0 + 1.0, "x", 0]
            rc, elapsed = module.interrupt(signal.SIGINT)
        log = assert_clean_exit(yarp_server, module, rc, elapsed,
                                ["/values_bridge/out:o", "/values_bridge/arm/in0:i",
                                 "/values_bridge/sens/in0:i"])
        assert "input /t/arm:o: received 2, dropped 0, stale periods" in log
        assert totals(log)["/t/arm:o"] == (2, 0, 0)
        assert totals(log)["published"] == 2

    def test_indexed_labels_nest_one_list_per_index(self, modules, yarp_server, env):
        """Indexed labels of an untyped Bottle (the elements of an array):
        one nested list per index, in the order of the indices, each holding
        its parts in the order written."""
        with modules.module("indexed_bridge", env) as module, \
                YarpReader(env, "/test/indexed:i", source="/indexed_bridge/out:o") as reader, \
                YarpProducer(env, "/test/a:o") as a:
            module.wait_log("connected /test/a:o -> /indexed_bridge/m/in0:i")
            reader.wait_connected()
            a.write([1.5, -2.25, 3.0])
            (got,) = reader.wait_for(1)
            a.write([4.0, 5.0, 6.0])
            (_, second) = reader.wait_for(2)
            rc, elapsed = module.interrupt(signal.SIGINT)
        assert got.data == [[[1.5, "first"], [-2.25, "second"], [1.5, -2.25, 3.0]], 0]
        assert got.types == [[["float64", "string"], ["float64", "string"], ["float64"] * 3], "int32"]
        assert second.data == [[[4.0, "first"], [5.0, "second"], [4.0, 5.0, 6.0]], 1]
        assert_clean_exit(yarp_server, module, rc, elapsed)

    @pytest.mark.parametrize("args", [(), ("--rate", "20")], ids=["event-driven", "fixed-rate"])
    def test_producer_never_starts(self, modules, yarp_server, env, args):
        """Inputs that never deliver: the module waits (says so once per
        input), publishes nothing, and exits cleanly; event-driven or at a
        fixed rate."""
        with modules.module("values_bridge", env, *args) as module, \
                YarpReader(env, "/test/never:i", source="/values_bridge/out:o") as reader:
            reader.wait_connected()
            module.wait_log("waiting for /t/arm:o")
            module.wait_log("waiting for /t/sens:o")
            time.sleep(2.5)
            assert module.alive
            assert module.count(r"waiting for /t/arm:o") == 1
            assert module.count(r"waiting for /t/sens:o") == 1
            assert reader.bottles == []
            rc, elapsed = module.interrupt(signal.SIGTERM)
        log = assert_clean_exit(yarp_server, module, rc, elapsed,
                                ["/values_bridge/out:o", "/values_bridge/arm/in0:i"])
        assert "input /t/arm:o: received 0, dropped 0, stale periods 0" in log
        assert "published 0 messages" in log

    def test_malformed_bottles_and_nan_are_dropped_and_counted(self, modules, yarp_server, env):
        """Bottles of the wrong size or element types, and NaN (on_nan =
        drop), on two inputs: dropped, the first of each input said, all
        counted; the module goes on."""
        with modules.module("values_bridge", env, *NEVER_STALE) as module, \
                YarpReader(env, "/test/drops:i", source="/values_bridge/out:o") as reader, \
                YarpProducer(env, "/t/arm:o") as p_arm, YarpProducer(env, "/t/sens:o") as p_sens:
            module.wait_log("connected /t/sens:o")
            module.wait_log("connected /t/arm:o")
            reader.wait_connected()
            # spaced out: an input keeps only its newest Bottle, so a burst could
            # reach the checks as its last Bottle only
            for producer, data in ((p_sens, [1, 2, 3.0, "a"]),          # 4 elements, expected 5
                                   (p_sens, [1, "two", 3.0, "a", 1]),   # a string where an int32 goes
                                   (p_sens, [1, 2, 3.0, "a", 2]),       # 2 is not a bool
                                   (p_arm, [1.0, float("nan")]),        # on_nan = drop
                                   (p_arm, [1.0, "x"]),                 # not a number
                                   (p_arm, [1.0, [2.0]])):              # a list is not a number
                producer.write(data)
                time.sleep(0.15)
            time.sleep(0.3)
            assert reader.bottles == []
            p_arm.write([10.0, 20.0, 30.0])
            p_sens.write([4, 5, 6.0, "ok", 1])
            (got,) = reader.wait_for(1)
            assert got.data[10] == "ok" and exactly(got.data[5], [10.0 * DEG, 20.0 * DEG, 30.0 * DEG])
            time.sleep(0.3)
            assert len(reader.bottles) == 1
            assert module.alive
            assert module.count(r"input /t/sens:o: dropped a Bottle \(4 elements, expected 5\)") == 1
            assert module.count(r"input /t/arm:o: dropped a Bottle \(element 1 is NaN\)") == 1
            assert module.count(r"dropped a Bottle") == 2  # the first drop of each input only
            rc, elapsed = module.interrupt()
        log = assert_clean_exit(yarp_server, module, rc, elapsed)
        assert "input /t/sens:o: received 4, dropped 3, stale periods 0" in log
        assert "input /t/arm:o: received 4, dropped 3, stale periods 0" in log
        assert "published 1 messages" in log

    def test_malformed_bottles_of_one_input_dropped_and_counted(self, modules, yarp_server, env):
        """One declared input (int32, float64 x2): a float64 takes an int;
        wrong sizes, a float or a string where an int32 goes, a list, NaN
        (on_nan = drop) are dropped; the first drop said, all counted."""
        with modules.module("strict_bridge", env, *NEVER_STALE) as module, \
                YarpReader(env, "/test/reader", source="/strict_bridge/out:o") as reader, \
                YarpProducer(env, "/test/a:o") as a:
            a.wait_outputs(1, timeout=60)
            reader.wait_connected(timeout=60)
            a.write([1, 2.0, 3])            # ok: float64 takes an int
            reader.wait_for(1)
            for bad in ([1, 2.0],               # wrong size
                        [1, 2.0, 3.0, 4.0],     # wrong size
                        [1.5, 2.0, 3.0],        # float where int32
                        ["x", 2.0, 3.0],        # string
                        [1, [2.0], 3.0],        # list
                        [1, float("nan"), 3.0]):  # NaN, on_nan = drop
                a.write(bad)
                time.sleep(0.05)  # one at a time: an input keeps only the newest Bottle
            a.write([4, 5.0, 6.0])          # ok
            got = reader.wait_for(2)
            time.sleep(0.3)
            rc, elapsed = module.interrupt(signal.SIGTERM)
        log = assert_clean_exit(yarp_server, module, rc, elapsed, ["/strict_bridge/out:o"])
        assert [g.data for g in reader.bottles] == [[0, [1, 2.0, 3.0]], [1, [4, 5.0, 6.0]]]
        assert exactly([g.data for g in reader.bottles], [[0, [1, 2.0, 3.0]], [1, [4, 5.0, 6.0]]])
        assert got[0].types == ["int32", ["int32", "float64", "float64"]]
        assert totals(log)["/test/a:o"] == (8, 6, 0)
        assert log.count("dropped a Bottle") == 1  # the first drop is reported, the rest counted
        assert "2 elements, expected 3" in log
        assert totals(log)["published"] == 2

    def test_nan_passes_by_default(self, modules, yarp_server, env):
        """on_nan = pass (the default): NaN goes out; an undeclared input's
        elements all go as float64."""
        with modules.module("relay_bridge", env) as module, \
                YarpReader(env, "/test/nan:i", source="/relay_bridge/out:o") as reader, \
                YarpProducer(env, "/t/src:o") as a:
            a.wait_outputs(1, timeout=60)
            reader.wait_connected(timeout=60)
            a.write([float("nan"), 1])
            (got,) = reader.wait_for(1)
            rc, elapsed = module.interrupt(signal.SIGTERM)
        assert_clean_exit(yarp_server, module, rc, elapsed)
        assert math.isnan(got.data[1]) and exactly(got.data[2], 1.0)
        assert got.types[1:] == ["float64", "float64"]  # undeclared: every element a float64
