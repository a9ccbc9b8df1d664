"""The ``ros2`` backend's node between YARP and ROS 2 topics: generated rclpy
nodes run against real YARP and real ROS 2 (separate producer, subscriber
and publisher processes). What the backend generates, the behaviour harness
on the node and its package: tests/test_backend_ros2.py.

- YARP -> ROS 2 end to end for every example that publishes to ROS 2, and
  ROS 2 -> YARP for every example that reads ROS 2 topics;
- faults on a ROS 2 output: a producer killed and restarted, malformed
  Bottles, SIGINT/SIGTERM, while streaming and while starting (between YARP
  ports: the harness);
- parameters (rate, timeout, prefix, verbose, use_sim_time);
- differential: the same inputs through the ROS 2 node and the ``py`` module.
"""
from __future__ import annotations

import dataclasses
import functools
import math
import operator
import re
import signal
import subprocess
import time
from pathlib import Path

import pytest

from harness.env import VENV_PYTHON
from harness.generated import module_file, write_generated
from harness.launchers import require_message_packages, write_node
from harness.module import EXIT_BOUND, Node, stop_clean, totals
from harness.procs import wait_until
from harness.programs import ros2_compiled, ros2_example, yarp_to_ros2_examples
from harness.reference import (TOL, assert_close, assert_matches, check_message, expected_message, sent_values,
                               wait_matching, write_all)
from harness.ros2 import Ros2Publisher, ros2_type, subscriber_for, wait_matched
from harness.yarp import YarpProducer, YarpReader
from ybg.backends.py import PyBackend
from ybg.compiler.ir import MessageArray, MuxRef, Output, QoS, Struct, Timestamp

# on YARP 3.5 and 4.0.0: 3.12.3 is the version tests' (docs/yarp-versions.md);
# the logs of the nodes a test ran, shown when it fails (conftest.py)
pytestmark = [pytest.mark.yarp_ends, pytest.mark.usefixtures("node_logs")]


# --------------------------------------------------------------------------
# helpers


def ns_of(seconds: float) -> tuple[int, int]:
    return divmod(round(seconds * 1e9), 1_000_000_000)


def stamp_seconds(stamp: dict) -> float:
    return stamp["sec"] + stamp["nanosec"] * 1e-9


def _uses_envelope(struct: Struct) -> bool:
    return any(_source_uses_envelope(f.source) for f in struct.fields)


def _source_uses_envelope(src) -> bool:
    if isinstance(src, Timestamp):
        return src.clock == "envelope"
    if isinstance(src, Struct):
        return _uses_envelope(src)
    if isinstance(src, MessageArray):
        return any(_source_uses_envelope(e) for e in src.elements)
    return False


# --------------------------------------------------------------------------
# YARP -> ROS 2, every example


def start_yarp_to_ros2(mw, stem, folder, *args):
    program = ros2_example(stem)
    require_message_packages(program)
    path = write_node(program, folder)
    started = []
    try:
        sub = subscriber_for(mw.env, program).start()
        started.append(sub)
        node = Node(mw.env, path, *args).start()
        started.append(node)
        producers = []
        for port in sent_values(program):
            producers.append(YarpProducer(mw.env, port).start())
            started.append(producers[-1])
        node.wait_log("publishing")
        for p in producers:
            p.wait_outputs(1, timeout=60)
        wait_matched(node, sub, program)
    except BaseException:
        for proc in started:
            proc.stop()
        raise
    return program, node, sub, producers


# The ROS 2 side of every example (the QoS offered, the exact message), on
# today's YARP: how each YARP release's Bottles are read is
# TestRos2Behaviour::test_config_end_to_end, on every release of the matrix.
@pytest.mark.yarp_min((4, 0))
@pytest.mark.parametrize("stem", yarp_to_ros2_examples())
def test_yarp_to_ros2(mw, tmp_path, stem):
    """Producers, the node, a subscriber with the output's QoS: the exact
    message; new values give a new message; exit totals."""
    program, node, sub, producers = start_yarp_to_ros2(mw, stem, tmp_path)
    stamped = _uses_envelope(program.message)
    try:
        qos = program.output.qos or QoS()  # what the node's publisher offers
        assert sub.publisher_qos == [{"reliability": qos.reliability, "durability": qos.durability}]
        sent, stamps, t_before = write_all(program, producers, stamped=stamped)
        got = sub.wait_after(t_before)
        check_message(got, expected_message(program, sent, stamps), t_before)
        sent, stamps, t_before = write_all(program, producers, offset=100.0, stamped=stamped)
        wait_matching(sub, t_before, expected_message(program, sent, stamps))
        log = stop_clean(node)
    finally:
        for p in producers:
            p.stop()
        sub.stop()
        node.stop()
    t = totals(log)
    for port in sent:
        assert t[port][:2] == (2, 0), t
    assert t["published"] >= 2 and t["failures"] == 0


# --------------------------------------------------------------------------
# ROS 2 -> YARP


@pytest.mark.parametrize("stem", ["ros2_to_yarp_gaze"])
def test_ros2_to_yarp(mw, tmp_path, stem):
    """A ROS 2 publisher, the node, a YARP reader on the port the config
    connects to; the reader restarted: the node connects to it again."""
    program = ros2_example(stem)
    assert program.output.connect_to
    (inp,) = [i for m in program.muxes for i in m.inputs]
    assert inp.kind == "ros2" and inp.fields == ("point.x", "point.y", "point.z")
    path = write_node(program, tmp_path)
    reader = YarpReader(mw.env, program.output.connect_to).start()
    node = Node(mw.env, path).start()
    pub = Ros2Publisher(mw.env, inp.name, ros2_type(inp.ros_type)).start()
    try:
        node.wait_log(f"connected {program.output.name} -> {program.output.connect_to}")
        pub.wait_matched(1, timeout=60)
        node.wait_log(f"{inp.name}: 1 publisher\n")  # the node's side of the match
        pub.publish({"header": {"frame_id": "goal"}, "point": {"x": 0.5, "y": -0.25, "z": 1.125}})
        (first, *_) = reader.wait_for(1)
        assert first.data == [0.5, -0.25, 1.125]
        assert first.types == ["float64"] * 3
        pub.publish({"point": {"x": 1e-3, "y": 2.0, "z": -3.0}})
        reader.wait(lambda: any(b.data == [1e-3, 2.0, -3.0] for b in reader.bottles), 10, "new point")
        # the consumer restarts: the node's watcher connects to it again
        reader.stop()
        reader.start()
        node.wait_log(f"connected {program.output.name} -> {program.output.connect_to}", count=2)
        pub.publish({"point": {"x": 7.0, "y": 8.0, "z": 9.0}})
        reader.wait(lambda: any(b.data == [7.0, 8.0, 9.0] for b in reader.bottles), 10, "after restart")
        log = stop_clean(node, signal.SIGTERM)
    finally:
        pub.stop()
        reader.stop()
        node.stop()
    t = totals(log)
    assert t[inp.name] == (3, 0, 0) or t[inp.name][:2] == (3, 0), t


# the rows of each message, on today's YARP: the Bottle of this config on every
# release is TestRos2Behaviour::test_config_end_to_end[moveit_trajectory_to_yarp]
@pytest.mark.yarp_min((4, 0))
def test_moveit_trajectory_rows_to_yarp(mw, tmp_path):
    """examples/moveit_trajectory_to_yarp.ini: each JointTrajectory becomes
    one Bottle with one list per point, (time_from_start in seconds, the
    positions in degrees), whatever the number of points and of joints."""
    program = ros2_example("moveit_trajectory_to_yarp")
    (inp,) = program.muxes[0].inputs
    assert inp.each == "points" and inp.fields == ("time_from_start", "positions")
    path = write_node(program, tmp_path)
    reader = YarpReader(mw.env, program.output.connect_to).start()
    node = Node(mw.env, path).start()
    pub = Ros2Publisher(mw.env, inp.name, ros2_type(inp.ros_type)).start()
    half = math.pi / 2
    try:
        node.wait_log(f"connected {program.output.name} -> {program.output.connect_to}")
        pub.wait_matched(1, timeout=60)
        node.wait_log(f"{inp.name}: 1 publisher\n")
        pub.publish({"joint_names": ["a", "b"], "points": [
            {"positions": [0.0, half], "time_from_start": {"sec": 0, "nanosec": 500000000}},
            {"positions": [half, math.pi], "time_from_start": {"sec": 1, "nanosec": 250000000}}]})
        (first, *_) = reader.wait_for(1)
        assert first.data == [[0.5, 0.0, 90.0], [1.25, 90.0, 180.0]]
        assert first.types == [["float64"] * 3] * 2
        pub.publish({"points": [{"positions": [-half, 0.0, half], "time_from_start": {"sec": k}}
                                for k in range(3)]})
        want = [[float(k), -90.0, 0.0, 90.0] for k in range(3)]
        reader.wait(lambda: any(b.data == want for b in reader.bottles), 10, "three points of three joints")
        log = stop_clean(node, signal.SIGTERM)
    finally:
        pub.stop()
        reader.stop()
        node.stop()
    assert totals(log)[inp.name][:2] == (2, 0)


JOINT_RELAY = """\
[module]
name = joint_relay

[output]
port = /joint_relay/out:o
on_nan = drop

[mux arm]
topics = /joint_states (sensor_msgs/JointState position)
via = ros2
convert = scale(2.0)

[message]
stamp = timestamp(arm)
values = [arm]
first = arm[0]
"""


# on today's YARP: a Bottle of lists written by the node to a YARP reader on
# every release is TestRos2Behaviour::test_config_end_to_end of the ROS 2 to
# YARP configs (ros2_to_yarp_gaze, moveit_trajectory_to_yarp, ros2_pose_goal_to_icub)
@pytest.mark.yarp_min((4, 0))
def test_ros2_array_field_to_yarp(mw, tmp_path):
    """One numeric array field of a ROS 2 message (any length) as a mux; its
    header.stamp as the envelope; a message holding NaN dropped and counted."""
    config = tmp_path / "joint_relay.ini"
    config.write_text(JOINT_RELAY)
    program = ros2_compiled(str(config))
    (inp,) = program.muxes[0].inputs
    assert (inp.kind, inp.fields, inp.layout) == ("ros2", ("position",), None)
    path = write_node(program, tmp_path)
    reader = YarpReader(mw.env, "/joint_relay/in:i", source="/joint_relay/out:o").start()
    node = Node(mw.env, path).start()
    pub = Ros2Publisher(mw.env, "/joint_states", "sensor_msgs/msg/JointState").start()
    try:
        reader.wait_connected(timeout=60)
        pub.wait_matched(1, timeout=60)
        node.wait_log("/joint_states: 1 publisher\n")
        pub.publish({"header": {"stamp": {"sec": 1234, "nanosec": 500000000}},
                     "position": [1.0, 2.5, -3.0]})
        (b,) = reader.wait_for(1)
        assert b.data == [[1234, 500000000], [2.0, 5.0, -6.0], 2.0]
        pub.publish({"position": [1.0, float("nan")]})
        node.wait_log("dropped a Bottle (element 1 is NaN)")  # taken before the next one comes
        pub.publish({"position": [0.5, 0.25, 0.125, 4.0, -1.0]})
        bottles = reader.wait_for(2)
        time.sleep(0.2)
        assert len(reader.bottles) == 2
        assert bottles[1].data[1:] == [[1.0, 0.5, 0.25, 8.0, -2.0], 1.0]
        log = stop_clean(node)
    finally:
        pub.stop()
        reader.stop()
        node.stop()
    assert "dropped a Bottle (element 1 is NaN)" in log
    assert totals(log)["/joint_states"][:2] == (3, 1)


# --------------------------------------------------------------------------
# faults


# Faults of the YARP inputs with a ROS 2 output, on today's YARP: on every
# release, an input gone stale and connected again and malformed Bottles
# dropped and counted are TestPyBehaviour's (the same YarpBridge).
@pytest.mark.yarp_min((4, 0))
def test_producer_killed_and_restarted(mw, tmp_path):
    program, node, sub, (producer,) = start_yarp_to_ros2(mw, "ball_point_stamped", tmp_path)
    try:
        producer.write([1000.0, 2000.0, 3000.0])
        sub.wait(lambda: any(m.msg["point"]["x"] == 1.0 for m in sub.messages), 10, "first point")
        producer.kill()
        node.wait_log("input /pf3dTracker/data:o is stale")
        assert node.alive
        producer.start()
        node.wait_log("connected /pf3dTracker/data:o", count=2)
        producer.write([4000.0, 5000.0, 6000.0])
        got = sub.wait(lambda: [m for m in sub.messages if m.msg["point"]["x"] == 4.0], 10,
                       "a point after the restart")[0]
        assert got.msg["point"] == {"x": 4.0, "y": 5.0, "z": 6.0}
        # stopped once stale again: the stale periods do not hang on how soon the stop came
        node.wait_log("input /pf3dTracker/data:o is stale", count=2)
        log = stop_clean(node)
    finally:
        producer.stop()
        sub.stop()
        node.stop()
    assert log.count("is stale") == 2 and log.count("is fresh again") == 1
    assert totals(log)["/pf3dTracker/data:o"] == (2, 0, 2)


@pytest.mark.yarp_min((4, 0))
def test_malformed_bottles_are_dropped_and_counted(mw, tmp_path):
    program, node, sub, (producer,) = start_yarp_to_ros2(mw, "ball_point_stamped", tmp_path)
    try:
        producer.write(["a", 1.0, 2.0])
        node.wait_log("dropped a Bottle (element 0 is a string")
        for bad in ([1.0, 2.0], [1.0, 2.0, 3.0, 4.0], [[1.0, 2.0, 3.0]]):
            producer.write(bad)
            time.sleep(0.2)  # an input keeps only its newest Bottle: one at a time
        producer.write([10.0, 20.0, 30.0])
        got = sub.wait_for(1)
        time.sleep(0.3)
        assert len(sub.messages) == 1
        assert_close(got[0].msg["point"], {"x": 0.01, "y": 0.02, "z": 0.03})
        log = stop_clean(node, signal.SIGTERM)
    finally:
        producer.stop()
        sub.stop()
        node.stop()
    assert log.count("dropped a Bottle") == 1, log
    assert "element 0 is a string" in log
    received, dropped, _ = totals(log)["/pf3dTracker/data:o"]
    # 5 written; one might be overtaken by the next on a loaded machine (newest only)
    assert received - dropped == 1 and dropped >= 3, (received, dropped)
    assert totals(log)["published"] == 1


# on today's YARP: on every release, a signal while the node streams is
# TestRos2Behaviour::test_signal_mid_stream (SIGINT, SIGTERM), while it waits for
# its inputs TestRos2Behaviour::test_producer_never_starts, while it starts
# test_signal_while_starting; the ROS 2 publisher's side depends on no release
@pytest.mark.yarp_min((4, 0))
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_exits_cleanly(mw, tmp_path, sig):
    """Exit 0 within 2 s with no traceback, while waiting for its inputs and
    while publishing; the node's ports are gone from the name server."""
    program = ros2_example("vizzy_rviz_joint_states")
    path = write_node(program, tmp_path)
    node = Node(mw.env, path).start()
    try:
        node.wait_log("waiting for")
        stop_clean(node, sig)
    finally:
        node.stop()
    assert not mw.yarp.exists("/vizzy_rviz_joint_states/arm/in0:i")
    program, node, sub, producers = start_yarp_to_ros2(mw, "imu_ros2", tmp_path / "b")
    try:
        for p in producers:
            p.send(cmd="write", data=sent_values(program)[p.port])
        sub.wait_for(3)
        log = stop_clean(node, sig)
    finally:
        for p in producers:
            p.stop()
        sub.stop()
        node.stop()
    assert totals(log)["published"] >= 3


def catches_sigterm(pid: int) -> bool:
    """Has the process installed a SIGTERM handler (its code has started)?"""
    try:
        status = Path(f"/proc/{pid}/status").read_text()
    except OSError:
        return False
    m = re.search(r"^SigCgt:\s*([0-9a-f]+)", status, re.M)
    return bool(m) and bool(int(m.group(1), 16) & (1 << (signal.SIGTERM - 1)))


def test_signal_while_starting(mw, tmp_path):
    """A signal at any moment of the start, once the node's own code runs
    (imports, rclpy, YARP ports): exit 0 within 2 s, no traceback.
    Forced: the signal is sent only once the node has installed its handler
    (read from /proc, waited for as long as a loaded machine needs), at a
    delay after it; the 2 s are timed from the signal to the exit."""
    path = write_node(ros2_example("imu_ros2"), tmp_path)
    for k, delay in enumerate((0.0, 0.1, 0.3, 0.6)):
        node = Node(mw.env, path, name=f"imu_ros2_start{k}").start()
        try:
            wait_until(lambda: catches_sigterm(node.pid), 60,
                       "the node's signal handler", node, interval=0.002)
            time.sleep(delay)
            rc, took = node.interrupt(signal.SIGINT if k % 2 else signal.SIGTERM)
            log = node.log_text()
        finally:
            node.stop()
        assert rc == 0 and took < EXIT_BOUND, (delay, rc, took, log)
        assert "Traceback" not in log, log


# --------------------------------------------------------------------------
# parameters


# The node's ROS parameters, on today's YARP: ROS 2's side depends on no YARP
# release; on every release, the options they set (--prefix, --timeout ...)
# name and watch the YARP inputs in TestPyBehaviour (the same YarpBridge).


@pytest.mark.yarp_min((4, 0))
def test_parameters(mw, tmp_path):
    """prefix names the node's ports, rate overrides the config's (event-driven
    here), verbose prints the values, timeout the freshness of every input."""
    program = ros2_example("ball_point_stamped")
    path = write_node(program, tmp_path)
    sub = subscriber_for(mw.env, program).start()
    node = Node(mw.env, path, "--ros-args", "-p", "prefix:=/custom", "-p", "rate:=20",
                "-p", "verbose:=true", "-p", "timeout:=0.3").start()
    producer = YarpProducer(mw.env, "/pf3dTracker/data:o", bottles=[[1.0, 2.0, 3.0]], rate=100).start()
    try:
        node.wait_log("on 20 Hz")
        assert mw.yarp.exists("/custom/tracker/in0:i")
        wait_matched(node, sub, program)
        node.wait_log("connected /pf3dTracker/data:o -> /custom/tracker/in0:i")
        got = sub.wait_for(20, timeout=60)
        # 20 Hz, though the input comes at 100 Hz: the stamps the node puts in
        # (its clock as it builds each message) of 20 messages span 19 cycles
        # at least (a cycle is built at most a period after it is due, later
        # ones skipped: 2 periods of room), as no reader's arrival times can say
        stamps = [stamp_seconds(m.msg["header"]["stamp"]) for m in got]
        assert stamps[-1] - stamps[0] >= (len(stamps) - 3) / 20.0, stamps
        producer.stop()
        node.wait_log("input /pf3dTracker/data:o is stale", timeout=60)
        log = stop_clean(node)
    finally:
        producer.stop()
        sub.stop()
        node.stop()
    assert "[tracker] 2: 0.003" in log
    # the node's own measure of the silence: 0.3 s, not the config's 1 s
    age = float(re.search(r"input /pf3dTracker/data:o is stale \(no data for ([\d.]+) s\)", log).group(1))
    assert 0.3 <= age < 1.0, age


@pytest.mark.yarp_min((4, 0))
def test_bad_parameter_exits_with_status_2(mw, tmp_path):
    path = write_node(ros2_example("ball_point_stamped"), tmp_path)
    for args, text in ((("-p", "rate:=-1.0"), "rate must be"), (("-p", "prefix:=nope"), "prefix must"),
                       (("-p", "verbose:=3"), "verbose must")):
        out = subprocess.run([VENV_PYTHON, path, "--ros-args", *args], env=mw.env, capture_output=True,
                             text=True, timeout=30)
        assert out.returncode == 2, out
        assert text in out.stdout and "Traceback" not in out.stdout + out.stderr
    out = subprocess.run([VENV_PYTHON, path, "--help"], env=mw.env, capture_output=True, text=True,
                         timeout=30)
    assert out.returncode == 0 and "use_sim_time" in out.stdout and "geometry_msgs/msg/PointStamped" in out.stdout


@pytest.mark.yarp_min((4, 0))
def test_use_sim_time_stamps_with_the_clock_topic(mw, tmp_path):
    program = ros2_example("vizzy_rviz_joint_states")
    path = write_node(program, tmp_path)
    clock = Ros2Publisher(mw.env, "/clock", "rosgraph_msgs/msg/Clock",
                          messages=[{"clock": {"sec": 4242, "nanosec": 500}}], rate=50).start()
    sub = subscriber_for(mw.env, program).start()
    node = Node(mw.env, path, "--ros-args", "-p", "use_sim_time:=true").start()
    producers = [YarpProducer(mw.env, port).start() for port in sent_values(program)]
    try:
        node.wait_log("publishing")
        for p in producers:
            p.wait_outputs(1, timeout=60)
        clock.wait_matched(1, timeout=60)
        wait_matched(node, sub, program)
        sim = {"sec": 4242, "nanosec": 500}
        deadline = time.monotonic() + 60
        while True:  # until the node has its first /clock message
            sent, stamps, t_before = write_all(program, producers)
            got = sub.wait_after(t_before)
            stamp = got.msg["header"]["stamp"]
            if stamp == sim:
                break
            # before it, simulated time is 0: never the wall clock
            assert stamp == {"sec": 0, "nanosec": 0}, stamp
            assert time.monotonic() < deadline, "no message stamped with the time of /clock in 60 s"
            time.sleep(0.1)
        stop_clean(node)
    finally:
        for p in producers:
            p.stop()
        clock.stop()
        sub.stop()
        node.stop()
    assert got.msg["header"]["stamp"] == {"sec": 4242, "nanosec": 500}
    assert_matches(got.msg["position"], expected_message(program, sent, stamps)["position"], (0, 0))


# --------------------------------------------------------------------------
# differential: the ROS 2 node and the py module on the same input streams


def assert_same_values(ros, bottle, path):
    """A ROS 2 value against a Bottle value: lists item by item, numbers to
    1e-12 whatever their wire type, strings exactly."""
    if isinstance(ros, list):
        assert isinstance(bottle, list) and len(ros) == len(bottle), (path, ros, bottle)
        for k, (a, b) in enumerate(zip(ros, bottle)):
            assert_same_values(a, b, f"{path}[{k}]")
    elif isinstance(ros, str):
        assert ros == bottle, (path, ros, bottle)
    else:
        assert isinstance(bottle, (int, float)), (path, ros, bottle)
        assert math.isclose(float(ros), float(bottle), rel_tol=0, abs_tol=TOL), (path, ros, bottle)


def _flat(items: list) -> list:
    """A Bottle's nested lists (a Pose's position, orientation) as one list."""
    return [x for i in items for x in (_flat(i) if isinstance(i, list) else [i])]


def _compare_tree(struct: Struct, ros: dict, bottle: list, path="msg"):
    """Field by field: the typed ROS 2 message against the py module's Bottle."""
    assert isinstance(bottle, list) and len(bottle) == len(struct.fields), f"{path}: {bottle!r}"
    for f, item in zip(struct.fields, bottle):
        value = ros[f.name]
        where = f"{path}.{f.name}"
        _compare_value(f.source, value, item, where)


def _compare_value(src, value, item, where: str) -> None:
    if isinstance(src, Struct):
        _compare_tree(src, value, item, where)
    elif isinstance(src, MessageArray):  # one nested list per element, in order
        assert isinstance(item, list) and len(value) == len(item) == len(src.elements), (where, value, item)
        for k, (element, v, i) in enumerate(zip(src.elements, value, item)):
            _compare_value(element, v, i, f"{where}[{k}]")
    elif isinstance(src, Timestamp):
        if src.clock == "envelope":  # the same envelope: the same stamp
            assert [value["sec"], value["nanosec"]] == item, (where, value, item)
    elif isinstance(src, MuxRef) and src.into_fields is not None:
        assert_same_values([functools.reduce(operator.getitem, n.split("."), value) for n in src.into_fields],
                           _flat(item), where)
    else:
        assert_same_values(value, item, where)


@pytest.mark.yarp_min((4, 0))  # as test_yarp_to_ros2: the message trees, on today's YARP
@pytest.mark.parametrize("stem", yarp_to_ros2_examples())
def test_differential_with_the_py_module(mw, tmp_path, stem):
    """The py module renders the same message tree as a Bottle: every field
    value (and every envelope stamp) is the same as in the ROS 2 message."""
    program = ros2_example(stem)
    require_message_packages(program)
    # values, not QoS, are compared here (QoS: test_yarp_to_ros2): reliable
    # delivery, so that a best-effort example (imu) loses no message under load
    if program.output.qos is not None:
        program = dataclasses.replace(program, output=dataclasses.replace(
            program.output, qos=dataclasses.replace(program.output.qos, reliability="reliable")))
    py_program = dataclasses.replace(program, module="ros2_diff_py",
                                     output=Output("yarp", "/ros2_diff_py/out:o", program.output.msg_type))
    py_files = PyBackend().render(py_program)
    write_generated(tmp_path, py_files)
    py_path = tmp_path / module_file(py_files, ".py")[0]
    path = write_node(program, tmp_path)
    sub = subscriber_for(mw.env, program).start()
    reader = YarpReader(mw.env, "/ros2_diff_py/in:i", source="/ros2_diff_py/out:o").start()
    node = Node(mw.env, path, "--ros-args", "-p", "rate:=0.0").start()
    py_module = Node(mw.env, py_path, "--rate", "0", name="ros2_diff_py").start()
    producers = [YarpProducer(mw.env, port).start() for port in sent_values(program)]
    stamped = _uses_envelope(program.message)
    try:
        node.wait_log("event-driven")
        py_module.wait_log("event-driven")
        for p in producers:
            p.wait_outputs(2, timeout=60)
        wait_matched(node, sub, program)
        reader.wait_connected()
        rounds = 4
        for k in range(rounds):
            write_all(program, producers, offset=3.0 * k, stamped=stamped)
            sub.wait_for(k + 1)
            reader.wait_for(k + 1)
        time.sleep(0.2)
        assert len(sub.messages) == len(reader.bottles) == rounds
        for m, b in zip(sub.messages, reader.bottles):
            _compare_tree(program.message, m.msg, b.data)
        assert sub.messages[0].msg != sub.messages[-1].msg
    finally:
        for p in producers:
            p.stop()
        for proc in (sub, reader, node, py_module):
            proc.stop()
