"""The bridge on a robot's network, with real middleware: four hosts
(tests/harness/netns.py: the YARP name server, the producers, the module, the
consumers, each a network namespace with its own address) and the faults of
such a network. Every test here runs on YARP 4.0.0 only (today's), whatever
``--yarp`` says, to bound the suite's time. See docs/network.md.

Each fault is a function (``fault_*``) that runs it against one backend's
module, asserts what comes out (no hang, no traceback, exit 0 on SIGINT
within 2 s, totals that agree with what was sent) and returns its figures
(seconds to recover, messages unused, memory before and after): the tests
assert only behaviour; bench/network_faults.py runs the same functions and
records the figures.

Needs root (network namespaces): elsewhere every test here fails saying so.
"""
from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import time
from pathlib import Path

import pytest

from harness import netns
from harness.build import session_builds
from harness.env import VENV_PYTHON, yarp_install
from harness.launchers import CppModules, PyModules, Ros2Modules, write_node
from harness.module import STATS_PUBLISHED, Module, assert_clean_exit, assert_delivered, stop_clean, totals
from harness.netns import Rig, rss_kb
from harness.programs import ros2_example
from harness.reference import exactly, expected_message, sent_values, wait_matching, write_all
from harness.ros2 import subscriber_for, wait_matched
from harness.yarp import YarpProducer, YarpReader

#: the YARP the rig runs
VERSION = "4.0.0"
BACKENDS = ("cpp", "py", "ros2")
SRC = "/t/src:o"
IN = "/relay_bridge/data/in0:i"
OUT = "/relay_bridge/out:o"
#: how long a host is cut off, and a producer floods
CUT = 5.0
FLOOD = 10.0
#: a Bottle on its way when its producer was stopped, never reported sent
SENT_UNSAID = 1
#: for a test that counts stale periods (0) but is not about staleness: an
#: input stale only after 30 s without data, whatever a loaded machine takes
#: between the test's steps
NEVER_STALE = ("--timeout", "30")
#: growth of a module's resident memory that still counts as flat, in kB
#: (an allocator's arenas; a queue that grew with the backlog would pass it)
FLAT_KB = 8 * 1024


# --------------------------------------------------------------------------
# fixtures


def rig_install():
    """YARP 4.0.0, or the test fails (in CI) or skips saying how to build it."""
    install = yarp_install(VERSION)
    missing = install.missing()
    if missing:
        msg = f"YARP {VERSION} is not built here (missing {missing[0]}). {install.build_hint()}"
        if os.environ.get("CI"):
            pytest.fail(msg, pytrace=False)
        pytest.skip(msg)
    return install


@pytest.fixture(scope="module")
def install():
    return rig_install()


@pytest.fixture
def rig(install):
    """Four fresh hosts and the name server, removed after the test."""
    try:
        r = Rig(install).start()
    except netns.RigUnavailable as e:
        pytest.fail(str(e), pytrace=False)
    try:
        r.start_name_server()
        yield r
    finally:
        r.stop()


@pytest.fixture(scope="module")
def cpp_builds(install, tmp_path_factory):
    """The session's C++ modules of YARP 4.0.0 (built once for the run),
    among them the relay, optimized as a user's (harness.programs.TIMED)."""
    builds = session_builds(tmp_path_factory, install)
    assert "relay_bridge" in builds.optimized
    return builds


def launcher(backend: str, folder: Path, cpp_builds=None):
    """How ``backend``'s module is started (the behaviour harness's Launcher)."""
    if backend == "cpp":
        return CppModules(cpp_builds)
    if backend == "py":
        return PyModules(folder)
    return Ros2Modules(folder, None)


@pytest.fixture(params=BACKENDS)
def modules(request, tmp_path, install, cpp_builds):
    # (cpp_builds is built on a first executable asked of it: by a cpp test)
    return launcher(request.param, tmp_path, cpp_builds if request.param == "cpp" else None)


# --------------------------------------------------------------------------
# the relay across the rig


def relay(stack: contextlib.ExitStack, rig: Rig, modules, *args, rate=50.0, count=None,
          started=True, carrier=""):
    """The relay module on the module host, a reader on the consumers host
    kept connected to its output (with ``carrier``), a producer of SRC on
    the producers host writing ``[k]`` ``rate`` times a second once the
    module has connected it (None: on command): (module, reader, producer),
    each stopped when ``stack`` closes."""
    module = rig.place("module", modules.module("relay_bridge", rig.env("module"), *args))
    reader = rig.place("consumers", YarpReader(rig.env("consumers"), "/test/in:i", source=OUT,
                                               carrier=carrier))
    producer = rig.place("producers", YarpProducer(rig.env("producers"), SRC,
                                                   bottles=[[float(k)] for k in range(10)],
                                                   rate=rate, count=count,
                                                   wait_connected=rate is not None))
    stack.enter_context(module)
    stack.enter_context(reader)
    stack.callback(producer.stop)
    module.wait_log("publishing")
    if started:
        producer.start()
    return module, reader, producer


def sent_total(producer: YarpProducer) -> int:
    """Bottles the producer wrote, over all its runs. A producer stopped
    in the middle of a write may have sent one more than it said: the
    totals are checked against ``sent_total() + 1`` (SENT_UNSAID)."""
    with producer._cond:
        return sum(1 for e in producer.events if e["ev"] == "sent")


def stop_module(rig: Rig, module: Module) -> dict:
    """SIGINT: exit 0 within 2 s, no traceback, its ports gone from the
    name server; the totals, SRC's with its unused Bottles:
    (received, dropped, stale periods, unused)."""
    rc, elapsed = module.interrupt(signal.SIGINT)
    log = assert_clean_exit(rig, module, rc, elapsed, [IN, OUT])
    t = totals(log)
    t[SRC] += (int(re.search(rf"input {SRC}: .*, unused (\d+)", log).group(1)),)
    return t


def published(rig: Rig) -> int:
    """The messages the relay has published, by its own count (its `stats`,
    asked on the module's host)."""
    text = rig.rpc("/relay_bridge/rpc:i", "stats", host="module")
    m = STATS_PUBLISHED.search(text)
    assert m, text
    return int(m.group(1))


def drain(producer: YarpProducer) -> None:
    """A finite stream written whole and delivered (the module's port has
    every Bottle)."""
    producer.wait_done(timeout=120)
    producer.burst([])


def quiet(module: Module, producer: YarpProducer, periods: int) -> None:
    """The producer stopped and its last Bottle handled: the input stale
    again (its ``periods``-th stale period), so no Bottle is half-way
    through the module when it is stopped."""
    producer.stop()
    module.wait_log(f"input {SRC} is stale", count=periods)


def settle(reader: YarpReader, t: dict) -> None:
    """Every message the module published (its totals ``t``) reached the
    reader, but those it counts missed (written while the reader's
    connection still sent the one before: YARP skips it for that reader)
    and the last: the module goes on at its rate until it stops, and the
    message of its last cycle may be written as its port closes, which
    fast_tcp (no acknowledgement) does not wait for."""
    least = t["published"] - 1 - t["missed"]
    reader.wait(lambda: len(reader.bottles) >= least, 30, f"{least} messages")
    assert len(reader.bottles) <= t["published"], t


# --------------------------------------------------------------------------
# end to end across hosts


def test_yarp_to_yarp_across_hosts(rig, modules):
    """Producer, module and reader on three hosts, the name server on a
    fourth: each port registered with its own host's address; the values
    exactly, in order, of their wire types; the counter counts messages;
    the totals agree; exit clean."""
    with contextlib.ExitStack() as stack:
        module, reader, producer = relay(stack, rig, modules, rate=None)
        producer.wait_outputs(1)
        reader.wait_connected()
        assert rig.registered(SRC) == rig.ip("producers")
        assert rig.registered(IN) == rig.ip("module") and rig.registered(OUT) == rig.ip("module")
        assert rig.registered("/test/in:i") == rig.ip("consumers")
        data = [[1.5, -2.0, 3], [4.25, 5, -6.5], [1e-9, 0.0, 7]]
        for k, d in enumerate(data):
            producer.write(d)
            reader.wait_for(k + 1)
        t = stop_module(rig, module)
    got = reader.bottles
    assert exactly([g.data for g in got], [[k, *map(float, d)] for k, d in enumerate(data)])
    # an undeclared input: every element a float64 (docs/runtime.md, "Reading")
    assert [g.types for g in got] == [["int32", "float64", "float64", "float64"]] * 3
    assert t[SRC][:2] == (3, 0) and t["published"] == 3


def test_yarp_to_ros2_across_hosts(rig, tmp_path):
    """The Rviz example's node on the module host: YARP producers on their
    host found through the name server, an rclpy subscriber on the consumers
    host found by DDS discovery across the subnet (UDP only): the exact
    message the reference says, then new values; exit clean."""
    program = ros2_example("vizzy_rviz_joint_states")
    path = write_node(program, tmp_path / "node")
    with contextlib.ExitStack() as stack:
        sub = stack.enter_context(rig.place("consumers", subscriber_for(rig.env("consumers"), program)))
        node = stack.enter_context(rig.place("module", Module(
            [VENV_PYTHON, path], env=rig.env("module"), name="vizzy_node")))
        producers = [stack.enter_context(rig.place("producers", YarpProducer(rig.env("producers"), port)))
                     for port in sent_values(program)]
        node.wait_log("publishing")
        for p in producers:
            p.wait_outputs(1)
            assert rig.registered(p.port) == rig.ip("producers")
        wait_matched(node, sub, program)
        for offset in (0.0, 100.0):
            sent, stamps, t_before = write_all(program, producers, offset=offset)
            wait_matching(sub, t_before, expected_message(program, sent, stamps))
        log = stop_clean(node)
    t = totals(log)
    for port in sent:
        assert t[port][:2] == (2, 0), t
    assert t["published"] >= 2 and t["failures"] == 0


# --------------------------------------------------------------------------
# faults: each returns its figures


def fault_name_server_restarted(rig: Rig, modules) -> dict:
    """The name server killed while data flows: the existing connections
    carry on (lookups only need it); restarted empty, it is told the
    module's ports again by the module, so a producer started after the
    restart is found and connected; the consumer's connection never broke."""
    with contextlib.ExitStack() as stack:
        module, reader, producer = relay(stack, rig, modules, "--timeout", "0.5")
        reader.wait_for(10)
        rss0 = rss_kb(module.pid)
        rig.name_server.kill()
        n = len(reader.bottles)
        reader.wait_for(n + 25)  # half a second of data, the name server dead
        assert not rig.exists("/root")
        rig.start_name_server()
        t_restart = time.monotonic()
        module.wait_log("registered them again")
        registered_again = time.monotonic() - t_restart
        assert rig.registered(IN) == rig.ip("module") and rig.registered(OUT) == rig.ip("module")
        producer.stop()
        module.wait_log(f"input {SRC} is stale")
        n = len(reader.bottles)
        t_start = time.monotonic()
        producer.start()  # a producer started after the restart
        reader.wait_for(n + 1)
        found = time.monotonic() - t_start
        module.wait_log(f"input {SRC} is fresh again")
        quiet(module, producer, 2)
        rss1 = rss_kb(module.pid)
        t = stop_module(rig, module)
        settle(reader, t)
        # event-driven and quiet before it stopped: its last message was written long before
        # its port closed, so every one it did not count missed reaches the reader, late or not
        reader.wait(lambda: len(reader.bottles) + t["missed"] >= t["published"], 30, "the last messages")
    sent = sent_total(producer)
    assert module.count(rf"connected {SRC} -> {IN}") == 2
    assert t[SRC][0] <= sent + SENT_UNSAID and t[SRC][1:3] == (0, 2)
    assert t["published"] == len(reader.bottles) + t["missed"] == t[SRC][0] - t[SRC][3]
    return {"registered again (s)": registered_again, "late producer found (s)": found,
            "sent": sent, "received": t[SRC][0], "unused": t[SRC][3],
            "rss before (kB)": rss0, "rss after (kB)": rss1}


def fault_producer_cut(rig: Rig, modules) -> dict:
    """The producers' host cut off for 5 s while it streams at 50 Hz
    (on_stale = skip, timeout 0.5 s): stale said once, nothing published
    while stale, fresh again said once when the link is back; what the
    producer wrote meanwhile arrives late, in order, within the queue's
    bound (the rest counted unused)."""
    with contextlib.ExitStack() as stack:
        module, reader, producer = relay(stack, rig, modules, "--timeout", "0.5")
        reader.wait_for(10)
        rss0 = rss_kb(module.pid)
        t_cut = time.monotonic()
        rig.cut("producers")
        try:
            module.wait_log(f"input {SRC} is stale", timeout=CUT)
            # the module's own count (a reader may still be taking the message of the
            # cycle before the stale one)
            stale = published(rig)
            time.sleep(max(0.0, t_cut + CUT - time.monotonic()))
            during = published(rig) - stale
        finally:
            rig.restore("producers")
        t_back = time.monotonic()
        module.wait_log(f"input {SRC} is fresh again", timeout=60)
        recovered = time.monotonic() - t_back
        said = module.count(r"is stale")
        reader.wait_for(len(reader.bottles) + 10)
        quiet(module, producer, 2)
        rss1 = rss_kb(module.pid)
        t = stop_module(rig, module)
        settle(reader, t)
    sent = sent_total(producer)
    assert during == 0, f"{during} messages published while {SRC} was stale"
    assert said == 1 and module.count(r"is fresh again") == 1  # once each for the cut
    counters = [b.data[0] for b in reader.bottles]
    assert counters[0] == 0
    assert_delivered(counters, t)
    received, dropped, periods, unused = t[SRC]
    assert (dropped, periods) == (0, 2)
    assert received <= sent + SENT_UNSAID and t["published"] == received - unused, (t, sent)
    assert rss1 - rss0 < FLAT_KB, (rss0, rss1)
    return {"fresh again after the link (s)": recovered, "sent": sent, "received": received,
            "unused": unused, "rss before (kB)": rss0, "rss after (kB)": rss1}


def fault_consumer_cut(rig: Rig, modules) -> dict:
    """The consumers' host cut off for 5 s while the module publishes at
    1 kHz: the input goes on being read (never stale, every Bottle
    counted), the module's memory stays flat, the output resumes when the
    link is back; what the consumer missed is the messages the output port
    dropped rather than queue (a reader that lags misses messages)."""
    with contextlib.ExitStack() as stack:
        module, reader, producer = relay(stack, rig, modules, "--rate", "1000", rate=100)
        reader.wait_for(1000)
        rss0 = rss_kb(module.pid)
        sent0 = sent_total(producer)
        rig.cut("consumers")
        try:
            time.sleep(CUT)
            rss_cut = rss_kb(module.pid)
        finally:
            rig.restore("consumers")
        t_back = time.monotonic()
        written = sent_total(producer) - sent0
        # a message the module published after the link came back: its counter past the
        # module's count then (the messages of the cut may still be on their way)
        back = published(rig)
        reader.wait(lambda: reader.bottles[-1].data[0] >= back, 60, "the output after the cut")
        resumed = time.monotonic() - t_back
        n = len(reader.bottles)
        reader.wait_for(n + 500)
        producer.stop()
        rss1 = rss_kb(module.pid)
        t = stop_module(rig, module)
    sent = sent_total(producer)
    assert written >= 100, f"the producer wrote {written} Bottles in {CUT} s"
    assert module.count(r"is stale") == 0  # the input was read all along
    # every Bottle that reached the module counted (those in flight when the
    # producer stopped never did)
    assert t[SRC][1:3] == (0, 0) and written <= t[SRC][0] <= sent + SENT_UNSAID, (t, sent)
    assert rss_cut - rss0 < FLAT_KB and rss1 - rss0 < FLAT_KB, (rss0, rss_cut, rss1)
    counters = [b.data[0] for b in reader.bottles]
    assert counters == sorted(set(counters))  # in order, none twice
    missed = t["published"] - len(reader.bottles)
    assert missed > 0 and t["missed"] > 0, t  # and the module said so
    return {"output resumed after the link (s)": resumed, "published": t["published"],
            "missed by the consumer": missed, "missed (the module's count)": t["missed"], "rss before (kB)": rss0,
            "rss at the end of the cut (kB)": rss_cut, "rss after (kB)": rss1}


def fault_module_killed(rig: Rig, modules) -> dict:
    """The module killed with SIGKILL (its registrations left behind in the
    name server) and started again: its port names are taken at once, the
    producer is connected again by it, the consumer finds its output again;
    every Bottle written to the new module comes out, its counter from 0."""
    with contextlib.ExitStack() as stack:
        # (never stale within the test: the totals count stale periods, 0)
        module, reader, producer = relay(stack, rig, modules, *NEVER_STALE, rate=None)
        producer.wait_outputs(1)
        reader.wait_connected()
        for k in range(5):
            producer.write([float(k)])
            reader.wait_for(k + 1)
        module.kill()
        assert rig.registered(IN) == rig.ip("module")  # the dead module's, left behind
        reader.wait_disconnected()
        t0 = time.monotonic()
        module.start()
        module.wait_log(f"connected {SRC} -> {IN}", count=2)
        reader.wait_connected()
        recovered = time.monotonic() - t0
        rss0 = rss_kb(module.pid)
        for k in range(5):
            producer.write([10.0 + k])
            reader.wait_for(6 + k)
        rss1 = rss_kb(module.pid)
        t = stop_module(rig, module)
    log = module.log_text().split("==== start 2")[1]
    assert "cannot open" not in log and "Traceback" not in log
    assert exactly([b.data for b in reader.bottles],
                   [[k, float(k)] for k in range(5)] + [[k, 10.0 + k] for k in range(5)])
    assert t[SRC] == (5, 0, 0, 0) and t["published"] == 5
    return {"connected again after the restart (s)": recovered, "received": t[SRC][0],
            "unused": t[SRC][3], "rss before (kB)": rss0, "rss after (kB)": rss1}


def fault_flood(rig: Rig, modules) -> dict:
    """The module samples at 100 Hz, its producer's usual rate; the producer
    sends at 10 times that for 10 s: every Bottle is read (strictly), each
    cycle uses the newest, the others are counted unused; memory flat.
    The reader takes the output over fast_tcp (no acknowledgement per
    message). On a loaded machine a message may be written while the
    reader's connection still sends the one before (its thread not
    scheduled within the module's patience): YARP skips it for that
    reader, and the module counts it missed (settle())."""
    with contextlib.ExitStack() as stack:
        module, reader, producer = relay(stack, rig, modules, "--rate", "100", rate=1000,
                                         count=int(1000 * FLOOD), started=False, carrier="fast_tcp")
        rss0 = rss_kb(module.pid)
        producer.start()
        drain(producer)
        # a last Bottle apart: once it is in a message, every Bottle was read
        producer.write([-1.0])
        reader.wait(lambda: reader.bottles and reader.bottles[-1].data[1] == -1.0, 60,
                    "the last Bottle in a message")
        rss1 = rss_kb(module.pid)
        t = stop_module(rig, module)
        settle(reader, t)
    sent = sent_total(producer)
    received, dropped, periods, unused = t[SRC]
    used = received - unused
    assert (received, dropped) == (sent, 0), (t, sent)
    assert 0 < used <= t["published"] and unused >= sent - t["published"]
    assert rss1 - rss0 < FLAT_KB, (rss0, rss1)
    return {"sent": sent, "published": t["published"], "missed": t["missed"], "unused": unused,
            "rss before (kB)": rss0, "rss after (kB)": rss1}


FAULTS = {
    "name server restarted": fault_name_server_restarted,
    "producer host cut 5 s": fault_producer_cut,
    "consumer host cut 5 s at 1 kHz": fault_consumer_cut,
    "module SIGKILL and restart": fault_module_killed,
    "producer at 10x for 10 s": fault_flood,
}


@pytest.mark.parametrize("fault", list(FAULTS))
def test_fault(rig, modules, fault):
    FAULTS[fault](rig, modules)


# --------------------------------------------------------------------------
# a name that leads to another port (docs/network.md)

#: a producer running since before the name server restarted, whose port
#: number the restarted server hands to the late source
OTHER = "/t/other:o"
#: its values, none of which the source sends
FOREIGN = [[1000.0 + k] for k in range(10)]
#: a port number no port of the producers' host holds
FREE_SOCKET = netns.NAME_SERVER_PORT + 900


class PinnedProducer(YarpProducer):
    """A producer whose port opens at a port number of its own choosing, its
    name registered there."""

    def __init__(self, env: dict, port: str, socket: int, **kw):
        super().__init__(env, port, **kw)
        self.config["socket"] = socket
        self.argv[-1] = json.dumps(self.config)


def start_failing(producer: YarpProducer) -> str:
    """Start a producer whose port cannot open: it says why and exits; its log."""
    with pytest.raises(RuntimeError, match="exited"):
        producer.start()
    producer.wait_exit(timeout=30)
    return producer.log_text()


def restart_beside_other(stack: contextlib.ExitStack, rig: Rig, modules):
    """OTHER producing, the relay (its source not started) and its reader
    connected, then the name server killed and started again: (other,
    module, reader, producer, the contact OTHER held before the restart)."""
    other = rig.place("producers", YarpProducer(rig.env("producers"), OTHER, bottles=FOREIGN, rate=50))
    stack.enter_context(other)
    # (never stale within the test: the totals count stale periods, 0)
    module, reader, producer = relay(stack, rig, modules, *NEVER_STALE, rate=None, started=False)
    reader.wait_connected()
    held = rig.contact(OTHER)
    rig.name_server.kill()
    rig.start_name_server()
    return other, module, reader, producer, held


def test_a_name_that_leads_to_another_port(rig, modules):
    """The name server killed and restarted: it has forgotten the producers
    that run on. The source, started late, is handed the port number the
    server believes free, the first it hands out, which a producer running
    since before (OTHER, started first) holds: YARP cannot open it (address
    conflict), but the name stays registered at OTHER's address. The module
    connects the name, YARP connects OTHER: said by OTHER's own name, none of
    its Bottles is used (no output carries its values), they are refused,
    counted and said once, the connection closed, and that address not
    connected again while OTHER answers there. The source started again on a
    free port: connected, its values relayed exactly."""
    with contextlib.ExitStack() as stack:
        other, module, reader, producer, held = restart_beside_other(stack, rig, modules)
        module.wait_log("registered them again")
        log = start_failing(producer)
        assert "address conflict" in log or "cannot open" in log, log[-2000:]
        assert rig.contact(SRC) == held  # the clash: the source's name at OTHER's address
        module.wait_log(f"connected {OTHER} -> {IN} (asked for {SRC})")
        module.wait_log(f"input {SRC}: {OTHER} is connected to its port, not {SRC}")
        other.wait(lambda: other.output_count() == 0, 30, f"{OTHER} -> {IN} closed")
        # the source, really there: started again on a free port of its host
        source = rig.place("producers", PinnedProducer(rig.env("producers"), SRC, FREE_SOCKET))
        stack.enter_context(source)
        module.wait_log(f"connected {SRC} -> {IN}")
        assert rig.contact(SRC) == (rig.ip("producers"), FREE_SOCKET)
        source.wait_outputs(1)
        for k in range(5):
            source.write([float(k)])
            reader.wait_for(k + 1)
        rc, elapsed = module.interrupt(signal.SIGINT)
        log = assert_clean_exit(rig, module, rc, elapsed, [IN, OUT])
    assert exactly([b.data for b in reader.bottles], [[k, float(k)] for k in range(5)])
    said = re.findall(rf"input {re.escape(SRC)}: {re.escape(OTHER)} is connected to its port", log)
    assert len(said) == 1, log[-3000:]
    assert module.count(rf"connected {re.escape(OTHER)} -> ") == 1  # never connected again
    refused = re.search(rf"input {re.escape(SRC)}: received 5, dropped 0, stale periods 0, unused 0, "
                        rf"refused (\d+) from {re.escape(OTHER)}\n", log)
    assert refused and int(refused.group(1)) >= 1, log[-3000:]


def test_a_name_server_that_keeps_its_registrations(rig, install, tmp_path):
    """A name server started with its registrations on disk (yarpserver
    --portdb): killed and started again, it still knows every port, so a
    source started late gets a port number of its own, `yarp name query`
    gives each port its own address, and the module connects the source.
    (What the name server does: one backend suffices.)"""
    rig.name_server.stop()
    rig.name_server = None
    rig.start_name_server(keep=True)
    modules = launcher("py", tmp_path)
    with contextlib.ExitStack() as stack:
        other, module, reader, producer, held = restart_beside_other(stack, rig, modules)
        assert rig.contact(OTHER) == held and rig.contact(IN)[0] == rig.ip("module")
        producer.start()
        module.wait_log(f"connected {SRC} -> {IN}")
        assert rig.contact(SRC)[0] == rig.ip("producers") and rig.contact(SRC) != held
        producer.wait_outputs(1)
        producer.write([1.5])
        reader.wait_for(1)
        rc, elapsed = module.interrupt(signal.SIGINT)
        log = assert_clean_exit(rig, module, rc, elapsed, [IN, OUT])
    assert "registered them again" not in log and "is connected to its port, not" not in log
    assert exactly([b.data for b in reader.bottles], [[0, 1.5]])


def test_without_root_the_rig_says_why(install, monkeypatch):
    """Not root: the rig refuses with a message that says so and how to run."""
    monkeypatch.setattr(os, "geteuid", lambda: 1000)
    with pytest.raises(netns.RigUnavailable, match="needs root.*sudo"):
        Rig(install).start()
