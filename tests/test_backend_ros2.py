"""The ``ros2`` backend: generated rclpy nodes run against real YARP and real
ROS 2 (separate producer, subscriber and publisher processes).

- generation (the golden files of every ROS 2 example: tests/test_golden.py):
  Python types of every field (the generated module imported and its
  message builder called), escaping, lowering errors, no name clash with
  the shared runtime;
- the thesis' legacy Rviz config converted with ``ybgc fmt --to named --ros2``;
- the behaviour harness (tests/harness/behaviour.py): ``TestRos2Behaviour`` says how
  the node is started, the harness runs every behaviour of a module between
  YARP ports on it, and every config this backend builds; the expected
  messages come from the harness's reference;
- the ament_python package (``--package``).

The node between YARP and ROS 2 topics (every example both ways, its faults,
its parameters, the differential with the ``py`` module):
tests/test_backend_ros2_node.py.
"""
from __future__ import annotations

import ast
import configparser
import dataclasses
import importlib.util
import types
import math
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import pytest

from harness.behaviour import BridgeBehaviour, NeverStartsAtAFixedRateOnTodayYarp, on_today_yarp
from harness.env import EXAMPLES, LEGACY_DIR, ROOT, VENV_PYTHON
from harness.generated import load_module
from harness.launchers import Ros2Modules, write_node
from harness.module import Node, stop_clean
from harness.programs import (DEG, ros2_compiled, ros2_example, ros2_examples, ros2_to_yarp_examples,
                              yarp_to_ros2_examples)
from harness.reference import assert_close, check_message, expected_message, sent_values
from harness.ros2 import subscriber_for, wait_matched
from harness.yarp import YarpProducer
from ybg.backends import RenderOptions, get_backend
from ybg.backends.ros2 import Ros2Backend
from ybg.backends.runtime import PY_MODULES, RUNTIME_DIR
from ybg.backends.ros2.lower import LoweringError, package_name
from ybg.compiler.ir import (Counter, Default, ElementGroup, Field, Input, Literal, Mux, MuxRef, Output, Program,
                             QoS, Seconds, Struct, Timestamp, Timing, TypeRef)

# on YARP 3.5 and 4.0.0: 3.12.3 is the version tests' (docs/yarp-versions.md);
# the logs of the nodes a test ran, shown when it fails (conftest.py)
pytestmark = [pytest.mark.yarp_ends, pytest.mark.usefixtures("node_logs")]

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
