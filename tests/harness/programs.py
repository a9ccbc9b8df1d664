"""The programs the tests run, in one place: the behaviour harness's (built
by hand from the IR, or compiled from a config's text), each backend's own
(escaping, golden files, the differential tests of the native ROS 2 module),
and the example and legacy configs each backend builds.

    PROGRAMS, ROS1_PROGRAMS   the behaviour tests' programs by key (= module name)
    build_programs()    every program of the session's one C++ build, by key
    supported_configs(backend), config_program(path, backend), text_program(text, name, backend)
    ros2_examples(), ros2_example(stem), yarp_to_ros2_examples(), ros2_to_yarp_examples()
    PY_GOLDEN_PROGRAMS, CPP_GOLDEN_PROGRAMS   the hand-made programs of the golden files
"""
from __future__ import annotations

import functools
import re
import math
from pathlib import Path
from typing import Callable

from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

from harness.env import EXAMPLES, LEGACY_DIR
from ybg.backends import check_result
from ybg.compiler.options import Options
from ybg.compiler.ir import (Converter, Counter, Default, ElementGroup, Field, Input, Literal, Mux,
                             MuxRef, Output, Policy, Program, Seconds, Struct, Timestamp, Timing,
                             TypeRef)
from ybg.compiler.pipeline import compile_path, compile_text

DEG = math.pi / 180.0

#: a string that breaks naive code generation in every way we know of
EVIL = ("q\"uo'te \\back\\slash\\\nnew line */ /* ''' \"\"\" # ; ??= ??/ ??' {{ x }} {% raw %} "
        "\t tab \0 nul ünïcødé 日本語 \u2028 \u202e bidi end\\")
FIXED_STRINGS = (
    EVIL, "", "'", '"', "\\", "*/", "/*", "//", "'''", "#", ";", "??", "???", "??/", "a\\\n",
    "\\x41g", "\\101", "é9", "\x01\x02", "\x7f", "tab\there", "\r\n", "trailing\\",
    "€ünï 日本", "\U0001F600", "0", "\x00", "a\x00b",
)
#: a list literal of strings (each kind of quote and a backslash)
EVIL_LIST = (EVIL, "", "'", '"', "\\")


def hypothesis_strings(n: int = 50) -> list[str]:
    """``n`` distinct strings drawn by hypothesis (derandomized: the same
    on every run), each at most 40 characters of any kind."""
    drawn: list[str] = []

    @settings(max_examples=3 * n, phases=[Phase.generate], database=None, derandomize=True,
              deadline=None, suppress_health_check=list(HealthCheck))
    @given(st.text(max_size=40))
    def collect(s):
        drawn.append(s)

    collect()
    unique = [s for s in dict.fromkeys(drawn) if s not in FIXED_STRINGS]
    return unique[:n]


# --------------------------------------------------------------------------
# the behaviour tests' programs


def values_program() -> Program:
    """Two muxes into an untyped Bottle that uses every kind of source: an
    undeclared mux in degrees and a declared one (int32 x2, float64, string,
    bool) whose producer stamps its envelope. NaN is dropped."""
    return Program(
        module="values_bridge", source="values_bridge.ini",
        muxes=(
            Mux("arm", (Input("/t/arm:o"),), (Converter("deg_to_rad", scale=DEG),)),
            Mux("sens", (Input("/t/sens:o", layout=(ElementGroup("int32", 2), ElementGroup("float64", 1),
                                                    ElementGroup("string", 1), ElementGroup("bool", 1))),),
                (Converter("scale", scale=2.0, offset=1.0, start=2, stop=3),
                 Converter("half", scale=0.5, to_float=False, start=1, stop=2))),
        ),
        message=Struct((
            Field("label", Literal(("hello",), "string")),
            Field("count", Counter("int32")),
            Field("seconds", Seconds()),
            Field("stamp", Timestamp()),
            Field("envelope", Timestamp(clock="envelope", mux="sens")),
            Field("arm", MuxRef("arm")),
            Field("first", MuxRef("arm", index=0)),
            Field("ints", MuxRef("sens", 0, 2, splice=True, element_type="int32")),
            Field("ratio", MuxRef("sens", index=2)),
            Field("name", MuxRef("sens", index=3, element_type="string")),
            Field("flag", MuxRef("sens", index=4, element_type="bool")),
            Field("nested", Struct((
                Field("x", Literal((1.5,), "float64")),
                Field("k", Literal((1, 2, 3), "int64", True)),
                Field("none", Literal((), "float64", True)),
                Field("pt", MuxRef("arm", 0, 3, into_fields=("x", "y", "z"), into_types=("float64",) * 3)),
            ))),
            Field("big", Literal((2 ** 40,), "int64")),
            Field("u32", Literal((4000000000,), "uint32")),
            Field("f32", Literal((0.1,), "float32")),
            Field("none_seq", Default(), TypeRef("float64", "sequence")),
            Field("none_time", Default(), TypeRef("time")),
            Field("none_fixed", Default(), TypeRef("int32", "fixed", 3)),
        )),
        output=Output("yarp", "/values_bridge/out:o"),
        policy=Policy(on_nan="drop"))


def relay_program() -> Program:
    """The least a bridge does: one undeclared input, its elements out."""
    return Program(
        module="relay_bridge", source="relay_bridge.ini",
        muxes=(Mux("data", (Input("/t/src:o"),)),),
        message=Struct((Field("count", Counter("int32")), Field("values", MuxRef("data", splice=True)))),
        output=Output("yarp", "/relay_bridge/out:o"))


def simple_program(module, *, rate=None, trigger="all", layout=None, on_stale="skip",
                   on_nan="pass", timeout=1.0, inputs=("/test/a:o",), envelope=False,
                   big=0, queue=64) -> Program:
    """One mux of ``inputs`` into (counter, values[, envelope time][, padding])."""
    fields = [Field("count", Counter("int32")), Field("values", MuxRef("m"))]
    if envelope:
        fields.append(Field("stamp", Timestamp(clock="envelope", mux="m")))
    if big:
        fields.append(Field("padding", Literal(tuple(float(k) for k in range(big)),
                                               "float64", True)))
    return Program(
        module=module, source=f"{module}.ini",
        muxes=(Mux("m", tuple(Input(n, layout=layout, timeout=timeout) for n in inputs)),),
        message=Struct(tuple(fields)),
        output=Output("yarp", f"/{module}/out:o"),
        timing=Timing(rate=rate, trigger=trigger, queue=queue),
        policy=Policy(on_stale=on_stale, on_nan=on_nan))


def escape_program(strings=FIXED_STRINGS, module="escape_bridge", lists=()) -> Program:
    """Every string as a literal field whose name is the string too (so it
    reaches comments), each of ``lists`` as a list literal, muxes named like
    keywords and reserved names, a config file name that needs escaping.
    Publishes on every tick."""
    return Program(
        module=module, source="we'ird \"name\"\n*/ ''' # ü.ini",
        muxes=(
            Mux("tick", (Input("/t/tick:o"),)),
            Mux("class", (Input("/t/class:o"),), verbose=True),
            Mux("a__b", (Input("/t/ab:o"),)),
            Mux("_Upper", (Input("/t/upper:o"),)),
        ),
        message=Struct(tuple(Field(s, Literal((s,), "string")) for s in strings)
                       + tuple(Field(f"list{k} {v[0]}", Literal(tuple(v), "string", True))
                               for k, v in enumerate(lists))
                       + (Field("tick", MuxRef("tick", splice=True)),)),
        output=Output("yarp", f"/{module}/out:o"))


TYPED_ROS1_INPUT = """\
[module]
name = typed_ros1_input

[output]
port = /typed_ros1_input/out:o

[mux g]
topics = /ybg_goal (geometry_msgs/PointStamped point)
via = ros1

[message]
label = "xyz"
p = g
"""


def typed_ros1_input_program() -> Program:
    """A typed ROS 1 topic read through YARP, from a real config: the point
    of a geometry_msgs/PointStamped (its header is not part of the mux)."""
    result = compile_text(TYPED_ROS1_INPUT, "typed_ros1_input.ini")
    assert result.program is not None, "\n".join(str(d) for d in result.diagnostics)
    return result.program


INDEXED = """\
[module]
name = indexed_bridge

[output]
port = /indexed_bridge/out:o

[mux m]
ports = /test/a:o (float64 x3)

[message]
points[1].x = m[1]
points[0].x = m[0]
points[0].label = "first"
points[1].label = "second"
points[2] = [m]
count = counter
"""


def indexed_program() -> Program:
    """An untyped Bottle with indexed labels: a nested list per index."""
    result = compile_text(INDEXED, "indexed_bridge.ini")
    assert result.program is not None, "\n".join(str(d) for d in result.diagnostics)
    return result.program


#: every program the behaviour tests run, by key (= its module name): a
#: backend that builds ahead (cpp) builds them all
PROGRAMS: dict[str, Callable[[], Program]] = {
    "values_bridge": values_program,
    "relay_bridge": relay_program,
    "indexed_bridge": indexed_program,
    "queue64_bridge": lambda: simple_program("queue64_bridge", inputs=("/test/a:o", "/test/b:o"), queue=64),
    "queue1_bridge": lambda: simple_program("queue1_bridge", inputs=("/test/a:o", "/test/b:o"), queue=1),
    "strict_bridge": lambda: simple_program("strict_bridge", on_nan="drop",
                                            layout=(ElementGroup("int32", 1), ElementGroup("float64", 2))),
    "wake_bridge": lambda: simple_program("wake_bridge", trigger="any", inputs=("/test/a:o", "/test/b:o"),
                                          on_stale="hold"),
    "hold_bridge": lambda: simple_program("hold_bridge", on_stale="hold", timeout=5.0, envelope=True),
    "escape_hypothesis": lambda: escape_program(FIXED_STRINGS + tuple(hypothesis_strings()),
                                                "escape_hypothesis", lists=(EVIL_LIST,)),
}
#: those that read ROS 1 topics through YARP (Ros1Behaviour)
ROS1_PROGRAMS: dict[str, Callable[[], Program]] = {
    "typed_ros1_input": typed_ros1_input_program,
}
#: the module whose timing the tests measure (built optimized, as a user's)
TIMED = "relay_bridge"


# --------------------------------------------------------------------------
# the example and legacy configs


def is_commands(path: Path) -> bool:
    """Is the config at ``path`` one of commands ([service] sections), which
    tests/test_services*.py run, not the stream harness?"""
    return re.search(r"(?m)^\[service ", path.read_text(encoding="utf-8")) is not None


def is_actions(path: Path) -> bool:
    """Is the config at ``path`` one of actions ([action] sections), which
    tests/test_actions.py runs, not the stream harness?"""
    return re.search(r"(?m)^\[action ", path.read_text(encoding="utf-8")) is not None


def is_stream(path: Path) -> bool:
    """Is the config at ``path`` a stream's (neither commands nor actions)?"""
    return not is_commands(path) and not is_actions(path)


def command_examples() -> list[Path]:
    """The examples of commands ([service] sections)."""
    return [p for p in sorted(EXAMPLES.glob("*.ini")) if is_commands(p)]


def command_program(path: Path, backend: str):
    """The Commands of a config of commands, checked for ``backend`` (a
    user's own services from msgpkgs/)."""
    options = Options(msg_path=(str(EXAMPLES.parent / "msgpkgs"),))
    result = check_result(compile_path(path, options), backend)
    assert result.ok, "\n".join(str(d) for d in result.diagnostics)
    return result.program


def config_paths() -> list[Path]:
    """Every example and legacy config of a stream (not of commands or actions)."""
    return [p for p in sorted(EXAMPLES.glob("*.ini")) + sorted(LEGACY_DIR.glob("*.ini")) if is_stream(p)]


@functools.lru_cache(maxsize=None)
def _supported(backend: str) -> tuple[Path, ...]:
    out = []
    for path in config_paths():
        result = check_result(compile_path(path), backend)
        if result.ok:
            out.append(path)
        else:
            codes = {d.code for d in result.errors}
            assert codes == {"E318"}, f"{path}: {[str(d) for d in result.errors]}"
    return tuple(out)


def supported_configs(backend: str) -> list[Path]:
    """The example and legacy configs that ``backend`` builds; any other
    error than "this backend cannot build it" (E318) fails."""
    return list(_supported(backend))


def uses_images(program: Program) -> bool:
    """Does ``program`` bridge camera images (tests/test_images_*.py), not Bottles?"""
    return program.output.image is not None or any(i.image for m in program.muxes for i in m.inputs)


def bottle_configs(backend: str) -> list[Path]:
    """The configs of :func:`supported_configs` that bridge Bottles, which the
    behaviour harness's reference knows (images have tests of their own)."""
    return [p for p in supported_configs(backend) if not uses_images(config_program(p, backend))]


def config_program(path: Path, backend: str) -> Program:
    """The program of the config at ``path``, checked for ``backend``."""
    result = check_result(compile_path(path), backend)
    assert result.program is not None, "\n".join(str(d) for d in result.diagnostics)
    return result.program


def text_program(text: str, name: str, backend: str) -> Program:
    """The program of config ``text`` (named ``name``), checked for ``backend``."""
    result = check_result(compile_text(text, name), backend)
    assert result.ok, [str(d) for d in result.diagnostics]
    return result.program


def needs_ros1(program: Program) -> bool:
    return program.output.kind == "ros1" or any(i.kind == "ros1" for m in program.muxes for i in m.inputs)


@functools.lru_cache(maxsize=None)
def ros2_compiled(path: str) -> Program:
    """The program of the config at ``path``, checked for the ros2 backend."""
    result = check_result(compile_path(path), "ros2")
    assert result.ok, "\n".join(str(d) for d in result.diagnostics)
    return result.program


def _targets_ros2(program: Program) -> bool:
    return program.output.kind == "ros2" or any(
        i.kind == "ros2" for m in program.muxes for i in m.inputs)


@functools.lru_cache(maxsize=None)
def ros2_examples() -> tuple[str, ...]:
    """Stems of the examples that compile for the ros2 backend and involve ROS 2."""
    out = []
    for p in sorted(EXAMPLES.glob("*.ini")):
        if not is_stream(p):
            continue
        result = check_result(compile_path(str(p)), "ros2")
        if result.ok and _targets_ros2(result.program) and not uses_images(result.program):
            out.append(p.stem)
    return tuple(out)


def ros2_example(stem: str) -> Program:
    """The example ``stem``, checked for the ros2 backend."""
    return ros2_compiled(str(EXAMPLES / f"{stem}.ini"))


def yarp_to_ros2_examples():
    return [s for s in ros2_examples() if ros2_example(s).output.kind == "ros2"]


def ros2_to_yarp_examples():
    return [s for s in ros2_examples() if ros2_example(s).output.kind == "yarp"]


# --------------------------------------------------------------------------
# the C++ backend's own programs, and the session's one build


def ros1_input_program() -> Program:
    """A typed ROS 1 topic read through YARP: the point of a
    geometry_msgs/PointStamped (its header is not part of the mux)."""
    return Program(
        module="typed_ros_input", source="typed_ros_input.ini",
        muxes=(Mux("g", (Input("/ybg_goal", kind="ros1", layout=(ElementGroup("float64", 3),),
                               ros_type="geometry_msgs/PointStamped",
                               fields=("point.x", "point.y", "point.z"),
                               positions=((1, 0), (1, 1), (1, 2))),)),),
        message=Struct((Field("label", Literal(("xyz",), "string")), Field("p", MuxRef("g", splice=True)))),
        output=Output("yarp", "/typed_ros_input/out:o"), ros="ros1", distro="noetic")


DIFF_NATIVE = """\
[module]
name = diff_native

[output]
topic = /diff/battery
type = sensor_msgs/BatteryState
via = ros2
depth = 100

[mux b]
ports = /diff/battery:o (float64 x4, uint8 x2, bool x1)
convert = scale(1.5)[0:2], offset(-0.25)[2:3]

[message]
header.stamp = timestamp(b)
header.frame_id = "bat \\"q\\" ; #"
voltage = b[0]
current = b[1]
charge = b[2]
capacity = b[3]
power_supply_status = b[4]
power_supply_health = b[5]
present = b[6]
cell_voltage = b[0:4]
cell_temperature = 1.5, -2, 1e-40
location = "left"
"""


DIFF_TF = """\
[module]
name = diff_tf

[output]
topic = /diff/tf
type = tf2_msgs/TFMessage
via = ros2
depth = 100

[mux hand]
ports = /diff/hand:o (float64 x6)
convert = euler_to_quat(rpy, deg)[3:6]

[mux tool]
ports = /diff/tool:o (float64 x7)
convert = axis_angle_to_quat[3:7], expr(clamp(x, -2, 2) * 0.5)[0:3]

[message]
transforms[0].header.stamp = timestamp(hand)
transforms[0].header.frame_id = "root_link"
transforms[0].child_frame_id = "r_hand"
transforms[0].transform.translation = hand[0:3]
transforms[0].transform.rotation = hand[3:7]
transforms[1].header.stamp = timestamp(tool)
transforms[1].header.frame_id = "r_hand"
transforms[1].child_frame_id = "r_tool"
transforms[1].transform.translation.x = tool[0]
transforms[1].transform.translation.z = tool[2]
transforms[1].transform.rotation = tool[3:7]
"""

#: a ROS 2 output fed by a YARP port and a ROS 2 topic: one node publishes and subscribes
SHARED_NODE = """\
[module]
name = arm_and_goal

[output]
topic = /arm_and_goal/joint_states
type = sensor_msgs/JointState
via = ros2

[mux arm]
ports = /arm/state:o (float64 x3)
convert = deg_to_rad

[mux goal]
topics = /arm_and_goal/goal (geometry_msgs/PointStamped point)
via = ros2

[message]
header.stamp = timestamp(goal)
header.frame_id = "goal"
position = arm
velocity = goal
"""


def shared_node_program() -> Program:
    """SHARED_NODE, for the native module (tests/test_cpp_ros2_inputs.py)."""
    return text_program(SHARED_NODE, "arm_and_goal.ini", "cpp")


def diff_native_program() -> Program:
    """A ROS 2 output of float32, uint8, bool and string fields, for the
    differential test of the native module and the rclpy node."""
    return text_program(DIFF_NATIVE, "diff_native.ini", "cpp")


def diff_tf_program() -> Program:
    """tf2_msgs/TFMessage: two transforms from two muxes, each with a geometry
    converter (Euler angles, an axis-angle to a quaternion), one with an
    expression too."""
    return text_program(DIFF_TF, "diff_tf.ini", "cpp")


#: the programs of the C++ golden files besides the configs
CPP_GOLDEN_PROGRAMS = {
    "values_bridge": values_program,
    "relay_bridge": relay_program,
    "escape_bridge": escape_program,
    "typed_ros_input": ros1_input_program,
}


@functools.lru_cache(maxsize=None)
def build_programs() -> dict:
    """Every program of the session's one C++ build, by key: the behaviour
    harness's, the typed ROS 1 input, the programs of the differential tests
    with ROS 2, every supported config (by its stem)."""
    programs = {key: make for key, make in {**PROGRAMS, **ROS1_PROGRAMS}.items()}
    programs["typed_ros_input"] = ros1_input_program
    programs["diff_native"] = diff_native_program
    programs["diff_tf"] = diff_tf_program
    programs["shared_node"] = shared_node_program
    # tests/test_cpp_ros2_qos.py's
    programs["qos_point"] = lambda: text_program(QOS_CONFIG, "qos_bridge.ini", "cpp")
    programs["qos_reader"] = lambda: text_program(QOS_READER, "qos_reader.ini", "cpp")
    programs["qos_sim"] = lambda: text_program(QOS_SIM_TIME, "sim_reader.ini", "cpp")
    programs["diag_bridge"] = lambda: text_program(DIAGNOSTICS_CONFIG, "diag_bridge.ini", "cpp")
    for path in bottle_configs("cpp"):  # the image modules: tests/test_images_cpp.py's build
        programs[path.stem] = lambda path=path: config_program(path, "cpp")
    return programs


# --------------------------------------------------------------------------
# the Python backend's own programs


#: a string that breaks naive code generation in every way we know of
PY_EVIL = ("q\"uo'te \\back\\slash\\\nnew line */ /* ''' \"\"\" # ; {{ x }} {% raw %} "
        "\t tab ünïcødé 日本語 \u2028 end\\")


def py_values_program(rate=None, trigger="all"):
    """Two muxes (undeclared degrees; declared int32, int32, float64) into an
    untyped Bottle using every kind of source."""
    return Program(
        module="values_bridge", source="values_bridge.ini",
        muxes=(
            Mux("arm", (Input("/test/arm:o"),), (Converter("deg_to_rad", scale=DEG),)),
            Mux("sens", (Input("/test/sens:o", layout=(ElementGroup("int32", 2),
                                                         ElementGroup("float64", 1))),),
                (Converter("scale", scale=2.0, offset=1.0, start=2, stop=3),)),
        ),
        message=Struct((
            Field("label", Literal(("hello",), "string")),
            Field("count", Counter("int32")),
            Field("stamp", Timestamp()),
            Field("seconds", Seconds()),
            Field("arm", MuxRef("arm")),
            Field("first", MuxRef("sens", index=0, element_type="int32")),
            Field("spliced", MuxRef("sens", splice=True)),
            Field("nested", Struct((
                Field("k", Literal((1, 2, 3), "int32", True)),
                Field("pt", MuxRef("arm", 0, 3, into_fields=("x", "y", "z"),
                                   into_types=("float64",) * 3)),
            ))),
            Field("empty", Literal((), "float64", True)),
        )),
        output=Output("yarp", "/values_bridge/out:o"),
        timing=Timing(rate=rate, trigger=trigger))


def py_escape_program():
    """Config strings full of quotes, backslashes, newlines, comment and
    template delimiters and non-ASCII text, in every place a string goes."""
    return Program(
        module="escape_bridge", source="we'ird \"name\"\n# ''' ü.ini",
        muxes=(Mux("m", (Input("/test/esc:o"),)),),
        message=Struct((
            Field(PY_EVIL, Literal((PY_EVIL,), "string")),
            Field("list" + PY_EVIL, Literal((PY_EVIL, "", "'", '"', "\\"), "string", True)),
            Field("values", MuxRef("m")),
        )),
        output=Output("yarp", "/escape_bridge/out:o"))


def legacy_splice_program():
    """The legacy untyped YARP output (to_ros = false): literals then the mux
    elements appended flat, as the tutorial's rpc command `set pos ...`."""
    return Program(
        module="tutorial_rpc", source="tutorial_example_ros_yarp.ini",
        muxes=(Mux("mux1", (Input("/fakebot_motor_control_ros"),), verbose=True),),
        message=Struct((
            Field("1", Literal(("set",), "string")),
            Field("2", Literal(("pos",), "string")),
            Field("3", MuxRef("mux1", splice=True)),
        )),
        output=Output("yarp", "/tutorial_rpc/out:o", connect_to="/fakebot/motor/rpc:i"),
        timing=Timing(rate=60.0))


#: the programs of the Python golden files besides the configs
PY_GOLDEN_PROGRAMS = {
    "values_bridge": py_values_program,
    "escape_bridge": py_escape_program,
    "tutorial_rpc": legacy_splice_program,
    "fixed_rate_hold": lambda: simple_program("fixed_rate_hold", rate=50.0, on_stale="hold",
                                              layout=(ElementGroup("float64", 3),),
                                              on_nan="drop", envelope=True),
}


# --------------------------------------------------------------------------
# the QoS tests' configs (the rclpy node's and the native module's)


QOS_CONFIG = """\
[module]
name = qos_bridge

[output]
topic = /qos/point
type = geometry_msgs/Point

[mux p]
ports = /qos/p:o (float64 x3)

[message]
x = p[0]
y = p[1]
z = p[2]
"""
#: the point the QoS tests' producer writes
QOS_VALUE = {"x": 0.25, "y": -1.5, "z": 3.0}

#: a ROS 2 topic in, a YARP port out
QOS_READER = """\
[module]
name = qos_reader

[output]
port = /qos_reader/out:o

[mux goal]
topics = /qos/goal (geometry_msgs/Point)
via = ros2

[message]
point = goal
"""

#: a ROS 2 output at a fixed rate with two inputs, each on /diagnostics (tests/test_diagnostics.py)
DIAGNOSTICS_CONFIG = """\
[module]
name = diag_bridge

[output]
topic = /diag/point
type = geometry_msgs/Point
rate = 20
on_stale = hold
timeout = 1.5

[mux arm]
ports = /diag/arm:o (float64 x2)

[mux hand]
ports = /diag/hand:o (float64 x1)

[message]
x = arm[0]
y = arm[1]
z = hand[0]
"""

#: a ROS 2 topic in, a YARP port out, with the times of the node's clock
QOS_SIM_TIME = """\
[module]
name = sim_reader

[output]
port = /sim_reader/out:o

[mux goal]
topics = /sim/goal (geometry_msgs/Point)
via = ros2

[message]
point = goal
seconds = time
stamp = timestamp
"""
