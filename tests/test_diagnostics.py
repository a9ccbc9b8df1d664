"""/diagnostics (diagnostic_msgs/DiagnosticArray, the diagnostic_updater
convention) of the ros2 node and of the native C++ module built for ROS 2,
read by a real rclpy subscriber while real YARP producers feed them: an input
that never delivered is an ERROR, a fresh one OK, a stalled one (its producer
stopped with SIGSTOP) a WARN with its counts frozen; the output's rate
achieved against the rate configured; the ``diagnostics`` parameter turns it
off, and a bad period stops the module with the reason. The C++ statuses'
texts are unit-tested beside the Python ones (tests/runtime/ros2/)."""
from __future__ import annotations

import os
import signal
from types import SimpleNamespace

import pytest

from harness.build import Builds, session_builds
from harness.generated import generate
from harness.module import Module, Node, stop_clean, totals
from harness.env import yarp_install
from harness.programs import DIAGNOSTICS_CONFIG as CONFIG
from harness.ros2 import QosSubscriber, statuses, yarp_and_ros2
from harness.yarp import YarpProducer

#: the cpp modules come from the session's build (request.getfixturevalue)
pytestmark = pytest.mark.builds


@pytest.fixture
def mw(ros2_domain):
    with yarp_and_ros2(ros2_domain) as both:
        yield both



NODE = "diag_bridge"
INPUT_ARM = f"{NODE}: input /diag/arm:o"
INPUT_HAND = f"{NODE}: input /diag/hand:o"
OUTPUT = f"{NODE}: output /diag/point"
OK, WARN, ERROR = 0, 1, 2


def wait_status(sub: QosSubscriber, pred, what: str, timeout: float = 60.0) -> dict:
    """The statuses of the first array received from now on that satisfies ``pred``."""
    start = len(sub.messages)

    def find():
        for m in sub.messages[start:]:
            st = statuses(m.msg)
            if pred(st):
                return st
        return None
    return sub.wait(find, timeout, what)


@pytest.fixture(scope="module")
def native(tmp_path_factory) -> Builds:
    """The session's modules of the name server's YARP, among them
    ``diag_bridge`` (CONFIG) built with --backend cpp."""
    return session_builds(tmp_path_factory, yarp_install("3.5"))


@pytest.fixture(params=["ros2", "cpp"])
def start_node(request, tmp_path):
    """Starts the Python node or the native module with ROS arguments."""
    def start(mw, *args):
        if request.param == "cpp":
            native = request.getfixturevalue("native")
            return Module([native.exe("diag_bridge"), *args], env=mw.env, name=NODE).start()
        folder = generate(tmp_path, CONFIG, NODE, "ros2")
        return Node(mw.env, folder / f"{NODE}_node.py", *args).start()
    return start


@pytest.mark.timeout(900)  # the first builds the native module
def test_inputs_and_output_on_diagnostics(mw, start_node):
    diag = QosSubscriber(mw.env, "/diagnostics", "diagnostic_msgs/msg/DiagnosticArray").start()
    arm = YarpProducer(mw.env, "/diag/arm:o", bottles=[[0.5, -1.25]], rate=20).start()
    hand = YarpProducer(mw.env, "/diag/hand:o").start()
    node = start_node(mw)
    try:
        node.wait_log("publishing")
        diag.wait_publishers(1)
        # the hand never delivered: ERROR; nothing published (on_stale = hold
        # waits for every input's first Bottle): the output is below its rate
        st = wait_status(diag, lambda s: int(s[INPUT_ARM][2]["received"]) > 0, "the arm received")
        assert set(st) == {INPUT_ARM, INPUT_HAND, OUTPUT}
        assert {s[3] for s in st.values()} == {NODE}  # hardware_id
        level, text, values, _ = st[INPUT_HAND]
        assert (level, text) == (ERROR, "no data received yet")
        assert values["received"] == "0" and values["age (s)"] == "" and values["timeout (s)"] == "1.5"
        assert st[INPUT_ARM][:2] == (OK, "fresh")
        level, text, values, _ = st[OUTPUT]
        assert level == WARN and text.startswith("rate too low")
        assert values["published"] == "0" and values["rate configured (Hz)"] == "20"

        # the hand delivers: every status has its counts, the output its rate
        hand.write([3.0])
        st = wait_status(diag, lambda s: s[INPUT_HAND][0] != ERROR and int(s[OUTPUT][2]["published"]) > 0,
                         "the hand received and messages published")
        assert st[INPUT_HAND][2]["received"] == "1" and st[INPUT_HAND][2]["dropped"] == "0"
        level, text, values, _ = st[OUTPUT]
        achieved = float(values["rate achieved (Hz)"])
        assert level == (OK if achieved >= 20 * 0.9 else WARN), (level, text, values)

        # the arm's producer stalls: its input goes stale (WARN), counts frozen
        os.kill(arm.pid, signal.SIGSTOP)
        try:
            st = wait_status(diag, lambda s: s[INPUT_ARM][0] == WARN, "the arm stale")
            level, text, values, _ = st[INPUT_ARM]
            assert text.startswith("stale: no data for ")
            assert values["stale periods"] == "1"
            frozen = values["received"]
            st = wait_status(diag, lambda s: True, "one more array")
            assert st[INPUT_ARM][0] == WARN and st[INPUT_ARM][2]["received"] == frozen
        finally:
            os.kill(arm.pid, signal.SIGCONT)
        st = wait_status(diag, lambda s: s[INPUT_ARM][0] == OK, "the arm fresh again")
        assert st[INPUT_ARM][1] == "fresh"
        assert int(st[INPUT_ARM][2]["received"]) > int(frozen)
        assert st[INPUT_ARM][2]["stale periods"] == "1"
        last = st
        log = stop_clean(node)
        # the exit totals count at least what /diagnostics said last
        assert totals(log)["/diag/hand:o"] == (1, 0, int(last[INPUT_HAND][2]["stale periods"]))
        assert totals(log)["published"] >= int(last[OUTPUT][2]["published"])
    finally:
        for p in (node, arm, hand, diag):
            p.stop()


def test_the_parameter_turns_diagnostics_off(mw, start_node):
    diag = QosSubscriber(mw.env, "/diagnostics", "diagnostic_msgs/msg/DiagnosticArray").start()
    out = QosSubscriber(mw.env, "/diag/point", "geometry_msgs/msg/Point").start()
    arm = YarpProducer(mw.env, "/diag/arm:o", bottles=[[0.5, -1.25]], rate=20).start()
    hand = YarpProducer(mw.env, "/diag/hand:o", bottles=[[3.0]], rate=20).start()
    node = start_node(mw, "--ros-args", "-p", "diagnostics:=false")
    try:
        node.wait_log("publishing")
        out.wait_for(3)  # the node's participant is discovered, its messages flow
        assert diag.publishers == 0 and diag.messages == []
        stop_clean(node)
    finally:
        for p in (node, arm, hand, out, diag):
            p.stop()


@pytest.mark.parametrize("value", ["-1.0", "soon"])
def test_a_bad_period_is_an_error(mw, start_node, value):
    node = start_node(mw, "--ros-args", "-p", f"diagnostic_updater.period:={value}")
    try:
        node.wait_exit(60)
        log = node.log_text()
        assert node.returncode == 2, log  # as a bad option
        assert "parameter diagnostic_updater.period must be " in log, log
        assert "Traceback" not in log, log
    finally:
        node.stop()


def test_status_levels():
    """The levels and texts of the statuses, from the runtime's state alone."""
    from ybg.runtime import ros2_io

    def head(status):  # the level (a byte in the message) as a number, and the text
        return status[0][0], status[1]

    bridge = SimpleNamespace(rate=None, published=7, skipped_cycles=0, build_errors=2, missed=3)
    status = ros2_io.output_status(bridge, 2.5)
    assert head(status) == (OK, "event-driven: 2.50 Hz")
    values = status[2]
    assert dict(values)["rate configured (Hz)"] == "event-driven"
    assert dict(values)["build failures"] == "2"
    assert dict(values)["missed by readers"] == "3"
    bridge.rate = 20.0
    assert head(ros2_io.output_status(bridge, 18.0)) == (OK, "18.00 Hz of 20 Hz")
    assert head(ros2_io.output_status(bridge, 17.99)) == (WARN, "rate too low: 17.99 Hz of 20 Hz")

    inp = SimpleNamespace(state="waiting", arrival=None, received=0, dropped=0, stale_periods=0,
                          unused=0, refused=0, timeout=0.5)
    assert head(ros2_io.input_status(inp, 100.0)) == (ERROR, "no data received yet")
    inp.state, inp.arrival, inp.received, inp.dropped, inp.refused = "stale", 97.75, 12, 3, 4
    status = ros2_io.input_status(inp, 100.0)
    assert head(status) == (WARN, "stale: no data for 2.2 s")
    values = status[2]
    assert dict(values) == {"received": "12", "dropped": "3", "stale periods": "0", "unused": "0",
                            "refused": "4", "age (s)": "2.250", "timeout (s)": "0.5"}
    inp.state = "fresh"
    assert head(ros2_io.input_status(inp, 97.875)) == (OK, "fresh")
