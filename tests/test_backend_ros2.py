"""The ``ros2`` backend: generated rclpy nodes run against real YARP and real
ROS 2 (separate producer, subscriber and publisher processes).

- generation (the golden files of every ROS 2 example: tests/test_golden.py):
  Python types of every field (the generated module imported and its
  message builder called), escaping, lowering errors, no name clash with
  the shared runtime;
- YARP -> ROS 2 end to end for every example that publishes to ROS 2, and
  ROS 2 -> YARP for every example that reads ROS 2 topics;
- the thesis' legacy Rviz config converted with ``ybgc fmt --to named --ros2``;
- faults on a ROS 2 output: a producer killed and restarted, malformed
  Bottles, SIGINT/SIGTERM (between YARP ports: the harness);
- the behaviour harness (tests/harness/behaviour.py): ``TestRos2Behaviour`` says how
  the node is started, the harness runs every behaviour of a module between
  YARP ports on it, and every config this backend builds; the expected
  messages come from the harness's reference;
- parameters (rate, timeout, prefix, verbose, use_sim_time);
- differential: the same inputs through the ROS 2 node and the ``py`` module;
- the ament_python package (``--package``).
"""
from __future__ import annotations

import ast
import configparser
import dataclasses
import functools
import importlib.util
import types
import math
import operator
import re
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path
from types import SimpleNamespace

import pytest

from harness.behaviour import BridgeBehaviour, NeverStartsAtAFixedRateOnTodayYarp, on_today_yarp
from harness.env import EXAMPLES, LEGACY_DIR, ROOT, VENV_PYTHON
from harness.generated import load_module, module_file, write_generated
from harness.launchers import Ros2Modules, require_message_packages, write_node
from harness.module import EXIT_BOUND, Node, stop_clean, totals
from harness.procs import wait_until
from harness.programs import (DEG, ros2_compiled, ros2_example, ros2_examples, ros2_to_yarp_examples,
                              yarp_to_ros2_examples)
from harness.reference import (assert_matches, check_message, expected_message, sent_values, wait_matching,
                               write_all)
from harness.ros2 import Ros2Publisher, ros2_environment, ros2_type, subscriber_for, wait_matched
from harness.yarp import YarpProducer, YarpReader
from ybg.backends import RenderOptions, get_backend
from ybg.backends.py import PyBackend
from ybg.backends.ros2 import Ros2Backend
from ybg.backends.runtime import PY_MODULES, RUNTIME_DIR
from ybg.backends.ros2.lower import LoweringError, package_name
from ybg.compiler.ir import (Counter, Default, ElementGroup, Field, Input, Literal, Mux,
                             MessageArray, MuxRef, Output, Program, QoS, Seconds, Struct, Timestamp, Timing,
                             TypeRef)

# on YARP 3.5 and 4.0.0: 3.12.3 is the version tests' (docs/yarp-versions.md)
pytestmark = pytest.mark.yarp_ends

TOL = 1e-12

#: a string that breaks naive code generation in every way we know of
EVIL = ("q\"uo'te \\back\\slash\\\nnew line */ /* ''' \"\"\" # ; {{ x }} {% raw %} "
        "\t tab ünïcødé 日本語 \u2028 end\\ -- <x>&amp;")


# --------------------------------------------------------------------------
# helpers


def import_node(program: Program, folder: Path):
    """The generated node imported as a module (it runs nothing on import),
    as one namespace with the names of the runtime beside it (Context,
    Stamps, convert ...): what the node's code sees when inlined."""
    module, runtime = load_module(write_node(program, folder), f"ybg_test_{program.module}_node")
    names = {}
    for part in ("core", "yarp_io", "ros2_io"):
        names.update(vars(runtime[part]))
    names.update(vars(module))
    return types.SimpleNamespace(**names)


@pytest.fixture(autouse=True)
def _print_node_logs():
    """The logs of the nodes a test ran, shown by pytest when it fails."""
    Node.started.clear()
    yield
    for node in Node.started:
        print(f"---- log of {node.name}:\n{node.log_text()[-4000:]}")


def ns_of(seconds: float) -> tuple[int, int]:
    return divmod(round(seconds * 1e9), 1_000_000_000)


def stamp_seconds(stamp: dict) -> float:
    return stamp["sec"] + stamp["nanosec"] * 1e-9


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



@pytest.fixture
def mw(yarp_server, ros2_domain):
    """One environment with the YARP name server and the ROS 2 domain."""
    return SimpleNamespace(env=ros2_environment(yarp_server.env, ros2_domain), yarp=yarp_server, ros2=ros2_domain)


# --------------------------------------------------------------------------
# the behaviour harness on the ROS 2 node (YARP ports in and out, or a ROS 2
# topic; the module's command line as ROS parameters: harness/launchers.py)


class TestRos2Behaviour(NeverStartsAtAFixedRateOnTodayYarp, BridgeBehaviour):
    """The node between YARP ports (the ros2 backend builds YARP outputs
    too), and every config it builds; not ROS 1."""

    backend = "ros2"

    @pytest.fixture
    def env(self, mw) -> dict:
        return mw.env

    @pytest.fixture
    def modules(self, tmp_path, ros2_domain) -> Ros2Modules:
        return Ros2Modules(tmp_path, ros2_domain)

    # Between YARP ports the node is the runtime's YarpBridge (its NodeBridge
    # subclass: ybg/runtime/ros2_io.py), the code the py module runs: how each
    # YARP release's Bottles are read and written, dropped and counted, its
    # connections lost and made again, its readers fast and held up, and the
    # runtime's own decisions (its clock, hold, trigger, options) are
    # TestPyBehaviour's (tests/test_backend_py.py) on every release. Here, those
    # run on today's YARP only. On every release stays where the node's own code
    # (rclpy started before the bridge, its executor thread stopped after it)
    # meets each release's bindings (the interpreter lock that YARP 3.12's keep
    # in their calls: docs/yarp-versions.md): waiting for inputs, signals, the
    # exit within 2 s with a stalled reader, and every config end to end.

    test_values_order_nesting_counter_and_stamps = on_today_yarp(
        BridgeBehaviour.test_values_order_nesting_counter_and_stamps)
    test_indexed_labels_nest_one_list_per_index = on_today_yarp(
        BridgeBehaviour.test_indexed_labels_nest_one_list_per_index)
    test_malformed_bottles_and_nan_are_dropped_and_counted = on_today_yarp(
        BridgeBehaviour.test_malformed_bottles_and_nan_are_dropped_and_counted)
    test_malformed_bottles_of_one_input_dropped_and_counted = on_today_yarp(
        BridgeBehaviour.test_malformed_bottles_of_one_input_dropped_and_counted)
    test_nan_passes_by_default = on_today_yarp(BridgeBehaviour.test_nan_passes_by_default)
    test_fixed_rate_50hz_with_nan_passing = on_today_yarp(
        BridgeBehaviour.test_fixed_rate_50hz_with_nan_passing)
    test_fixed_rate_skips_overrun_cycles = on_today_yarp(BridgeBehaviour.test_fixed_rate_skips_overrun_cycles)
    test_escaped_strings_arrive_exactly = on_today_yarp(BridgeBehaviour.test_escaped_strings_arrive_exactly)
    test_verbose_prints_values_after_conversion = on_today_yarp(
        BridgeBehaviour.test_verbose_prints_values_after_conversion)
    test_envelope_stamp = on_today_yarp(BridgeBehaviour.test_envelope_stamp)
    test_hold_policy_and_cli_options = on_today_yarp(BridgeBehaviour.test_hold_policy_and_cli_options)
    test_hold_policy_and_trigger_any = on_today_yarp(BridgeBehaviour.test_hold_policy_and_trigger_any)
    test_producer_killed_and_restarted = on_today_yarp(BridgeBehaviour.test_producer_killed_and_restarted)
    test_producer_killed_and_restarted_twice = on_today_yarp(
        BridgeBehaviour.test_producer_killed_and_restarted_twice)
    test_queue_one_keeps_the_newest_bottle_only = on_today_yarp(
        BridgeBehaviour.test_queue_one_keeps_the_newest_bottle_only)
    test_event_driven_wakes_on_arrival = on_today_yarp(BridgeBehaviour.test_event_driven_wakes_on_arrival)
    test_a_burst_within_the_backlog_is_relayed_whole_and_in_order = on_today_yarp(
        BridgeBehaviour.test_a_burst_within_the_backlog_is_relayed_whole_and_in_order)
    test_a_reader_held_up_skips_the_oldest_and_says_so = on_today_yarp(
        BridgeBehaviour.test_a_reader_held_up_skips_the_oldest_and_says_so)


# --------------------------------------------------------------------------
# what each example must publish, from the values its producers wrote: the
# harness's reference (tests/harness/reference.py), with named fields


def test_every_ros2_example_is_covered():
    """The reference expresses the message of every ROS 2 example."""
    stems = set(ros2_examples())
    assert {"vizzy_rviz_joint_states", "icub_moveit_joint_states", "ball_point_stamped",
            "imu_ros2", "ros2_to_yarp_gaze", "ball_markers_ros2", "tf_frames_ros2"} <= stems
    assert set(yarp_to_ros2_examples()) == {"vizzy_rviz_joint_states", "icub_moveit_joint_states",
                                            "ball_point_stamped", "imu_ros2", "ball_markers_ros2",
                                            "tf_frames_ros2", "icub_imu_ros2", "icub_cartesian_pose_ros2"}
    assert set(ros2_to_yarp_examples()) == {"ros2_to_yarp_gaze", "moveit_trajectory_to_yarp",
                                            "ros2_pose_goal_to_icub"}
    for stem in yarp_to_ros2_examples():
        program = ros2_example(stem)
        want = expected_message(program, sent_values(program), {})
        assert set(want) == {f.name for f in program.message.fields}


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


def test_output_is_deterministic_and_compiles():
    for stem in ros2_examples():
        program = ros2_example(stem)
        a = Ros2Backend().render(program, RenderOptions(package=True))
        b = get_backend("ros2").render(program, RenderOptions(package=True))
        assert a == b
        for rel, text in a.items():
            assert "generated by ybgc" in text.splitlines()[0].lower(), rel
            if rel.endswith(".py"):
                compile(text, rel, "exec")
                assert not undefined_globals(text, rel), (rel, undefined_globals(text, rel))
        node = a[f"{package_name(program.module)}/{program.module}_node.py"]
        for region in ("imports", "setup", "compute"):
            assert f"# ybgc:user-begin {region}\n" in node and f"# ybgc:user-end {region}\n" in node


def undefined_globals(source: str, filename: str) -> set[str]:
    """Names that functions of ``source`` read as globals but that neither
    the module nor the builtins define (an import the runtime needs and the
    node template lacks shows up here, not only when that code runs)."""
    import builtins
    import symtable

    top = symtable.symtable(source, filename, "exec")
    defined = {s.get_name() for s in top.get_symbols() if s.is_assigned() or s.is_imported()}
    defined |= {c.get_name() for c in top.get_children()}
    defined |= set(dir(builtins))
    missing = set()

    def walk(table):
        for sym in table.get_symbols():
            if sym.is_referenced() and sym.is_global() and sym.get_name() not in defined:
                missing.add(sym.get_name())
        for child in table.get_children():
            walk(child)

    for child in top.get_children():
        walk(child)
    return missing


def _top_level_names(source: Path) -> set[str]:
    text = source.read_text()
    names = set()
    for node in ast.parse(text).body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
    return names


def test_no_name_clash_with_the_shared_runtime():
    """--single-file inlines the runtime's modules one after the other in
    one namespace: no module may redefine a name of another."""
    where = {}
    for module in PY_MODULES:
        for name in _top_level_names(RUNTIME_DIR / f"{module}.py"):
            assert where.setdefault(name, module) == module, (name, where[name], module)
    assert {"Bridge", "Input", "Context", "convert", "Process", "CommandsBridge"} <= set(where)
    # and no message class alias (ros_<pkg>_<Name>) can clash with either
    assert not any(n.startswith("ros_") for n in where)


# --------------------------------------------------------------------------
# the message builder, called in-process on real rclpy messages


def test_imu_fields_have_the_right_python_types(tmp_path):
    import rclpy.time

    program = ros2_example("imu_ros2")
    node = import_node(program, tmp_path)
    values = [0.5, -0.5, 0.5, 0.5, 10.0, 20.0, 30.0, 0.0, 0.0, 9.81]  # a unit quaternion: quat_normalize keeps it
    ctx = node.Context({"inertial": node.convert(values, node.SPEC.muxes[0].converters)}, 0, {})
    msg = node.build_message(ctx, node.Stamps(rclpy.time.Time(nanoseconds=1_500_000_000), {}))
    assert type(msg).__name__ == "Imu"
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (1, 500_000_000)
    assert msg.header.frame_id == "imu_link"
    assert [msg.orientation.x, msg.orientation.y, msg.orientation.z, msg.orientation.w] == values[:4]
    assert msg.angular_velocity.y == 20.0 * DEG
    assert msg.linear_acceleration.z == 9.81
    assert list(msg.orientation_covariance) == [0.01, 0, 0, 0, 0.01, 0, 0, 0, 0.01]
    assert str(msg.orientation_covariance.dtype) == "float64" and len(msg.linear_acceleration_covariance) == 9


def typed_program(layout, target_type="sensor_msgs/JointState", fields=None, rate=None):
    """One mux (``layout`` None: undeclared) into a typed message."""
    return Program(
        module="typed_bridge", source="typed_bridge.ini",
        muxes=(Mux("m", (Input("/typed/in:o", layout=layout),)),),
        message=Struct(tuple(fields), target_type),
        output=Output("ros2", "/typed", target_type, qos=QoS()),
        timing=Timing(rate=rate), ros="ros2", distro="jazzy")


def _header(frame, stamp=Timestamp(style="ros2")):
    return Field("header", Struct((
        Field("stamp", stamp, TypeRef("builtin_interfaces/Time")),
        Field("frame_id", Literal((frame,), "string"), TypeRef("string")),
    ), "std_msgs/Header"), TypeRef("std_msgs/Header"))


def test_integers_strings_counter_and_escaping(tmp_path):
    """Int mux values into float64[]; int literals into float64[9]; a
    counter and the node-clock seconds into scalars; strings full of
    quotes round-trip exactly."""
    import rclpy.time

    program = typed_program(
        (ElementGroup("int32", 3),),
        "sensor_msgs/JointState",
        [_header(EVIL),
         Field("name", Literal((EVIL, "", "b"), "string", True), TypeRef("string", "sequence")),
         Field("position", MuxRef("m"), TypeRef("float64", "sequence")),
         Field("velocity", Literal((1, 2), "int32", True), TypeRef("float64", "sequence")),
         Field("effort", Default(), TypeRef("float64", "sequence"))])
    node = import_node(program, tmp_path)
    ctx = node.Context({"m": [1, -2, 3]}, 7, {})
    msg = node.build_message(ctx, node.Stamps(rclpy.time.Time(nanoseconds=5), {}))
    assert msg.header.frame_id == EVIL
    assert list(msg.name) == [EVIL, "", "b"]
    assert list(msg.position) == [1.0, -2.0, 3.0] and all(type(x) is float for x in msg.position)
    assert list(msg.velocity) == [1.0, 2.0]
    assert list(msg.effort) == []

    program = typed_program(
        (ElementGroup("float64", 3), ElementGroup("int32", 1)), "sensor_msgs/Imu",
        [_header("f"),
         Field("orientation", MuxRef("m", 0, 3, into_fields=("x", "y", "z"),
                                     into_types=("float64",) * 3), TypeRef("geometry_msgs/Quaternion")),
         Field("orientation_covariance", Literal((0, 1, 2, 3, 4, 5, 6, 7, 8), "int32", True),
               TypeRef("float64", "fixed", 9))])
    node = import_node(program, tmp_path / "imu")
    msg = node.build_message(node.Context({"m": [0.5, 0.25, -1.0, 4]}, 0, {}),
                             node.Stamps(rclpy.time.Time(nanoseconds=0), {}))
    assert (msg.orientation.x, msg.orientation.y, msg.orientation.z, msg.orientation.w) == (0.5, 0.25, -1.0, 1.0)
    assert list(msg.orientation_covariance) == [float(k) for k in range(9)]

    counter = typed_program((ElementGroup("float64", 1),), "std_msgs/UInt32",
                            [Field("data", Counter("uint32"), TypeRef("uint32"))])
    node = import_node(counter, tmp_path / "counter")
    msg = node.build_message(node.Context({"m": [1.0]}, 41, {}),
                             node.Stamps(rclpy.time.Time(nanoseconds=0), {}))
    assert msg.data == 41
    seconds = typed_program((ElementGroup("float64", 1),), "std_msgs/Float64",
                            [Field("data", Seconds(), TypeRef("float64"))])
    node = import_node(seconds, tmp_path / "seconds")
    msg = node.build_message(node.Context({"m": [1.0]}, 0, {}),
                             node.Stamps(rclpy.time.Time(nanoseconds=2_250_000_000), {}))
    assert msg.data == 2.25


def test_bytes_bools_and_float32(tmp_path):
    """byte fields take bytes, bool fields bools, float32 fields floats."""
    import rclpy.time

    cases = [
        ("std_msgs/ByteMultiArray", [Field("data", MuxRef("m", 0, 2, element_type="int32"),
                                           TypeRef("byte", "sequence"))],
         lambda msg: list(msg.data) == [b"\x01", b"\xff"]),
        ("std_msgs/Bool", [Field("data", MuxRef("m", index=2, element_type="int32"), TypeRef("bool"))],
         lambda msg: msg.data is True),
        ("std_msgs/Byte", [Field("data", Literal((7,), "byte"), TypeRef("byte"))],
         lambda msg: msg.data == b"\x07"),
        ("geometry_msgs/Point32", [Field("x", MuxRef("m", index=0, element_type="int32"), TypeRef("float32")),
                                   Field("y", Literal((2,), "int32"), TypeRef("float32"))],
         lambda msg: (msg.x, msg.y, msg.z) == (1.0, 2.0, 0.0)),
    ]
    for k, (msg_type, fields, check) in enumerate(cases):
        program = typed_program((ElementGroup("int32", 3),), msg_type, fields)
        node = import_node(program, tmp_path / str(k))
        stamps_at_0 = node.Stamps(rclpy.time.Time(nanoseconds=0), {})
        msg = node.build_message(node.Context({"m": [1, 255, 1]}, 0, {}), stamps_at_0)
        assert check(msg), (msg_type, msg)


def test_dynamic_width_checks_sizes_at_run_time(tmp_path):
    """An undeclared mux into a fixed-size field: the wrong number of values
    is refused (and counted by the bridge), never sent."""
    import rclpy.time

    program = typed_program(None, "sensor_msgs/Imu", [
        Field("angular_velocity_covariance", MuxRef("m", 0, 9), TypeRef("float64", "fixed", 9)),
        Field("orientation_covariance", MuxRef("m"), TypeRef("float64", "fixed", 9)),
    ])
    node = import_node(program, tmp_path)
    stamps = node.Stamps(rclpy.time.Time(nanoseconds=0), {})
    msg = node.build_message(node.Context({"m": [float(k) for k in range(9)]}, 0, {}), stamps)
    assert list(msg.orientation_covariance) == list(msg.angular_velocity_covariance) == [float(k) for k in range(9)]
    with pytest.raises(node.FillError):
        node.build_message(node.Context({"m": [1.0] * 10}, 0, {}), stamps)
    with pytest.raises(IndexError):
        node.build_message(node.Context({"m": [1.0] * 8}, 0, {}), stamps)


def test_lowering_errors():
    backend = Ros2Backend()
    bad_size = typed_program((ElementGroup("float64", 1),), "sensor_msgs/Imu", [
        Field("orientation_covariance", Literal((0.0,) * 8, "float64", True), TypeRef("float64", "fixed", 9))])
    with pytest.raises(LoweringError, match="fixed-size"):
        backend.render(bad_size)
    bad_slice = typed_program((ElementGroup("float64", 4),), "sensor_msgs/Imu", [
        Field("orientation_covariance", MuxRef("m", 0, 4), TypeRef("float64", "fixed", 9))])
    with pytest.raises(LoweringError, match="fixed-size"):
        backend.render(bad_slice)
    no_yarp = dataclasses.replace(ros2_example("ball_point_stamped"), muxes=(
        Mux("tracker", (Input("/p", "ros2", (ElementGroup("float64", 3),), "geometry_msgs/Point",
                              ("x", "y", "z")),)),))
    with pytest.raises(LoweringError, match="no YARP port"):
        backend.render(no_yarp)
    ros1 = dataclasses.replace(ros2_example("ball_point_stamped"),
                               output=Output("ros1", "/ball", "geometry_msgs/PointStamped"))
    with pytest.raises(LoweringError, match="ros1"):
        backend.render(ros1)
    assert package_name("Vizzy__Upper-Body") == "vizzy_upper_body"
    assert package_name("9lives") == "ybg_9lives"


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
# the thesis' Rviz config (legacy, ROS 1) for ROS 2, through the CLI


def ybgc(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "ybg.cli", *map(str, args)], capture_output=True,
                          text=True, cwd=cwd or ROOT, timeout=120)


def test_legacy_ros1_config_gives_e318():
    out = ybgc(LEGACY_DIR / "thesis_figure5_rviz.ini", "--backend", "ros2", "-o", "/nonexistent/never")
    assert out.returncode == 1, out
    assert "E318" in out.stderr
    assert "fmt --to named --ros2" in out.stderr
    assert not Path("/nonexistent/never").exists()


# on today's YARP: the conversion depends on no YARP release, and an arm in
# degrees read into a JointState on every release is
# TestRos2Behaviour::test_config_end_to_end[vizzy_rviz_joint_states]
@pytest.mark.yarp_min((4, 0))
def test_thesis_rviz_config_converted_for_ros2(mw, tmp_path):
    named = tmp_path / "thesis_rviz_ros2.ini"
    out = ybgc("fmt", "--to", "named", "--ros2", LEGACY_DIR / "thesis_figure5_rviz.ini", "-o", named)
    assert out.returncode == 0, out.stderr
    out = ybgc(named, "--backend", "ros2", "-o", tmp_path / "gen")
    assert out.returncode == 0, out.stderr
    (path,) = (tmp_path / "gen").glob("*_node.py")
    program = ros2_compiled(str(named))
    sub = subscriber_for(mw.env, program).start()
    node = Node(mw.env, path).start()
    producer = YarpProducer(mw.env, "/vizzySim/left_shoulder_arm/state:o").start()
    try:
        node.wait_log("publishing")
        producer.wait_outputs(1, timeout=60)
        wait_matched(node, sub, program)
        degrees = [0.0, 90.0, -45.0, 30.0, 180.0, -90.0, 1.0, 360.0]
        t_before = time.time()
        producer.write(degrees)
        got = sub.wait_after(t_before)
        log = stop_clean(node)
    finally:
        producer.stop()
        sub.stop()
        node.stop()
    check_message(got, expected_message(program, {"/vizzySim/left_shoulder_arm/state:o": degrees}, {}),
                  t_before)
    assert got.msg["name"] == ["l_shoulder_scapula_joint", "l_shoulder_flection_joint",
                               "l_shoulder_abduction_joint", "l_shoulder_rotation_joint",
                               "l_elbow_flection_joint", "l_forearm_pronation_joint",
                               "l_wrist_abduction_joint", "l_wrist_flection_joint"]
    assert got.msg["header"]["frame_id"] == "0" and got.msg["velocity"] == got.msg["effort"] == []
    assert_close(got.msg["position"], [d * math.pi / 180.0 for d in degrees])
    assert got.msg["position"][4] == math.pi  # pi to full precision, not 3.1415926
    # the legacy config asks for verbose output: every value after conversion
    assert "[mux1] 1: %r" % (math.pi / 2) in log


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


# --------------------------------------------------------------------------
# the ament_python package


@pytest.mark.parametrize("stem", ["vizzy_rviz_joint_states", "ros2_to_yarp_gaze"])
def test_package_is_well_formed(tmp_path, stem):
    program = ros2_example(stem)
    files = Ros2Backend().render(program, RenderOptions(package=True))
    pkg = package_name(program.module)
    exe = f"{program.module}_node"
    root = tmp_path / pkg
    for rel, text in files.items():
        (root / rel).parent.mkdir(parents=True, exist_ok=True)
        (root / rel).write_text(text, encoding="utf-8")
    assert sorted(files) == sorted([
        "package.xml", "setup.py", "setup.cfg", f"resource/{pkg}", f"{pkg}/__init__.py",
        f"{pkg}/{exe}.py", f"launch/{program.module}.launch.py"]
        + [f"{pkg}/ybgc_runtime/{m}.py" for m in ("__init__", *PY_MODULES)])

    # package.xml: format 3, ament_python, exec_depend on rclpy and the message packages
    xml = ET.parse(root / "package.xml").getroot()
    assert xml.tag == "package" and xml.get("format") == "3"
    assert xml.findtext("name") == pkg
    assert xml.find("maintainer").get("email") and xml.findtext("license")
    assert xml.find("export").findtext("build_type") == "ament_python"
    deps = [e.text for e in xml.findall("exec_depend")]
    msg_pkgs = {t.split("/")[0] for t in
                [program.output.msg_type] + [i.ros_type for m in program.muxes for i in m.inputs]
                if t}
    assert deps[0] == "rclpy" and msg_pkgs <= set(deps)

    # setup.cfg: scripts into lib/<package> (where ros2 run looks)
    cfg = configparser.ConfigParser()
    cfg.read(root / "setup.cfg")
    assert cfg["install"]["install_scripts"] == f"$base/lib/{pkg}"

    # setup.py builds a wheel with the console script, the marker, package.xml and the launch file
    out = subprocess.run([VENV_PYTHON, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation",
                          "-q", "-w", tmp_path / "dist", root], capture_output=True, text=True,
                         timeout=180)
    assert out.returncode == 0, out.stderr
    (wheel,) = (tmp_path / "dist").glob("*.whl")
    with zipfile.ZipFile(wheel) as z:
        names = z.namelist()
        (entry,) = [n for n in names if n.endswith("entry_points.txt")]
        assert f"{exe} = {pkg}.{exe}:main" in z.read(entry).decode()
        for data in (f"share/ament_index/resource_index/packages/{pkg}", f"share/{pkg}/package.xml",
                     f"share/{pkg}/launch/{program.module}.launch.py"):
            assert any(n.endswith(".data/data/" + data) for n in names), (data, names)
        assert f"{pkg}/{exe}.py" in names
        # the runtime inside the package, as a subpackage of its own
        assert {f"{pkg}/ybgc_runtime/{m}.py" for m in ("__init__", "core", "yarp_io", "ros2_io")} <= set(names)
        z.extractall(tmp_path / "installed")
    # the installed node runs (its --help, without any middleware)
    out = subprocess.run([VENV_PYTHON, "-c", f"import sys; from {pkg}.{exe} import main; sys.exit(main(['--help']))"],
                         cwd=tmp_path / "installed", capture_output=True, text=True, timeout=60)
    assert out.returncode == 0 and "ROS parameters" in out.stdout, out

    # the launch file imports, and starts that executable with the node's parameters
    spec = importlib.util.spec_from_file_location("launch_file", root / "launch" / f"{program.module}.launch.py")
    launch = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(launch)
    assert callable(launch.generate_launch_description)
    assert (launch.PACKAGE, launch.EXECUTABLE) == (pkg, exe)
    assert launch.PARAMETERS == {"rate": program.timing.rate or 0.0, "timeout": 0.0,
                                 "prefix": "/" + program.module, "verbose": False,
                                 "diagnostics": True, "use_sim_time": False}
    tree = ast.parse((root / "launch" / f"{program.module}.launch.py").read_text())
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)
                for a in n.names if n.module in ("launch", "launch_ros.actions")}
    assert {"LaunchDescription", "Node"} <= imported


def test_package_regeneration_keeps_user_blocks(tmp_path):
    """Through the CLI: --package writes the package; a second run keeps what
    the user wrote in the marked places (maintainer, compute)."""
    out_dir = tmp_path / "pkg"
    out = ybgc(EXAMPLES / "imu_ros2.ini", "--backend", "ros2", "--package", "-o", out_dir)
    assert out.returncode == 0, out.stderr
    xml = out_dir / "package.xml"
    text = xml.read_text().replace('<maintainer email="maintainer@todo.todo">maintainer</maintainer>',
                                   '<maintainer email="me@example.org">Me</maintainer>')
    xml.write_text(text)
    out = ybgc(EXAMPLES / "imu_ros2.ini", "--backend", "ros2", "--package", "-o", out_dir)
    assert out.returncode == 0, out.stderr
    assert ET.parse(xml).getroot().find("maintainer").get("email") == "me@example.org"
    assert (out_dir / "resource" / "imu_ros2").exists()
