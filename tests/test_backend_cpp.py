"""The ``cpp`` backend: generated C++ modules, built with CMake against YARP
(``-Wall -Wextra -Werror``), run against real YARP (and ROS 1).

Every module the tests run is generated into one temporary folder and built
once per session (the ``builds`` fixture: one CMake project that adds each
module's own folder, so each module's generated CMakeLists.txt is the one
used; tests/harness/build.py): the programs of the behaviour harness
(tests/harness/programs.py, ``PROGRAMS``), every example and legacy config
this backend supports, and this file's own. To keep the session short, only
the module whose timing is measured is optimized like a user's default
build (-O2, which also checks the warnings GCC finds only when it
optimizes); the others are built without optimization; all with -Wall
-Wextra -Werror.

What a module does is tested once for every backend by the harness:
``TestCppBehaviour`` says how a C++ module is started. The rest of this file
is the C++ backend's own: escaping and literals, generation, lowering
errors, the CMake build, its install rule (its golden files:
tests/test_golden.py).
"""
from __future__ import annotations

import json
import math
import os
import random
import re
import signal
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from harness.behaviour import BridgeBehaviour, ModuleCommandLine, NeverStartsAtAFixedRateOnTodayYarp, on_today_yarp
from harness.behaviour_ros1 import Ros1Behaviour
from harness.build import RUNTIME_FOLDER
from harness.differential import Differential
from harness.launchers import CppModules
from harness.module import EXIT_BOUND, Module
from harness.programs import DEG, build_programs, escape_program, relay_program, ros1_input_program
from harness.properties import examples
from harness.ros2 import Ros2Publisher, ros2_environment, subscriber_for
from harness.yarp import YarpProducer
from ybg.backends import get_backend
from ybg.backends.cpp import ROS2_LINK, CppBackend, runtime_library
from ybg.backends.cpp.escape import (CPP_KEYWORDS, cpp_comment, cpp_float, cpp_identifier, cpp_int,
                                     cpp_std_string, cpp_string, mangle)
from ybg.backends.cpp.lower import WIRE_ROS1, WIRE_YARP, LoweringError
from ybg.compiler import ir
from ybg.compiler.diagnostics import Span
from ybg.compiler.ir import Default, Field, Input, Literal, Mux, MuxRef, Output, Program, Struct, TypeRef

# on YARP 3.5 and 4.0.0: 3.12.3 is the version tests' (docs/yarp-versions.md)
pytestmark = pytest.mark.yarp_ends

ROOT = Path(__file__).resolve().parents[1]


# --------------------------------------------------------------------------
# the behaviour harness on the C++ modules (its Launcher: harness/launchers.py)



# the first test of a YARP release builds every module of the session (two
# jobs, about two minutes on a quiet machine, more on a busy one): more time
# than a single test gets
@pytest.mark.timeout(900)
class TestCppBehaviour(NeverStartsAtAFixedRateOnTodayYarp, BridgeBehaviour, Ros1Behaviour, ModuleCommandLine):
    backend = "cpp"
    help_options = ("--name P", "--prefix P", "--rate HZ", "--timeout S", "--verbose", "--from FILE", "--context CTX",
                    "--help")

    @pytest.fixture
    def modules(self, builds, request) -> CppModules:
        return CppModules(builds, request)

    # What the runtime decides by its own clock and options, on today's YARP
    # only: the period of a fixed rate and the cycles it skips (std::chrono in
    # ybgc_runtime.cpp, no YARP call), the hold policy with trigger = any, the
    # command line's options. The YARP side of each runs on every release in
    # the harness's other tests: a fixed rate (at 100 Hz in
    # test_stalled_consumer_does_not_stall_the_module), NaN passing
    # (test_nan_passes_by_default), hold with trigger = any
    # (test_event_driven_wakes_on_arrival, test_config_end_to_end[mixed_types_yarp]),
    # --prefix and --timeout (test_producer_killed_and_restarted), --verbose
    # (test_verbose_prints_values_after_conversion).

    test_fixed_rate_50hz_with_nan_passing = on_today_yarp(
        BridgeBehaviour.test_fixed_rate_50hz_with_nan_passing)
    test_fixed_rate_skips_overrun_cycles = on_today_yarp(BridgeBehaviour.test_fixed_rate_skips_overrun_cycles)
    test_hold_policy_and_cli_options = on_today_yarp(BridgeBehaviour.test_hold_policy_and_cli_options)
    test_hold_policy_and_trigger_any = on_today_yarp(BridgeBehaviour.test_hold_policy_and_trigger_any)


# --------------------------------------------------------------------------
# escaping


def parse_cpp_literal(text: str) -> bytes:
    """The bytes of a C++ narrow string literal, by the language's rules
    (octal escapes take up to three digits, hex escapes every hex digit)."""
    assert text.startswith('"') and text.endswith('"'), text
    body = text[1:-1]
    out = bytearray()
    simple = {"n": 10, "t": 9, "r": 13, "\\": 92, '"': 34, "'": 39, "?": 63, "a": 7, "b": 8,
              "f": 12, "v": 11}
    i = 0
    while i < len(body):
        c = body[i]
        if c == '"':
            raise AssertionError(f"unescaped quote in {text}")
        if c != "\\":
            assert 0x20 <= ord(c) < 0x7F, f"raw {c!r} in {text}"
            out.append(ord(c))
            i += 1
            continue
        e = body[i + 1]
        if e in simple:
            out.append(simple[e])
            i += 2
        elif e in "01234567":
            m = re.match(r"[0-7]{1,3}", body[i + 1:])
            out.append(int(m.group(0), 8))
            i += 1 + len(m.group(0))
        elif e == "x":
            m = re.match(r"[0-9a-fA-F]+", body[i + 2:])
            out.append(int(m.group(0), 16))
            i += 2 + len(m.group(0))
        else:
            raise AssertionError(f"unknown escape \\{e} in {text}")
    return bytes(out)


@settings(max_examples=examples(300), deadline=None)
@given(st.text())
def test_string_literal_round_trips(s):
    lit = cpp_string(s)
    assert parse_cpp_literal(lit) == s.encode("utf-8", "surrogatepass")
    assert "??" not in lit  # no trigraph-like sequence
    assert "\n" not in lit and "\r" not in lit
    assert all(0x20 <= ord(c) < 0x7F for c in lit)
    std = cpp_std_string(s)
    if "\0" in s:
        assert std == f"std::string({lit}, {len(s.encode('utf-8', 'surrogatepass'))})"
    else:
        assert std == lit


def test_string_literal_cases():
    assert cpp_string('a"b') == r'"a\"b"'
    assert cpp_string("a\\b") == r'"a\\b"'
    assert cpp_string("l1\nl2") == r'"l1\nl2"'
    assert cpp_string("*/") == '"*/"'
    assert cpp_string("??=") == r'"?\?="'
    assert cpp_string("???") == r'"?\?\?"'
    assert cpp_string("é1") == r'"\303\2511"'  # three digits: the 1 is not part of the escape
    assert cpp_string("\0") == r'"\000"'
    assert cpp_std_string("a\0b") == r'std::string("a\000b", 3)'
    assert cpp_string("\ud800") == r'"\355\240\200"'  # lone surrogate: still a literal
    # a comment never ends with a backslash (line splice) nor holds a line break
    for text in ("end\\", "a\nb", "??/", "*/"):
        c = cpp_comment(text)
        assert not c.endswith("\\") and "\n" not in c and "??" not in c


def test_identifiers():
    for word in ("class", "int", "and", "namespace", "main", "override", "NULL"):
        assert word in CPP_KEYWORDS
        with pytest.raises(ValueError):
            cpp_identifier(word)
    for bad in ("", "1x", "a-b", "a b", "__x", "a__b", "_Upper", "é"):
        with pytest.raises(ValueError):
            cpp_identifier(bad)
    assert cpp_identifier("arm") == "arm"
    assert cpp_identifier("_lower") == "_lower"
    assert mangle("mux_", "class") == "mux_class"
    assert mangle("mux_", "a__b") == "mux_a_b"
    assert mangle("mux_", "x-y z") == "mux_x_y_z"


@settings(max_examples=examples(300), deadline=None)
@given(st.floats(allow_nan=False, allow_infinity=False))
def test_float_literals_are_exact(x):
    text = cpp_float(x)
    assert float(text) == x and math.copysign(1, float(text)) == math.copysign(1, x)
    assert "." in text or "e" in text


def test_numeric_literals():
    assert cpp_float(float("inf")) == "std::numeric_limits<double>::infinity()"
    assert cpp_float(float("-inf")) == "-std::numeric_limits<double>::infinity()"
    assert cpp_float(1.0) == "1.0"
    assert cpp_float(DEG) == "0.017453292519943295"
    assert cpp_int(-2 ** 63) == "(-9223372036854775807 - 1)"
    assert cpp_int(4000000000, 32) == "-294967296"  # wraps like the cast to int32
    assert cpp_int(255, 8) == "-1"
    with pytest.raises(TypeError):
        cpp_int(True)


def test_wire_tables_cover_every_element_type():
    assert set(WIRE_YARP) == set(WIRE_ROS1) == set(ir.BOTTLE_ELEMENT_TYPES)
    assert WIRE_YARP["uint32"] == "Int64" and WIRE_ROS1["uint32"] == "Int32"
    assert WIRE_ROS1["float32"] == "Float32" and WIRE_ROS1["bool"] == "Int8"


# --------------------------------------------------------------------------
# generation


def test_backend_registered():
    b = get_backend("cpp")
    assert isinstance(b, CppBackend)
    assert b.output_kinds == {"yarp", "ros1", "ros2"} and b.input_kinds == {"yarp", "ros1", "ros2"}


def render(program) -> dict[str, str]:
    return CppBackend().render(program)


def test_generated_text_is_deterministic_and_marked():
    program = escape_program()
    files = render(program)
    assert files == render(escape_program())
    code = ("import sys, json; sys.path.insert(0, %r); from harness.programs import escape_program; "
            "from ybg.backends import get_backend; print(json.dumps(get_backend('cpp').render(escape_program())))"
            % str(Path(__file__).parent))
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env={**os.environ, "PYTHONHASHSEED": "12345", "PYTHONPATH": str(ROOT)}, check=True)
    assert json.loads(other.stdout) == files
    cpp = files["escape_bridge.cpp"]
    assert re.search(r"generated by ybgc [0-9.]+ from", cpp.splitlines()[0])
    assert "generated by ybgc from" in files["CMakeLists.txt"].splitlines()[0]
    for region in ("includes", "state", "compute", "message"):
        assert cpp.count(f"// ybgc:user-begin {region}\n") == 1
        assert cpp.count(f"// ybgc:user-end {region}\n") == 1
    assert all(ord(c) < 0x80 for c in cpp)  # every config string is escaped
    assert "mux_class" in cpp and "mux_a_b" in cpp and "mux_Upper" in cpp


def test_user_code_is_kept_on_regeneration(tmp_path):
    from ybg.writer import write_files
    program = relay_program()
    write_files(tmp_path, render(program))
    path = tmp_path / "relay_bridge.cpp"
    text = path.read_text()
    path.write_text(text.replace("    // ybgc:user-begin compute\n",
                                 "    // ybgc:user-begin compute\n    mux.data.clear();\n"))
    write_files(tmp_path, render(program))
    assert "    // ybgc:user-begin compute\n    mux.data.clear();\n" in path.read_text()


def test_unsupported_programs_are_refused():
    base = relay_program()
    with pytest.raises(LoweringError):
        render(Program(module="x", source="x.ini", muxes=base.muxes, message=base.message,
                       output=Output("ros2", "/t")))
    with pytest.raises(LoweringError, match="no message type"):  # a ROS 2 input needs its type
        render(Program(module="x", source="x.ini", muxes=(Mux("m", (Input("/t", kind="ros2"),)),),
                       message=base.message, output=base.output))
    with pytest.raises(LoweringError):
        render(Program(module="x", source="x.ini", muxes=base.muxes,
                       message=Struct((Field("h", Default(), TypeRef("std_msgs/Header")),)),
                       output=base.output))


def test_ros1_input_fields_are_found_by_path():
    cpp = render(ros1_input_program())["typed_ros_input.cpp"]
    assert '{{"point.x", {1, 0}}, {"point.y", {1, 1}}, {"point.z", {1, 2}}}' in cpp



# --------------------------------------------------------------------------
# building


# the first of these builds every module of the session (two jobs, about two
# minutes on a quiet machine): more time than a single test gets
@pytest.mark.timeout(900)
@pytest.mark.parametrize("key", sorted(build_programs()))
def test_builds_with_werror(builds, key):
    if builds.refused(key):
        # YARP 4 has no ROS 1: the module's CMakeLists says so, with the fix
        r = builds.configure_alone(key)
        said = " ".join(r.stderr.split())  # CMake wraps its messages
        assert r.returncode != 0
        assert "removed in YARP 4.0" in said and "`via = ros2`" in said, r.stderr[-2000:]
        return
    exe = builds.exe(key)
    assert os.access(exe, os.X_OK)


def test_modules_of_one_project_build_the_runtime_once(builds):
    """Every module of the session is a folder added to one CMake project: each
    part of the runtime library (its core, its ROS 2 side) is compiled once, for
    all of them, as one translation unit (its sources together: YARP's headers
    read once). The project adds the runtime's own folder first
    (``runtime_folder()``); each module's folder defines the same libraries
    unless defined, so a module's CMakeLists that defined them again would
    fail to configure."""
    builds.exe("relay_bridge")
    assert f"add_subdirectory({RUNTIME_FOLDER} EXCLUDE_FROM_ALL)" in (builds.root / "src" / "CMakeLists.txt").read_text()
    for part in ("runtime", "ros2"):
        compiled = re.findall(rf"Building CXX object (\S*/{runtime_library(part)}\.dir/\S+)", builds.log)
        assert len(compiled) == 1, (part, compiled)
        assert "/Unity/" in compiled[0], compiled
    folder = (builds.root / "src" / "relay_bridge" / "CMakeLists.txt").read_text()
    assert f"if(NOT TARGET {runtime_library()})" in folder
    assert len(builds.programs) > 10
    assert sum(p.output.kind == "ros2" for p in builds.programs.values()) > 5


def test_install_rule(builds, tmp_path):
    builds.exe("relay_bridge")
    r = subprocess.run(["cmake", "--install", str(builds.root / "build" / "relay_bridge"), "--prefix", str(tmp_path)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    assert os.access(tmp_path / "bin" / "relay_bridge", os.X_OK)


# --------------------------------------------------------------------------
# ROS 2 through rcl: the native module and the rclpy node are the same bridge


def diff_values(rng: random.Random) -> list:
    """One Bottle of /diff/battery:o: float64 x4 (float32 fields too, so within
    float32's range, with NaN, -0.0, tiny and large values), uint8 x2, bool."""
    reals = [rng.choice([rng.uniform(-1e6, 1e6), rng.uniform(-1, 1) * 1e-30, -0.0, math.nan,
                         float(rng.randint(-5, 5)), 3.0e38, 1e-45]) for _ in range(4)]
    return reals + [rng.randint(0, 255), rng.randint(0, 255), rng.random() < 0.5]


# The ROS 2 side of the native module (its messages, bit for bit, use_sim_time)
# on today's YARP, as test_backend_ros2_node's: it depends on no YARP release (as
# tests/test_cpp_ros2_qos.py); how each release's Bottles are read into a ROS 2
# message is TestCppBehaviour::test_config_end_to_end of every config that
# publishes to ROS 2 (vizzy_rviz_joint_states, imu_ros2 ...), on every release.
@pytest.mark.yarp_min((4, 0))
def test_ros2_output_publishes_what_the_ros2_node_publishes(builds, yarp_server, ros2_domain, tmp_path):
    """The same YARP stream (values and envelopes) through the native module
    and the rclpy node of --backend ros2: the same messages, bit for bit
    (float32 rounding, integer and bool fields, strings, constants, stamps
    from the envelope); SIGINT ends the native module with 0 within 2 s."""
    rng = random.Random(14)
    rounds = 25
    with Differential(builds, "diff_native", ros2_environment(yarp_server.env, ros2_domain), tmp_path) as diff:
        for k in range(rounds):
            diff.round(k, {"/diff/battery:o": diff_values(rng)}, rng)
        msgs = diff.messages(rounds)
    assert len({json.dumps(m["cell_voltage"]) for m in msgs}) > rounds // 2  # not a constant
    assert msgs[0]["location"] == "left" and msgs[0]["header"]["frame_id"] == 'bat "q" ; #'


# the message trees on today's YARP, as test_backend_ros2_node's differential: how
# each release's Bottles are read is the harness's, on every release
@pytest.mark.yarp_min((4, 0))
def test_ros2_output_arrays_of_messages_as_the_ros2_node(builds, yarp_server, ros2_domain, tmp_path):
    """Arrays of messages, the same bit for bit through the native module and
    the rclpy node: a tf2_msgs/TFMessage of two transforms from two muxes
    with geometry converters and an expression (diff_tf), and the nested
    visualization_msgs/MarkerArray of examples/ball_markers_ros2.ini (a
    marker's points, one filled from a mux); the message is kept and filled
    again: every round's values, none stale, the unset fields' defaults."""
    rng = random.Random(1414)
    rounds = 12
    env = ros2_environment(yarp_server.env, ros2_domain)

    def reals(n: int, scale: float) -> list:
        return [rng.choice([rng.uniform(-scale, scale), -0.0, float(rng.randint(-3, 3)), 1e-40])
                for _ in range(n)]

    with Differential(builds, "diff_tf", env, tmp_path / "tf") as diff:
        for k in range(rounds):
            axis = [rng.uniform(-1, 1) for _ in range(3)]
            diff.round(k, {"/diff/hand:o": reals(3, 2.0) + [rng.uniform(-180, 180) for _ in range(3)],
                           "/diff/tool:o": reals(3, 5.0) + axis + [rng.uniform(-math.pi, math.pi)]}, rng)
        tf = diff.messages(rounds)
    assert [[t["child_frame_id"] for t in m["transforms"]] for m in tf] == [["r_hand", "r_tool"]] * rounds
    rotations = {json.dumps(m["transforms"][1]["transform"]["rotation"]) for m in tf}
    assert len(rotations) == rounds  # each round's own, converted
    # unset: the default (floats as their bits)
    assert all(m["transforms"][1]["transform"]["translation"]["y"] == (0.0).hex() for m in tf)

    with Differential(builds, "ball_markers_ros2", env, tmp_path / "markers") as diff:
        for k in range(rounds):
            diff.round(k, {"/pf3dTracker/data:o": reals(3, 5000.0)}, rng)
        markers = diff.messages(rounds)
    assert all(len(m["markers"]) == 2 and len(m["markers"][1]["points"]) == 2 for m in markers)
    assert len({json.dumps(m["markers"][1]["points"][1]) for m in markers}) == rounds
    assert markers[-1]["markers"][1]["points"][0]["y"] == (0.0).hex()
    assert markers[-1]["markers"][0]["pose"]["orientation"]["w"] == (1.0).hex()


@pytest.mark.yarp_min((4, 0))  # the ROS 2 side, as above
def test_ros2_output_use_sim_time_stamps_with_the_clock_topic(builds, yarp_server, ros2_domain):
    """`--ros-args -p use_sim_time:=true`, as for every ROS 2 node: the stamps
    are the simulated time of /clock; the module's own options still work
    after `--`."""
    program = builds.programs["vizzy_rviz_joint_states"]
    env = ros2_environment(yarp_server.env, ros2_domain)
    clock = Ros2Publisher(env, "/clock", "rosgraph_msgs/msg/Clock",
                          messages=[{"clock": {"sec": 4242, "nanosec": 500}}], rate=50)
    sub = subscriber_for(env, program)
    module = Module([builds.exe("vizzy_rviz_joint_states"), "--ros-args", "-p", "use_sim_time:=true", "--",
                     "--rate", "20"], env=env, name="vizzy_sim_time")
    producers = [YarpProducer(env, "/vizzy/torso/state:o", bottles=[[10.0]], rate=20),
                 YarpProducer(env, "/vizzy/left_shoulder_arm/state:o", bottles=[[float(k) for k in range(8)]],
                              rate=20)]
    procs = [clock, sub, module, *producers]
    try:
        for p in procs:
            p.start()
        module.wait_log("use_sim_time: stamps from /clock")
        module.wait_log("20 Hz")
        clock.wait_matched(1, timeout=60)
        sim = {"sec": 4242, "nanosec": 500}
        first = sub.wait_after(0.0, pred=lambda m: m.msg["header"]["stamp"] == sim)
        got = sub.wait_for(sub.messages.index(first) + 4)
        # simulated time from the start: 0 until the first /clock message, never the wall clock
        stamps = [m.msg["header"]["stamp"] for m in got]
        k = stamps.index(sim)
        assert set(map(str, stamps[:k])) <= {str({"sec": 0, "nanosec": 0})} and stamps[k:] == [sim] * len(stamps[k:])
        assert first.msg["position"][0] == 10.0 * DEG
        rc, elapsed = module.interrupt(signal.SIGINT)
        assert rc == 0 and elapsed < EXIT_BOUND, module.log_text()[-2000:]
    finally:
        for p in reversed(procs):
            p.stop()


def test_ros2_output_refuses_what_the_c_struct_builder_cannot_fill():
    """A field type without a C conversion (wstring), an array of messages of
    another type than its field's or with more elements than its bound are
    lowering errors at their place, never C++ that does not compile; an input
    that is a ROS 2 topic is read on the publisher's node
    (tests/test_cpp_ros2_inputs.py)."""
    def program(field: Field, inputs=(Input("/value:o"),)) -> Program:
        return Program(module="label", source="label.ini", muxes=(Mux("m", inputs),),
                       message=Struct((field,), "my_msgs/Label"), output=Output("ros2", "/label", "my_msgs/Label"),
                       ros="ros2", distro="jazzy")

    text, corners = Span(7, 1, 7, 11), Span(9, 1, 9, 20)  # where a config would write them
    with pytest.raises(LoweringError) as e:
        CppBackend().lower(program(Field("text", MuxRef("m", index=0), TypeRef("wstring"), text)))
    assert e.value.span == text and "wstring" in str(e.value)
    topic = Input("/goal", kind="ros2", ros_type="geometry_msgs/PointStamped", fields=("point.x",))
    module = CppBackend().render(program(Field("value", MuxRef("m", index=0), TypeRef("float64")), (topic,)))
    assert "    ybgc::ros2::read(out, msg.point.x);\n" in module["label.cpp"]
    assert "ybgc::ros2::run(bridge::kSpec, bridge::kRos2, bridge::kMessage, bridge::kTopics," in module["label.cpp"]
    files = CppBackend().render(program(Field("value", MuxRef("m", index=0), TypeRef("float64"))))
    assert "ybgc::ros2::set(msg.value, mux.m[0]);" in files["label.cpp"]
    assert "#include <my_msgs/msg/label.h>" in files["label.cpp"]
    # an array of messages of another type than the field's, more elements than a bounded field holds
    corner = Struct((Field("x", Literal((1.5,), "float64"), TypeRef("float64")),), "my_msgs/Corner")
    with pytest.raises(LoweringError) as e:
        CppBackend().lower(program(Field("corners", ir.MessageArray((corner,), "my_msgs/Other"),
                                         TypeRef("my_msgs/Corner", "sequence"), corners)))
    assert e.value.span == corners
    with pytest.raises(LoweringError) as e:
        CppBackend().lower(program(Field("corners", ir.MessageArray((corner,) * 3, "my_msgs/Corner"),
                                         TypeRef("my_msgs/Corner", "sequence", 2), corners)))
    assert e.value.span == corners and "bounded" in str(e.value)


def test_ros2_output_fills_arrays_of_messages_of_every_kind():
    """An array of messages in the C struct: a sequence (bounded or not) sized
    to the config's elements with its package's functions, a fixed-size array
    as it is (its elements are in the struct); the elements' fields by their
    path, an element filled from a mux, a nested message left unset one
    comment; the elements' header included and their package linked."""
    corner = Struct((Field("x", MuxRef("m", index=1), TypeRef("float64")),
                     Field("at", Struct((Field("sec", Default(), TypeRef("int32")),), "builtin_interfaces/Time"),
                           TypeRef("builtin_interfaces/Time"))), "my_msgs/Corner")
    filled = MuxRef("m", 0, 2, into_fields=("x", "at.sec"), into_types=("float64", "int32"))
    fields = (Field("path", ir.MessageArray((corner, filled), "my_msgs/Corner"),
                    TypeRef("my_msgs/Corner", "sequence", 4)),
              Field("box", ir.MessageArray((corner,) * 2, "my_msgs/Corner"), TypeRef("my_msgs/Corner", "fixed", 2)),
              Field("none", ir.MessageArray((), "my_msgs/Corner"), TypeRef("my_msgs/Corner", "sequence")))
    program = Program(module="shape", source="shape.ini", muxes=(Mux("m", (Input("/value:o"),)),),
                      message=Struct(fields, "my_msgs/Shape"), output=Output("ros2", "/shape", "my_msgs/Shape"),
                      ros="ros2", distro="jazzy")
    files = CppBackend().render(program)
    builder = files["shape.cpp"].split("bool buildMessage", 1)[1].split("// ybgc:user-begin message", 1)[0]
    body = [line.strip() for line in builder.splitlines()]
    assert body[body.index("// path (my_msgs/Corner[<=4]): 2 elements"):][:9] == [
        "// path (my_msgs/Corner[<=4]): 2 elements",
        "ybgc::ros2::resize(msg.path, 2, &my_msgs__msg__Corner__Sequence__init,",
        "&my_msgs__msg__Corner__Sequence__fini);",
        "// path[0].x (float64)",
        "ybgc::ros2::set(msg.path.data[0].x, mux.m[1]);",
        "// path[0].at (builtin_interfaces/Time): the definition's defaults",
        "// path[1] (my_msgs/Corner)",
        "ybgc::ros2::set(msg.path.data[1].x, mux.m[0]);",
        "ybgc::ros2::set(msg.path.data[1].at.sec, mux.m[1]);",
    ]
    assert "// box (my_msgs/Corner[2]): 2 elements" in body and "ybgc::ros2::set(msg.box[1].x, mux.m[1]);" in body
    assert not any("resize(msg.box" in line for line in body)
    assert "ybgc::ros2::resize(msg.none, 0, &my_msgs__msg__Corner__Sequence__init," in body
    assert "#include <my_msgs/msg/corner.h>" in files["shape.cpp"]
    # the message package linked: its C type support found by the CMakeLists' ROS 2 macro
    linked = re.search(rf"^{ROS2_LINK}\(shape (.*)\)$", files["CMakeLists.txt"], re.M)[1].split()
    assert "my_msgs" in linked, linked
