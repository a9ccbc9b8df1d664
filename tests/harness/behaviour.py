"""One behaviour harness for every backend: what a bridge module must do,
written once, run against each backend's module.

The behaviour tests are methods of ``BridgeBehaviour`` (every backend: YARP
ports in, YARP port out; its values tests are its base's, ``ValuesBehaviour``:
harness/behaviour_values.py), ``ModuleCommandLine`` (the command line of a YARP
module) and ``Ros1Behaviour`` (ROS 1 topics through YARP:
harness/behaviour_ros1.py). A backend's test
module subclasses them (``class TestCppBehaviour(...)``) and says only how
to start its module: the ``modules`` fixture returns a ``Launcher`` of that
backend (harness/launchers.py). (sqlglot's dialect ``Validator``: one base,
each dialect's test file says which dialect.) What a module must output is
the reference's (harness/reference.py); the programs they run are
harness/programs.py's ``PROGRAMS``.

Every situation the tests depend on is forced (SIGSTOP, a held stdout,
producers written one Bottle at a time, bursts acknowledged by the reader's
port), never left to a race with the machine's speed.
"""
from __future__ import annotations

import contextlib
import functools
import math
import os
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest

from harness.behaviour_values import ValuesBehaviour
from harness.env import EXAMPLES, base_env, free_port
from harness.module import (EXIT_BOUND, assert_clean_exit, assert_delivered, assert_fixed_rate, hold_the_reader,
                            stats, totals)
from harness.programs import DEG, EVIL_LIST, FIXED_STRINGS, hypothesis_strings, needs_ros1, bottle_configs
from harness.reference import (COUNTER, Envelope, assert_matches, exactly, expected, mux_values, sent_values,
                               topic_message)
from harness.ros1 import RospySubscriber, ros1_type_known, rospy_publisher
from harness.ros2 import Ros2Publisher
from harness.yarp import YarpProducer, YarpReader, yarp_env, yarp_ports
from ybg.runtime.core import MISSED_LINE

#: the runtime's bound on unread Bottles (docs/runtime.md, "Reading"): a
#: reader more than this far behind skips the oldest unread
BACKLOG = 64


class BridgeBehaviour(ValuesBehaviour):
    """What every backend's module does between YARP ports (and, for its
    configs, ROS topics): the values tests of ``ValuesBehaviour`` and the
    ones below. A subclass gives the ``modules`` fixture (a
    Launcher) and may override ``env`` (the environment every process of a
    test gets) and ``configs`` (the configs its backend builds)."""

    @pytest.fixture
    def env(self, yarp_server) -> dict:
        return yarp_server.env

    @classmethod
    def configs(cls) -> list[Path]:
        return bottle_configs(cls.backend)

    def pytest_generate_tests(self, metafunc):
        if "config" in metafunc.fixturenames:
            paths = self.configs()
            metafunc.parametrize("config", paths, ids=[p.stem for p in paths])

    # -- signals and faults

    @pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
    def test_signal_mid_stream(self, modules, yarp_server, env, sig):
        """A signal while messages stream: exit 0 within 2 s, the totals, and
        every port of the module gone from the name server."""
        with modules.module("relay_bridge", env) as module, \
                YarpReader(env, "/test/sig:i", source="/relay_bridge/out:o") as reader, \
                YarpProducer(env, "/t/src:o", bottles=[[1.0, 2.0, 3.0]], rate=100):
            reader.wait_for(20)
            assert {"/relay_bridge/data/in0:i", "/relay_bridge/out:o"} <= yarp_ports(yarp_server)
            rc, elapsed = module.interrupt(sig)
            assert rc == 0, module.log_text()[-2000:]
            assert elapsed < EXIT_BOUND
            assert not any(p.startswith("/relay_bridge") for p in yarp_ports(yarp_server))
        log = module.log_text()
        assert "totals:" in log and "Traceback" not in log
        assert totals(log)["published"] >= 20

    def test_producer_killed_and_restarted(self, modules, yarp_server, env):
        """A producer streaming at 20 Hz is killed: the input goes stale
        (said once), nothing is published meanwhile; restarted, it is
        connected again and the stream goes on, no message lost or repeated.
        --timeout and --prefix act."""
        producer = YarpProducer(env, "/t/src:o", bottles=[[5.0, 6.0]], rate=20)
        with modules.module("relay_bridge", env, "--timeout", "0.5", "--prefix", "/relay2") as module, \
                YarpReader(env, "/test/restart:i", source="/relay_bridge/out:o") as reader:
            yarp_server.wait_port("/relay2/data/in0:i", timeout=60)
            producer.start()
            try:
                reader.wait_for(5)
                producer.kill()
                module.wait_match(r"input /t/src:o is stale \(no data for 0\.\d s\)", timeout=60)
                # nothing published while stale: the module's own count, a second apart
                # (not the reader's, which a loaded machine may leave behind)
                published = stats(yarp_server, "/relay2/rpc:i")["published"][0]
                time.sleep(1.0)
                assert stats(yarp_server, "/relay2/rpc:i")["published"][0] == published
                assert module.count(r"is stale") == 1  # said once, not once per cycle
                n = len(reader.bottles)
                producer.start()
                reader.wait_for(n + 5, timeout=60)
                module.wait_log("input /t/src:o is fresh again")
                assert module.count(r"connected /t/src:o -> /relay2/data/in0:i") == 2
                counters = [b.data[0] for b in reader.bottles]
            finally:
                producer.stop()
            # stopped once stale again: the stale periods do not hang on how soon the stop came
            module.wait_log("input /t/src:o is stale", count=2)
            rc, elapsed = module.interrupt()
        log = assert_clean_exit(yarp_server, module, rc, elapsed, ["/relay2/data/in0:i"])
        assert counters[0] == 0
        assert_delivered(counters, totals(log))  # no message lost or repeated by the module
        assert "stale periods 2" in log and log.count("is stale") == 2 and log.count("is fresh again") == 1

    def test_producer_killed_and_restarted_twice(self, modules, yarp_server, env):
        """One Bottle at a time: written, the producer killed (stale), started
        again (the module's watcher connects it again), written: every
        Bottle once, each transition said once and counted."""
        with modules.module("relay_bridge", env, "--timeout", "0.5") as module, \
                YarpReader(env, "/test/reader", source="/relay_bridge/out:o") as reader, \
                YarpProducer(env, "/t/src:o") as a:
            a.wait_outputs(1, timeout=60)
            reader.wait_connected(timeout=60)
            a.write([1.0])
            reader.wait_for(1)
            a.kill()
            module.wait_log("input /t/src:o is stale (no data for")
            time.sleep(1.0)
            a.start()
            a.wait_outputs(1, timeout=60)  # the module's watcher connected it again
            a.write([2.0])
            reader.wait_for(2)
            module.wait_log("input /t/src:o is fresh again")
            a.kill()
            module.wait_log("is stale (no data for", count=2)
            a.start()
            a.wait_outputs(1, timeout=60)
            a.write([3.0])
            got = reader.wait_for(3)
            # stopped once stale again: the stale periods do not hang on how soon the stop came
            module.wait_log("is stale (no data for", count=3)
            rc, elapsed = module.interrupt(signal.SIGINT)
        log = assert_clean_exit(yarp_server, module, rc, elapsed, ["/relay_bridge/out:o"])
        assert exactly([g.data for g in got], [[0, 1.0], [1, 2.0], [2, 3.0]])
        assert log.count("is stale (no data for") == 3  # once per transition, not per cycle
        assert log.count("is fresh again") == 2
        assert module.count(r"connected /t/src:o -> /relay_bridge/data/in0:i") == 3
        assert totals(log)["/t/src:o"] == (3, 0, 3)

    def test_no_name_server(self, modules, tmp_path):
        """Without a reachable yarpserver the module says so and exits 1."""
        env = base_env(tmp_path)
        env.update(yarp_env(tmp_path / "yarp", free_port()))
        env = modules.environment(env)
        # (a module that waited for good would be stopped by the timeout: the test fails)
        r = subprocess.run(modules.module("relay_bridge", env).argv, capture_output=True, text=True,
                           env=env, timeout=30)
        assert r.returncode == 1
        assert "cannot reach the YARP name server" in r.stdout

    # -- timing

    def test_fixed_rate_50hz_with_nan_passing(self, modules, yarp_server, env):
        """--rate 50: a true period over 4 s (200 cycles), whatever the input
        rate (200 Hz); NaN passes (on_nan = pass); every message reaches the
        reader, but those the module counts missed.
        Forced: the rate is the module's own account between two `stats`,
        each of which takes its counts and its clock at one instant: the
        messages it published over the seconds between (the rate it says),
        and with the cycles it skipped, which a loaded machine may make it
        skip, so that neither the test's clock nor a reader's lateness enters:
        49.5..50.5 Hz either way (a cycle more or less at each end is 0.25 Hz
        over 4 s)."""
        port = "/relay_bridge/rpc:i"
        with modules.module("relay_bridge", env, "--rate", "50") as module, \
                YarpReader(env, "/test/rate:i", source="/relay_bridge/out:o") as reader, \
                YarpProducer(env, "/t/src:o", bottles=[[1.0, float("nan")]], rate=200):
            reader.wait_for(10, timeout=60)
            before = stats(yarp_server, port)  # the module's meter starts again here
            mark = time.time()
            reader.wait(lambda: reader.bottles[-1].t - mark >= 4.0, 60, "4 s of messages")
            after = stats(yarp_server, port)  # the rate since the one before
            got = list(reader.bottles)
            rc, elapsed = module.interrupt()
        log = assert_clean_exit(yarp_server, module, rc, elapsed, ["/relay_bridge/out:o"])
        counters = [b.data[0] for b in got]
        assert_delivered(counters, totals(log))  # each message reached the reader
        published = after["published"][0] - before["published"][0]
        skipped = after["published"][1] - before["published"][1]
        low = after["rate"][0]  # published / seconds, to 2 decimals
        high = low * (published + skipped) / published
        assert published >= 150 and low <= 50.5 and high >= 49.5, (low, high, published, skipped, after["text"])
        assert math.isnan(got[-1].data[2])  # on_nan = pass

    def test_fixed_rate_skips_overrun_cycles(self, modules, yarp_server, env):
        """A module held up for a second at 50 Hz skips the cycles it missed and
        counts them; it does not catch up with a burst, and goes on afterwards.
        Forced: the module is stopped (SIGSTOP, as a machine under load would)
        for at least a time the test measures, d. The cycles missed (50 d, less
        the one it may publish late) must be counted as skipped, and published
        + skipped can never exceed the cycles of its life, which the module
        tells itself: its first `stats` gives its counts and the rate since it
        started, both at one instant, so its own clock gives the seconds it
        has run (no wall clock of the test's, which a loaded machine would
        make say more or less than the module's). A catch-up burst fails one
        or the other, whatever the machine's speed (other overruns only add
        skips)."""
        with modules.module("relay_bridge", env, "--rate", "50") as module, \
                YarpReader(env, "/test/skip:i", source="/relay_bridge/out:o") as reader, \
                YarpProducer(env, "/t/src:o", bottles=[[1.0]], rate=100, wait_connected=True):
            reader.wait_for(10, timeout=60)
            os.kill(module.pid, signal.SIGSTOP)
            try:
                t0 = time.monotonic()
                time.sleep(1.0)
                d = time.monotonic() - t0
            finally:
                os.kill(module.pid, signal.SIGCONT)
            reader.wait_for(len(reader.bottles) + 50, timeout=60)  # it goes on
            account = stats(yarp_server, "/relay_bridge/rpc:i")
            rc, elapsed = module.interrupt()
        log = assert_clean_exit(yarp_server, module, rc, elapsed, ["/relay_bridge/out:o"])
        t = totals(log)
        assert t["skipped"] >= 50 * d - 2, (t, d)
        published, skipped, _ = account["published"]
        assert t["published"] >= published and t["skipped"] >= skipped, (t, account["text"])
        # the seconds since its start, at most: its messages over its rate (said to 2 decimals)
        life = published / (account["rate"][0] - 0.005)
        assert published + skipped <= 50 * life + 2, (account["text"], life)

    @pytest.mark.parametrize("queue, pairs", [(64, [[1.0, 10.0], [2.0, 20.0]]), (1, [[2.0, 10.0]])],
                             ids=["queue64", "queue1"])
    def test_queue_one_keeps_the_newest_bottle_only(self, modules, yarp_server, env, queue, pairs):
        """Two stamped Bottles on a before any on b: with the default queue both
        are paired with b's Bottles of the same stamps; with `queue = 1` (YARP's
        newest-only reading) the first is replaced (unused) before b
        delivers, and the one message pairs the newest of a with b's first."""
        key = f"queue{queue}_bridge"
        with modules.module(key, env) as module, \
                YarpReader(env, "/test/newest:i", source=f"/{key}/out:o") as reader, \
                YarpProducer(env, "/test/a:o") as a, YarpProducer(env, "/test/b:o") as b:
            reader.wait_connected(timeout=60)
            a.wait_outputs(1, timeout=60)
            b.wait_outputs(1, timeout=60)
            a.write([1.0], stamp=[1, 500.001])
            time.sleep(0.1)  # read one by one, even by a newest-only port
            a.write([2.0], stamp=[2, 500.002])
            time.sleep(0.3)
            b.write([10.0], stamp=[1, 500.001])
            time.sleep(0.1)
            b.write([20.0], stamp=[2, 500.002])
            reader.wait_for(len(pairs))
            time.sleep(0.3)
            got = [r.data for r in reader.bottles]
            rc, elapsed = module.interrupt(signal.SIGTERM)
        log = assert_clean_exit(yarp_server, module, rc, elapsed, [f"/{key}/out:o"])
        assert got == [[k, p] for k, p in enumerate(pairs)]
        assert re.search(rf"input /test/a:o: received 2, dropped 0, stale periods \d+, unused "
                         rf"{0 if queue > 1 else 1}\n", log), log[-800:]

    def test_event_driven_wakes_on_arrival(self, modules, yarp_server, env):
        """Event-driven: each arrival is published at once (no polling sleep);
        trigger "any" publishes on one of two inputs, with the other's last
        values (on_stale = hold); nothing before every input delivered once."""
        with modules.module("wake_bridge", env) as module, \
                YarpReader(env, "/test/reader", source="/wake_bridge/out:o") as reader, \
                YarpProducer(env, "/test/a:o") as a, YarpProducer(env, "/test/b:o") as b:
            a.wait_outputs(1, timeout=60)
            b.wait_outputs(1, timeout=60)
            reader.wait_connected(timeout=60)
            a.write([1.0])
            time.sleep(0.2)
            assert reader.bottles == [], "published before every input had delivered (hold)"
            b.write([2.0])
            reader.wait_for(1)
            latencies = []
            for k in range(20):
                sent = a.write([float(k)])
                got = reader.wait_for(2 + k)[-1]
                latencies.append(got.t - sent["t"])
                time.sleep(0.02)
            data = [x.data for x in reader.bottles]
            rc, elapsed = module.interrupt(signal.SIGTERM)
        assert_clean_exit(yarp_server, module, rc, elapsed, ["/wake_bridge/out:o"])
        assert data[0] == [0, [1.0, 2.0]]
        # "any": every new Bottle of a alone is published, with b's last values
        assert [d[1] for d in data[1:]] == [[float(k), 2.0] for k in range(20)]
        assert [d[0] for d in data] == list(range(21))
        # at once, not at the loop's next timed wake: the freshness check, up to
        # 1 s away here (the input's timeout), which would put the median near
        # 0.5 s; a loaded machine delays the three processes a message goes
        # through by some milliseconds each, far under the bound
        latencies.sort()
        assert latencies[len(latencies) // 2] < 0.25, latencies

    # -- readers and writers that are slow or fast

    def test_stalled_consumer_does_not_stall_the_module(self, modules, yarp_server, env):
        """A reader that stops reading (SIGSTOP) neither holds the module up
        nor makes its memory grow: the other reader keeps getting every
        message in order, and the module exits within 2 s and unregisters
        though a peer does not answer.
        Forced: the stalled reader stays stopped while the live one waits for
        300 messages of 16 kB (more than the stalled connection's buffers
        hold: a module that waited for it would publish none), then for 300
        more between two readings of the module's memory; counts of
        messages, not durations, so a slow machine only takes longer."""
        big = [float(k) for k in range(2000)]  # 16 kB messages: a stalled reader's buffers fill fast
        # the readers keep each message's counter only (decoding and printing
        # 2000 floats a message was most of the test's CPU)
        stalled = YarpReader(env, "/test/stalled:i", source="/relay_bridge/out:o", head=1)
        with modules.module("relay_bridge", env, "--rate", "100") as module, \
                YarpReader(env, "/test/live:i", source="/relay_bridge/out:o", head=1) as live, \
                YarpProducer(env, "/t/src:o", bottles=[big], rate=50):

            def rss_kb():
                with open(f"/proc/{module.pid}/status") as f:
                    return int(re.search(r"VmRSS:\s+(\d+)", f.read()).group(1))
            stalled.start()
            try:
                stalled.wait_for(5, timeout=60)
                live.wait_for(1, timeout=60)
                os.kill(stalled.pid, signal.SIGSTOP)
                n = len(live.bottles)
                live.wait_for(n + 300, timeout=60)  # the stalled connection's buffers are full by now
                rss0 = rss_kb()
                got = live.wait_for(n + 600, timeout=60)[n + 300:]
                rss1 = rss_kb()
                counters = [b.data[0] for b in got]
                assert counters == sorted(set(counters)), "out of order"
                assert module.alive
                rc, elapsed = module.interrupt()
                assert rc == 0 and elapsed < EXIT_BOUND
                # closing waits for the stalled peer at most a deadline, then unregisters the names
                assert not any(p.startswith("/relay_bridge") for p in yarp_ports(yarp_server))
            finally:
                os.kill(stalled.pid, signal.SIGCONT)
                stalled.stop()
        assert rss1 - rss0 < 8 * 1024, f"memory grew from {rss0} kB to {rss1} kB"
        log = assert_clean_exit(yarp_server, module, rc, elapsed)
        # what the stalled reader missed is counted, in every runtime's one text
        t = totals(log)
        assert 1 <= t["missed"] <= t["published"], t
        assert "  " + MISSED_LINE % t["missed"] + "\n" in log, log[-2000:]

    def test_a_burst_within_the_backlog_is_relayed_whole_and_in_order(self, modules, yarp_server, env):
        """Inputs are read strictly: bursts of 65 Bottles written back to back
        (as fast as the connection takes them, far faster than a robot port)
        are all read and published, in order, none overwritten or skipped;
        the totals say so. Forced: each burst is as long as the runtime may
        ever have to hold (while it handles one Bottle at most 64 are
        unread), and the next burst starts once the module has built the
        last one's final message (its --verbose values say so), so that the
        result does not depend on how fast the machine is. What reaches the
        reader is in order and exact, and every message reaches it but those
        the module counts missed (written while the connection still sent the
        one before, past the module's patience: on a loaded machine the
        module's or the reader's thread may not be scheduled in time)."""
        bursts, size = 8, BACKLOG + 1
        n = bursts * size
        with modules.module("relay_bridge", env, "--verbose") as module, \
                YarpReader(env, "/test/burst:i", source="/relay_bridge/out:o", carrier="fast_tcp") as reader, \
                YarpProducer(env, "/t/src:o") as producer:
            reader.wait_connected(timeout=60)
            module.wait_log("connected /t/src:o -> /relay_bridge/data/in0:i", timeout=60)
            for b in range(bursts):
                producer.burst([[float(k)] for k in range(b * size, (b + 1) * size)])
                module.wait_log("[data] 0: %r\n" % float((b + 1) * size - 1), timeout=60)
            # a marker after the bursts, written until one reaches the reader:
            # every message sent before it has then arrived (one connection, in order)
            end = time.monotonic() + 60
            while not any(b.data[1] == -1.0 for b in reader.bottles):
                assert time.monotonic() < end, "no marker message reached the reader"
                producer.write([-1.0])
                with contextlib.suppress(TimeoutError):
                    reader.wait(lambda: any(b.data[1] == -1.0 for b in reader.bottles), 2, "the marker")
            got = [b for b in reader.wait_for(1) if b.data[1] != -1.0]
            rc, elapsed = module.interrupt(signal.SIGTERM)
        log = assert_clean_exit(yarp_server, module, rc, elapsed, ["/relay_bridge/out:o"])
        assert re.search(r"input /t/src:o: received (\d+), dropped 0, stale periods \d+, unused 0", log)
        values = [float(m.group(1)) for m in re.finditer(r"\[data\] 0: (\S+)\n", log)]
        assert values[:n] == [float(k) for k in range(n)] and set(values[n:]) == {-1.0}
        t = totals(log)
        assert t["published"] == len(values)
        counters = [b.data[0] for b in got]
        assert counters == sorted(set(counters)) and n - len(counters) <= t["missed"], (counters, t)
        assert exactly([b.data for b in got], [[k, float(k)] for k in counters])

    def test_a_reader_held_up_skips_the_oldest_and_says_so(self, modules, yarp_server, env):
        """A reader thread more than 64 Bottles behind skips the oldest unread
        Bottles so that it catches up, counts them as unused, and keeps the
        order of what it relays (docs/runtime.md, "Reading").
        Forced: the module's reading thread is held up (it blocks printing its
        --verbose values on a held stdout) while the producer writes a burst
        that the module's port accepts whole (strict writes, each acknowledged);
        then it is let go. Exactly the Bottles read before the hold and the
        last 65 come out: the ones in between were more than 64 behind."""
        m = 300
        with modules.module("relay_bridge", env, "--verbose", "--timeout", "60",
                            gate_output=True) as module, \
                YarpReader(env, "/test/behind:i", source="/relay_bridge/out:o") as reader, \
                YarpProducer(env, "/t/src:o") as producer:
            reader.wait_connected(timeout=60)
            module.wait_log("connected /t/src:o -> /relay_bridge/data/in0:i", timeout=60)
            held = hold_the_reader(module, reader, producer)
            n = held + m
            producer.burst([[float(k)] for k in range(held, n)])
            assert module.output_blocked() and len(reader.bottles) == held - 1
            module.release_output()
            keep = list(range(held)) + list(range(n - BACKLOG - 1, n))
            got = reader.wait_for(len(keep), timeout=60)
            module.wait_log("[data] 0: %r\n" % float(n - 1), timeout=60)
            rc, elapsed = module.interrupt()
        log = assert_clean_exit(yarp_server, module, rc, elapsed, ["/relay_bridge/out:o"])
        assert [b.data[0] for b in got] == list(range(len(keep)))  # the module's counter
        assert [b.data[1] for b in got] == [float(k) for k in keep]
        unused = n - len(keep)
        assert re.search(rf"input /t/src:o: received {n}, dropped 0, stale periods \d+, unused {unused}\n",
                         log), log[-1500:]
        assert f"published {len(keep)} messages" in log

    # -- strings, options, stamps

    def test_escaped_strings_arrive_exactly(self, modules, yarp_server, env):
        """Config strings of every kind (quotes, backslashes, line breaks,
        NUL, comment and template delimiters, trigraphs, non-ASCII, and 50
        drawn by hypothesis) arrive exactly as written, as strings."""
        strings = list(FIXED_STRINGS) + hypothesis_strings()
        assert len(strings) >= 70
        with modules.module("escape_hypothesis", env) as module, \
                YarpReader(env, "/test/esc:i", source="/escape_hypothesis/out:o") as reader, \
                YarpProducer(env, "/t/tick:o") as tick:
            module.wait_log("connected /t/tick:o")
            reader.wait_connected()
            tick.write([42.0])
            (got,) = reader.wait_for(1)
            rc, elapsed = module.interrupt()
        assert_clean_exit(yarp_server, module, rc, elapsed, ["/escape_hypothesis/out:o"])
        assert got.data[:-2] == strings
        assert got.types[:-2] == ["string"] * len(strings)
        assert got.data[-2] == list(EVIL_LIST) and got.types[-2] == ["string"] * len(EVIL_LIST)
        assert exactly(got.data[-1], 42.0)

    def test_verbose_prints_values_after_conversion(self, modules, yarp_server, env):
        with modules.module("values_bridge", env, "--verbose") as module, \
                YarpReader(env, "/test/verbose:i", source="/values_bridge/out:o") as reader, \
                YarpProducer(env, "/t/arm:o") as p_arm, YarpProducer(env, "/t/sens:o") as p_sens:
            module.wait_log("connected /t/sens:o")
            module.wait_log("connected /t/arm:o")
            reader.wait_connected()  # else the one message may go out before the reader is there
            p_arm.write([90.0, 1e16, 0.0001])
            p_sens.write([7, -3, 0.25, "abc", 1])
            reader.wait_for(1)
            log = module.wait_log("[sens] 4: ")
            rc, elapsed = module.interrupt()
        assert_clean_exit(yarp_server, module, rc, elapsed)
        assert f"[arm] 0: {math.pi / 2!r}\n" in log
        assert f"[arm] 1: {1e16 * DEG!r}\n" in log
        assert f"[arm] 2: {0.0001 * DEG!r}\n" in log
        assert "[sens] 0: 7\n[sens] 1: -1\n[sens] 2: 1.5\n[sens] 3: 'abc'\n[sens] 4: True\n" in log

    def test_envelope_stamp(self, modules, yarp_server, env):
        """A timestamp(m) field is the envelope time of the newest Bottle."""
        with modules.module("hold_bridge", env) as module, \
                YarpReader(env, "/test/reader", source="/hold_bridge/out:o") as reader, \
                YarpProducer(env, "/test/a:o") as a:
            a.wait_outputs(1, timeout=60)
            reader.wait_connected(timeout=60)
            a.write([1.0], stamp=[5, 1234.5])
            reader.wait_for(1)  # (written at once, the second would replace the first: newest only)
            a.write([2.0], stamp=[6, 1700000000.25])
            got = reader.wait_for(2)
            rc, elapsed = module.interrupt(signal.SIGTERM)
        assert_clean_exit(yarp_server, module, rc, elapsed, ["/hold_bridge/out:o"])
        assert got[0].data == [0, [1.0], [1234, 500000000]]
        sec, nsec = got[1].data[2]
        assert sec == 1700000000 and abs(nsec - 250000000) < 1000
        assert_matches(got[1].data[2], Envelope(1700000000.25), (0, 0))

    def test_hold_policy_and_cli_options(self, modules, yarp_server, env):
        """on_stale = hold keeps publishing the last values; --prefix, --rate,
        --timeout and --verbose act as docs/runtime.md says.
        Forced: every step waits for its event (the watcher's connection, the
        stale notice, 20 held messages) instead of a fixed time; the rate is
        read from the module's own clock (the wall-clock stamp it puts in each
        message) and its counter, with the cycles it skipped (its totals),
        not from when the test process happened to receive them."""
        with modules.module("hold_bridge", env, "--prefix", "/other", "--rate", "20",
                            "--timeout", "0.3", "--verbose") as module, \
                YarpReader(env, "/test/reader", source="/hold_bridge/out:o") as reader, \
                YarpProducer(env, "/test/a:o") as a:
            a.wait_outputs(1, timeout=60)
            assert yarp_server.exists("/other/m/in0:i")
            reader.wait_connected(timeout=60)
            a.write([90.0])
            module.wait_log("input /test/a:o is stale (no data for 0.3 s)", timeout=60)
            reader.clear()
            held = reader.wait_for(20, timeout=60)
            rc, elapsed = module.interrupt(signal.SIGTERM)
        log = assert_clean_exit(yarp_server, module, rc, elapsed, ["/other/m/in0:i", "/hold_bridge/out:o"])
        assert all(h.data[1] == [90.0] for h in held)
        counters = [h.data[0] for h in held]
        t = totals(log)
        assert_delivered(counters, t)
        # 20 Hz, not event-driven (the config's): held messages come with no input at all
        assert_fixed_rate([(h.data[0], h.data[2][0] + h.data[2][1] / 1e9) for h in held], t["skipped"], 20.0)
        assert "[m] 0: 90.0" in log

    def test_hold_policy_and_trigger_any(self, modules, yarp_server, env):
        """examples/mixed_types_yarp.ini (on_stale = hold, trigger = any):
        nothing before every input delivered once; then a message for each new
        Bottle of any input, with the last values of a stale one (said once).
        Forced: each joints Bottle carries its own number, so "one message per
        Bottle" is read from the messages (every number once, in order), not
        from how many arrived in a wall-clock window."""
        path = EXAMPLES / "mixed_types_yarp.ini"
        program = modules.program(path)
        assert program.policy.on_stale == "hold" and program.timing.trigger == "any"
        joints = [[100.0 * k + j for j in range(6)] for k in range(600)]  # 30 s at 20 Hz
        with modules.module(path, env, "--timeout", "0.5") as module, \
                YarpReader(env, "/test/hold:i", source="/hand_status/out:o") as reader, \
                YarpProducer(env, "/icub/left_hand/status:o") as status, \
                YarpProducer(env, "/icub/left_hand/joints:o", bottles=joints, rate=20):
            module.wait_log("connected /icub/left_hand/status:o", timeout=60)
            module.wait_log("connected /icub/left_hand/joints:o", timeout=60)
            time.sleep(1.0)
            assert reader.bottles == []  # hold: not before every input delivered once
            status.write([1, 0, 1])
            reader.wait_for(5, timeout=60)
            module.wait_match(r"input /icub/left_hand/status:o is stale \(no data for 0\.\d s\)", timeout=60)
            n = len(reader.bottles)
            got = reader.wait_for(n + 20, timeout=60)[n:]
            rc, elapsed = module.interrupt()
        assert_clean_exit(yarp_server, module, rc, elapsed)
        numbers = [round(b.data[1][0] / DEG / 100.0) for b in got]
        assert numbers == list(range(numbers[0], numbers[0] + len(got)))  # one per joints Bottle
        for b, k in zip(got, numbers):
            assert b.data == ["left_hand", [x * DEG for x in joints[k]], 1, [1, 0, 1]]
        assert module.count(r"is stale") == 1

    # -- every supported example and legacy config, from the real file

    def test_config_end_to_end(self, modules, config, yarp, request):
        """The module generated from the real config reads real producers
        (YARP ports; ROS topics: a rospy or rclpy publisher) and publishes
        exactly what the reference says the config asks for, to a YARP
        reader, a rospy or an rclpy subscriber; SIGINT ends it cleanly.
        Where YARP has no ROS 1 (3.10 and later), a ROS 1 module refuses to
        build or to start, and says why."""
        program = modules.program(config)
        ros1 = needs_ros1(program)
        if ros1 and not yarp.has_ros1:
            modules.refuses_ros1(config, request.getfixturevalue("env"))
            return
        stack = request.getfixturevalue("yarp_ros_server" if ros1 else "yarp_server")
        env = modules.environment(dict(stack.env))
        out = program.output
        named = (out.kind == "ros1" and ros1_type_known(out.msg_type)) or out.kind == "ros2"
        sent = sent_values(program)
        want = expected(program, mux_values(program, sent), named=named)
        peers = []
        try:
            begun = time.time()
            module = modules.module(config, env).start()
            peers.append(module)
            if out.kind == "ros2":
                consumer = modules.subscriber(env, program).start()
            elif named:
                consumer = RospySubscriber(env, out.name, out.msg_type).start()
            elif out.kind == "ros1":
                consumer = YarpReader(env, "/test/cfg:i", source=f"{out.name}+@{out.node}").start()
            elif out.connect_to:
                consumer = YarpReader(env, out.connect_to).start()  # the module connects to it
            else:
                consumer = YarpReader(env, "/test/cfg:i", source=out.name).start()
            peers.append(consumer)
            for m in program.muxes:
                for inp in m.inputs:
                    if inp.kind == "ros1":
                        fields = dict(zip("xyz", sent[inp.name]))
                        peers.append(rospy_publisher(env, inp.name, "geometry_msgs/Point", fields).start())
                    elif inp.kind == "ros2":
                        pkg, name = inp.ros_type.split("/")
                        peers.append(Ros2Publisher(env, inp.name, f"{pkg}/msg/{name}",
                                                   messages=[topic_message(inp, sent[inp.name])],
                                                   rate=20).start())
                    else:
                        peers.append(YarpProducer(env, inp.name, bottles=[sent[inp.name]], rate=20).start())
            got = consumer.wait_for(3, timeout=60)
            last = got[-1]
            data = last.msg if named else last.data
            # a time the module stamps: its clock, after it started, before the consumer had the message
            assert_matches(data, want, (begun, last.t), exact_fields=out.kind == "ros2")
            if named and "header" in want and want["header"].get("seq") == COUNTER:
                counters = [g.msg["header"]["seq"] for g in got]
                assert counters == sorted(counters) and len(set(counters)) == len(counters)
            rc, elapsed = module.interrupt(signal.SIGINT)
            assert rc == 0 and elapsed < EXIT_BOUND, module.log_text()[-2000:]
            log = module.log_text()
            assert "totals:" in log and "Traceback" not in log, log[-3000:]
            assert not re.search(r"published 0 messages", log)
            if not ros1:
                assert not any(p.startswith(f"/{program.module}") for p in yarp_ports(stack))
        finally:
            for p in reversed(peers):
                p.stop()


def on_today_yarp(test):
    """A test of the behaviour harness, with its parameters, run on today's
    YARP (4.0) only: for a behaviour that other tests show on every release
    (``test_x = on_today_yarp(BridgeBehaviour.test_x)`` in a backend's class)."""
    @functools.wraps(test)
    def run(self, *args, **kwargs):
        return test(self, *args, **kwargs)
    return pytest.mark.yarp_min((4, 0))(run)


class NeverStartsAtAFixedRateOnTodayYarp:
    """Put before ``BridgeBehaviour`` in a backend's class: waiting for inputs
    that never deliver on every release, event-driven; at a fixed rate too
    (the runtime's own loop, which calls no YARP while nothing comes) on
    today's YARP only."""

    @pytest.mark.parametrize("args", [()], ids=["event-driven"])
    def test_producer_never_starts(self, modules, yarp_server, env, args):
        BridgeBehaviour.test_producer_never_starts(self, modules, yarp_server, env, args)

    @pytest.mark.yarp_min((4, 0))
    @pytest.mark.parametrize("args", [("--rate", "20")], ids=["fixed-rate"])
    def test_producer_never_starts_at_a_fixed_rate(self, modules, yarp_server, env, args):
        BridgeBehaviour.test_producer_never_starts(self, modules, yarp_server, env, args)


class ModuleCommandLine:
    """The command line of a YARP module (cpp, py): --help and bad options.
    (The ros2 node takes ROS parameters instead: test_backend_ros2_node.)"""

    #: how the backend's --help shows each option
    help_options = ("--prefix", "--rate HZ", "--timeout S", "--verbose", "--help")

    def test_help_and_bad_options(self, modules):
        """--help without a name server: the options, what the module does
        and where it comes from; a bad option: exit 2 with the usage."""
        env = base_env()
        argv = modules.module("values_bridge", env).argv
        r = subprocess.run(argv + ["--help"], capture_output=True, text=True, env=env, timeout=60)
        assert r.returncode == 0, r.stderr
        for opt in self.help_options:
            assert opt in r.stdout, (opt, r.stdout)
        assert "Generated by ybgc from values_bridge.ini." in r.stdout
        assert "module values_bridge: 2 input(s) in 2 mux(es)" in r.stdout
        for bad in (["--rate", "-1"], ["--rate=x"], ["--timeout", "0"], ["--prefix", "nope"], ["--bogus"],
                    ["--rate"]):
            r = subprocess.run(argv + bad, capture_output=True, text=True, env=env, timeout=60)
            assert r.returncode == 2, bad
            assert "usage:" in r.stderr
