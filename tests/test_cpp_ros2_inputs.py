"""ROS 2 topic inputs of the ``cpp`` backend: the native module subscribes
through rcl (docs/ros2-native.md) and reads the same values as the Python
ROS 2 node (ybg/runtime/ros2_io.py).

The examples that read ROS 2 and write a YARP port, built once per YARP
version against the ROS 2 wheels, run with a yarpserver, an rclpy publisher
and a YARP reader (the behaviour harness's ``test_config_end_to_end`` runs
them too, from the reference values); here: the exact Bottles, with the
converters applied, against the Python ROS 2 node reading the same topic
(differential), an input that goes stale as the Python node's does, SIGINT
with a live publisher; and what the C++ module still cannot read is E318.
"""
from __future__ import annotations

import dataclasses
import math
import random
import signal
import struct
import time

import pytest

from behaviour import Module, config_program
from middleware import VENV, Ros2Publisher, YarpReader
from test_backend_cpp import ROOT, Builds, ros2_environment
from test_backend_ros2 import totals, write_node
from ybg.backends import check_result
from ybg.compiler.pipeline import compile_path

EXAMPLES = ROOT / "examples"
POSE = "ros2_pose_goal_to_icub"
GAZE = "ros2_to_yarp_gaze"


@pytest.fixture(scope="module")
def built(tmp_path_factory, yarp) -> Builds:
    """The ROS 2 -> YARP examples, generated with --backend cpp and built
    (one CMake project) against ``yarp`` and the ROS 2 wheels."""
    b = Builds(tmp_path_factory.mktemp(f"cpp_ros2_inputs_{yarp.version}"), yarp)
    for stem in (POSE, GAZE):
        b.add(stem, config_program(EXAMPLES / f"{stem}.ini", "cpp"))
    return b


def ros2_type(msg_type: str) -> str:
    pkg, name = msg_type.split("/")
    return f"{pkg}/msg/{name}"


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
    0.3 s until every reader has a Bottle after it (``want``: that Bottle)."""
    counts = [len(r.bottles) for r in readers]
    end = time.monotonic() + timeout
    while True:
        pub.publish(msg)
        deadline = time.monotonic() + 0.3
        while time.monotonic() < deadline:
            if all(any(want is None or b.data == want for b in r.bottles[n:]) for r, n in zip(readers, counts)):
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


def test_pose_goal_reads_the_fields_and_applies_the_converters(built, yarp_server, ros2_domain):
    """examples/ros2_pose_goal_to_icub.ini: an rclpy PoseStamped, the
    module, a YARP reader on the port the config connects to: the position
    clamped to the box, the orientation as axis and angle, all float64."""
    program = built.programs[POSE]
    (inp,) = program.muxes[0].inputs
    env = ros2_environment(yarp_server.env, ros2_domain)
    reader = YarpReader(env, program.output.connect_to)
    module = Module([built.exe(POSE)], env=env, name=POSE)
    pub = Ros2Publisher(env, inp.name, ros2_type(inp.ros_type))
    procs = [reader, module, pub]
    try:
        for p in procs:
            p.start()
        module.wait_log("30 Hz")
        pub.wait_matched(1, timeout=60)
        publish_until(pub, pose(0.25, -0.9, 0.125, math.pi / 2), [reader])
        got = reader.bottles[-1]
        assert got.types == ["float64"] * 7
        assert got.data[:3] == [0.25, -0.6, 0.125]
        assert got.data[3:6] == pytest.approx([0.0, 0.0, 1.0], abs=1e-12)
        assert got.data[6] == pytest.approx(math.pi / 2, abs=1e-12)
        publish_until(pub, pose(1.5, 0.0, -0.0625, math.pi / 3, (1.0, 0.0, 0.0)), [reader])
        got = reader.bottles[-1]
        assert got.data[:3] == [0.6, 0.0, -0.0625]
        assert got.data[3:] == pytest.approx([1.0, 0.0, 0.0, math.pi / 3], abs=1e-12)
        rc, elapsed = module.interrupt(signal.SIGINT)
        assert rc == 0 and elapsed < 2.0, module.log_text()[-2000:]
        t = totals(module.log_text())
        assert t[inp.name][1] == 0 and t[inp.name][0] >= 2 and t["published"] >= 2, t
    finally:
        for p in reversed(procs):
            p.stop()


@pytest.mark.parametrize("stem", [POSE, GAZE])
def test_native_module_writes_what_the_python_node_writes(built, yarp_server, ros2_domain, tmp_path, stem):
    """The same rclpy stream read by the native module and by the Python
    ROS 2 node of --backend ros2, each writing its own YARP port: the same
    Bottles, bit for bit, message after message."""
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
        assert len(native_bottles) == 12, native_bottles
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
        counts = [len(r.bottles) for r in readers]
        time.sleep(0.5)
        assert [len(r.bottles) for r in readers] == counts  # on_stale = skip: nothing written
        pub = Ros2Publisher(env, inp.name, ros2_type(inp.ros_type),
                            messages=[{"point": {"x": 1.0, "y": 2.0, "z": 3.0}}], rate=50)
        procs.append(pub)
        pub.start()
        for r in readers:
            r.wait(lambda r=r: any(b.data == [1.0, 2.0, 3.0] for b in r.bottles), 60, "fresh again")
        native.wait_log(f"{inp.name} is fresh again")
        rc, elapsed = native.interrupt(signal.SIGINT)
        log = native.log_text()
        assert rc == 0 and elapsed < 2.0, log[-2000:]
        received, dropped, stale = totals(log)[inp.name]
        assert received >= 2 and dropped == 0 and stale == 1, log[-2000:]
    finally:
        for p in reversed(procs):
            p.stop()


def test_what_the_cpp_module_cannot_read_is_e318_at_the_input():
    """The elements of an array of messages, one row each (the MoveIt
    trajectory), need a mux of rows, which the C++ module has not: E318 at
    the topic, with a hint; the ros2 backend builds it."""
    result = check_result(compile_path(EXAMPLES / "moveit_trajectory_to_yarp.ini"), "cpp")
    (d,) = result.errors
    assert d.code == "E318" and (d.span.line, d.span.column) == (15, 10), str(d)
    assert "array of messages" in d.message and "`--backend ros2`" in d.hint
    for stem in (POSE, GAZE):
        assert check_result(compile_path(EXAMPLES / f"{stem}.ini"), "cpp").ok
