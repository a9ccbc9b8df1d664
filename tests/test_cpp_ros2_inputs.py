"""ROS 2 topic inputs of the ``cpp`` backend: the native module subscribes
through rcl (docs/ros2-native.md) and reads the same values as the Python
ROS 2 node (ybg/runtime/ros2_io.py).

The examples that read ROS 2 and write a YARP port, built once per YARP
version against the ROS 2 wheels, run with a yarpserver, an rclpy publisher
and a YARP reader (the behaviour harness's ``test_config_end_to_end`` runs
them too, from the reference values); here: the exact Bottles, with the
converters applied, against the Python ROS 2 node reading the same topic
(differential), the MoveIt trajectory's rows, an input that goes stale as
the Python node's does, SIGINT with a live publisher, a ROS 2 output and a
ROS 2 input on one node; and what the C++ module still refuses (the rows of
an array of messages into a ROS 2 message) is E318 at the topic.
"""
from __future__ import annotations

import dataclasses
import math
import os
import random
import signal
import struct
import time

import pytest

from harness.build import Builds
from harness.env import EXAMPLES, VENV
from harness.launchers import write_node
from harness.module import EXIT_BOUND, Module, stats, totals
from harness.programs import SHARED_NODE, text_program
from harness.ros2 import Ros2Publisher, ros2_environment, ros2_type, subscriber_for
from harness.yarp import YarpProducer, YarpReader
from ybg.backends import LoweringError, check_result
from ybg.backends.cpp import CppBackend
from ybg.compiler.pipeline import compile_path
from ybg.compiler.ir import QoS

# on YARP 3.5 and 4.0.0: 3.12.3 is the version tests' (docs/yarp-versions.md)
pytestmark = pytest.mark.yarp_ends

POSE = "ros2_pose_goal_to_icub"
GAZE = "ros2_to_yarp_gaze"
MOVEIT = "moveit_trajectory_to_yarp"


@pytest.fixture
def built(builds) -> Builds:
    """The session's modules of ``yarp`` (conftest.py): among them the ROS 2
    -> YARP examples, by their stems, and ``shared_node`` (SHARED_NODE),
    generated with --backend cpp and built against the ROS 2 wheels."""
    return builds


# the first test may build the session's modules (two jobs: about a minute
# on a quiet machine, minutes on a busy one): more time than a single test gets
@pytest.mark.timeout(900)
def test_modules_build_with_werror(built):
    """Each module's generated CMakeLists links rcl and the message packages
    of the topics it reads, with a YARP output too; built with -Werror."""
    for key in (POSE, GAZE, MOVEIT, "shared_node"):
        assert os.access(built.exe(key), os.X_OK)


def bits(data):
    """A Bottle's values with every float as its bits (an exact comparison)."""
    if isinstance(data, list):
        return [bits(x) for x in data]
    if isinstance(data, float):
        return struct.pack("<d", data).hex()
    return data


def distinct(bottles) -> list:
    """The Bottles' values, consecutive repeats collapsed (a message published again)."""
    out: list = []
    for b in bottles:
        if not out or out[-1] != b.data:
            out.append(b.data)
    return out


def publish_until(pub, msg, readers, want=None, timeout=60.0):
    """Publishes ``msg`` (best effort, as the inputs subscribe) again every
    0.3 s until every reader has a Bottle after it that is ``want``, or by
    default one whose values differ from the reader's newest before it: a
    module at a fixed rate writes the previous message again meanwhile."""
    counts = [len(r.bottles) for r in readers]
    before = [r.bottles[-1].data if r.bottles else None for r in readers]

    def fits(bottle, previous):
        return bottle.data != previous if want is None else bottle.data == want
    end = time.monotonic() + timeout
    while True:
        pub.publish(msg)
        deadline = time.monotonic() + 0.3
        while time.monotonic() < deadline:
            if all(any(fits(b, prev) for b in r.bottles[n:]) for r, n, prev in zip(readers, counts, before)):
                return
            time.sleep(0.02)
        if time.monotonic() > end:
            raise AssertionError(f"no Bottle after {msg!r}: {[r.bottles[n:] for r, n in zip(readers, counts)]}")


def pose(x, y, z, angle, axis=(0.0, 0.0, 1.0)):
    s = math.sin(angle / 2)
    return {"header": {"frame_id": "goal"},
            "pose": {"position": {"x": x, "y": y, "z": z},
                     "orientation": {"x": axis[0] * s, "y": axis[1] * s, "z": axis[2] * s,
                                     "w": math.cos(angle / 2)}}}


@pytest.mark.parametrize("stem", [POSE, GAZE])
def test_native_module_writes_what_the_python_node_writes(built, yarp_server, ros2_domain, tmp_path, stem):
    """The examples that read ROS 2 and write a YARP port: an rclpy
    publisher, the native module and the Python ROS 2 node of --backend ros2
    reading the same topic, each writing its own YARP reader. The values
    read (the pose goal: the position clamped to the box, the orientation as
    axis and angle, all float64), then the same Bottles from both, bit for
    bit, message after message."""
    program = built.programs[stem]
    (inp,) = program.muxes[0].inputs
    node_program = python_twin(program)
    env = ros2_environment(yarp_server.env, ros2_domain)
    readers = [YarpReader(env, program.output.connect_to), YarpReader(env, "/test/py:i")]
    native = Module([built.exe(stem)], env=env, name=stem)
    node = Module([VENV / "bin" / "python", write_node(node_program, tmp_path)], env=env, name=node_program.module)
    pub = Ros2Publisher(env, inp.name, ros2_type(inp.ros_type))
    procs = [*readers, native, node, pub]
    rng = random.Random(14)
    try:
        for p in procs:
            p.start()
        native.wait_log("30 Hz")
        node.wait_log("30 Hz")
        pub.wait_matched(2, timeout=60)
        if stem == POSE:
            publish_until(pub, pose(0.25, -0.9, 0.125, math.pi / 2), readers)
            got = readers[0].bottles[-1].data
            assert got[:3] == [0.25, -0.6, 0.125]
            assert got[3:] == pytest.approx([0.0, 0.0, 1.0, math.pi / 2], abs=1e-12)
            publish_until(pub, pose(1.5, 0.0, -0.0625, math.pi / 3, (1.0, 0.0, 0.0)), readers)
            got = readers[0].bottles[-1].data
            assert got[:3] == [0.6, 0.0, -0.0625]
            assert got[3:] == pytest.approx([1.0, 0.0, 0.0, math.pi / 3], abs=1e-12)
        else:
            publish_until(pub, {"header": {"frame_id": "goal"}, "point": {"x": 0.5, "y": -0.25, "z": 1.125}},
                          readers, want=[0.5, -0.25, 1.125])
        known = len(distinct(readers[0].bottles))
        for k in range(12):
            if stem == POSE:
                axis = [rng.uniform(-1, 1) for _ in range(3)]
                norm = math.sqrt(sum(a * a for a in axis))
                msg = pose(*(rng.uniform(-1, 1) for _ in range(3)), rng.uniform(0.1, 3.0),
                           tuple(a / norm for a in axis))
            else:
                msg = {"header": {"frame_id": "f", "stamp": {"sec": 1000 + k, "nanosec": rng.randrange(10 ** 9)}},
                       "point": {"x": rng.uniform(-2, 2), "y": rng.gauss(0, 1e-3), "z": float(k)}}
            publish_until(pub, msg, readers)
        native_bottles, node_bottles = (distinct(r.bottles) for r in readers)
        assert len(native_bottles) == known + 12, native_bottles
        assert bits(native_bottles) == bits(node_bottles)
        width = len(native_bottles[0])
        assert {tuple(b.types) for r in readers for b in r.bottles} == {("float64",) * width}
    finally:
        for p in reversed(procs):
            p.stop()


def python_twin(program):
    """The program as the Python ROS 2 node runs it beside the native module:
    its own name (node, ports) and its own YARP reader, /test/py:i."""
    module = f"{program.module}_py"
    output = dataclasses.replace(program.output, name=f"/{module}/out:o", connect_to="/test/py:i")
    return dataclasses.replace(program, module=module, output=output)


def test_stale_input_and_sigint_with_a_live_publisher(built, yarp_server, ros2_domain, tmp_path):
    """examples/ros2_to_yarp_gaze.ini (on_stale = skip, timeout 1 s): the
    publisher stops, the input goes stale and nothing more is written, as
    with the Python node; it publishes again, the input is fresh again;
    SIGINT while it publishes at 50 Hz ends the module with 0 within 2 s."""
    program = built.programs[GAZE]
    (inp,) = program.muxes[0].inputs
    node_program = python_twin(program)
    env = ros2_environment(yarp_server.env, ros2_domain)
    readers = [YarpReader(env, program.output.connect_to), YarpReader(env, "/test/py:i")]
    native = Module([built.exe(GAZE)], env=env, name=GAZE)
    node = Module([VENV / "bin" / "python", write_node(node_program, tmp_path)], env=env, name=node_program.module)
    point = {"point": {"x": 0.5, "y": -0.25, "z": 1.125}}
    pub = Ros2Publisher(env, inp.name, ros2_type(inp.ros_type), messages=[point], rate=20)
    procs = [*readers, native, node]
    try:
        for p in procs:
            p.start()
        native.wait_log("30 Hz")
        node.wait_log("30 Hz")
        pub.start()
        for r in readers:
            r.wait(lambda r=r: any(b.data == [0.5, -0.25, 1.125] for b in r.bottles), 60, "a point")
        pub.stop()  # no more messages: stale after the 1 s timeout
        for m in (native, node):
            m.wait_log(f"{inp.name} is stale", timeout=30)
        # on_stale = skip: nothing written, by each module's own count (a reader
        # may still be taking the message of the cycle before the stale one)
        ports = [f"/{program.module}/rpc:i", f"/{node_program.module}/rpc:i"]
        counts = [stats(yarp_server, port)["published"][0] for port in ports]
        time.sleep(0.5)
        assert [stats(yarp_server, port)["published"][0] for port in ports] == counts
        pub = Ros2Publisher(env, inp.name, ros2_type(inp.ros_type),
                            messages=[{"point": {"x": 1.0, "y": 2.0, "z": 3.0}}], rate=50)
        procs.append(pub)
        pub.start()
        for r in readers:
            r.wait(lambda r=r: any(b.data == [1.0, 2.0, 3.0] for b in r.bottles), 60, "fresh again")
        native.wait_log(f"{inp.name} is fresh again")
        rc, elapsed = native.interrupt(signal.SIGINT)
        log = native.log_text()
        assert rc == 0 and elapsed < EXIT_BOUND, log[-2000:]
        received, dropped, stale = totals(log)[inp.name]
        assert received >= 2 and dropped == 0 and stale == 1, log[-2000:]
    finally:
        for p in reversed(procs):
            p.stop()


def test_moveit_trajectory_one_list_per_point(built, yarp_server, ros2_domain, tmp_path):
    """examples/moveit_trajectory_to_yarp.ini: each JointTrajectory is one
    Bottle with one list per point, (time_from_start in seconds, the
    positions converted to degrees), whatever the number of points and
    joints; the Python ROS 2 node writes the same Bottles, bit for bit."""
    program = built.programs[MOVEIT]
    (inp,) = program.muxes[0].inputs
    assert inp.each == "points"
    node_program = python_twin(program)
    env = ros2_environment(yarp_server.env, ros2_domain)
    readers = [YarpReader(env, program.output.connect_to), YarpReader(env, "/test/py:i")]
    native = Module([built.exe(MOVEIT)], env=env, name=MOVEIT)
    node = Module([VENV / "bin" / "python", write_node(node_program, tmp_path)], env=env, name=node_program.module)
    pub = Ros2Publisher(env, inp.name, ros2_type(inp.ros_type))
    procs = [*readers, native, node, pub]
    half = math.pi / 2
    try:
        for p in procs:
            p.start()
        native.wait_log("event-driven")
        node.wait_log("event-driven")
        # the plan read reliably, as its mux asks (`reliability = reliable`)
        assert inp.qos == QoS("reliable", "volatile", 10)
        native.wait_log(f"{inp.name} (trajectory_msgs/msg/JointTrajectory; reliable, volatile, depth 10)")
        pub.wait_matched(2, timeout=60)
        plan = {"joint_names": ["a", "b"], "points": [
            {"positions": [0.0, half], "time_from_start": {"sec": 0, "nanosec": 500000000}},
            {"positions": [half, math.pi], "time_from_start": {"sec": 1, "nanosec": 250000000}}]}
        publish_until(pub, plan, readers)
        assert readers[0].bottles[-1].data == [[0.5, 0.0, 90.0], [1.25, 90.0, 180.0]]
        assert readers[0].bottles[-1].types == [["float64"] * 3] * 2
        rng = random.Random(7)
        for n_points, n_joints in ((3, 3), (1, 6), (0, 2), (5, 1)):
            plan = {"points": [{"positions": [rng.uniform(-3, 3) for _ in range(n_joints)],
                                "time_from_start": {"sec": k, "nanosec": rng.randrange(10 ** 9)}}
                               for k in range(n_points)]}
            publish_until(pub, plan, readers)
            assert len(readers[0].bottles[-1].data) == n_points
        native_bottles, node_bottles = (distinct(r.bottles) for r in readers)
        assert len(native_bottles) == 5, native_bottles
        assert bits(native_bottles) == bits(node_bottles)
        rc, elapsed = native.interrupt(signal.SIGINT)
        assert rc == 0 and elapsed < EXIT_BOUND, native.log_text()[-2000:]
        received, dropped, _ = totals(native.log_text())[inp.name]
        assert dropped == 0 and received >= 5
    finally:
        for p in reversed(procs):
            p.stop()


def test_ros2_output_and_ros2_input_on_one_node(built, yarp_server, ros2_domain):
    """A ROS 2 output fed by a YARP port and a ROS 2 topic: the publisher's
    node subscribes too; the message holds both, stamped with the topic's
    header.stamp (its envelope)."""
    program = built.programs["shared_node"]
    env = ros2_environment(yarp_server.env, ros2_domain)
    module = Module([built.exe("shared_node")], env=env, name="shared_node")
    sub = subscriber_for(env, program)
    producer = YarpProducer(env, "/arm/state:o", bottles=[[90.0, -45.0, 180.0]], rate=20)
    pub = Ros2Publisher(env, "/arm_and_goal/goal", "geometry_msgs/msg/PointStamped")
    procs = [module, sub, producer, pub]
    try:
        for p in procs:
            p.start()
        module.wait_log("event-driven")
        sub.wait_publishers(1)
        pub.wait_matched(1, timeout=60)
        stamp = {"sec": 1700000000, "nanosec": 250000000}
        goal = {"header": {"stamp": stamp}, "point": {"x": 0.5, "y": -0.25, "z": 1.125}}
        end = time.monotonic() + 60
        while not any(m.msg["velocity"] == [0.5, -0.25, 1.125] for m in sub.messages):
            assert time.monotonic() < end, sub.messages[-3:]
            pub.publish(goal)
            time.sleep(0.3)
        got = next(m.msg for m in sub.messages if m.msg["velocity"] == [0.5, -0.25, 1.125])
        assert got["position"] == [math.pi / 2, -math.pi / 4, math.pi]
        # the envelope is the topic's stamp in seconds (a double: 0.25 s is exact), published to the nanosecond
        assert got["header"] == {"stamp": stamp, "frame_id": "goal"}
        rc, elapsed = module.interrupt(signal.SIGINT)
        assert rc == 0 and elapsed < EXIT_BOUND, module.log_text()[-2000:]
    finally:
        for p in reversed(procs):
            p.stop()


def test_cpp_reads_ros2_inputs_and_refuses_rows_into_a_ros2_message():
    """`ybgc check --backend cpp` takes the examples that read ROS 2; the
    rows of an array of messages fill a YARP Bottle (the MoveIt example), and
    a program that would fill a ROS 2 message with them (the checker refuses
    it first, E305) is refused by the lowering at the topic (E318 there)."""
    assert "ros2" in CppBackend.input_kinds
    for stem in (POSE, GAZE, MOVEIT):
        assert check_result(compile_path(EXAMPLES / f"{stem}.ini"), "cpp").ok
    program = text_program(SHARED_NODE, "arm_and_goal.ini", "cpp")
    rows = dataclasses.replace(program.muxes[1].inputs[0], ros_type="trajectory_msgs/JointTrajectory",
                               fields=("positions",), layout=None, each="points")
    program = dataclasses.replace(program, muxes=(program.muxes[0], dataclasses.replace(program.muxes[1],
                                                                                        inputs=(rows,))))
    with pytest.raises(LoweringError, match="array of messages") as e:
        CppBackend().lower(program)
    assert e.value.span is not None and e.value.span == program.muxes[1].inputs[0].span  # the topic's item
