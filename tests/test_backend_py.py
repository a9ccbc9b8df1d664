"""The ``py`` backend: generated Python modules, run as scripts by the venv's
Python against real YARP (and ROS 1).

What a module does is tested once for every backend by the harness
(tests/harness/behaviour.py): ``TestPyBehaviour`` says how a Python module
is started. The rest of this file is the Python backend's own: imports,
escaping, the module imported and its data, the float64 fast path of the
runtime, lowering errors (its golden files, and every supported config's:
tests/test_golden.py).
"""
from __future__ import annotations

import ast
import json
import re
import subprocess
import sys

import pytest

from harness.behaviour import BridgeBehaviour, ModuleCommandLine
from harness.behaviour_ros1 import Ros1Behaviour
from harness.env import VENV_PYTHON
from harness.generated import load_module, module_file
from harness.launchers import PyModules, write_module
from harness.programs import DEG, PY_EVIL as EVIL, PY_GOLDEN_PROGRAMS as GOLDEN_PROGRAMS, simple_program, \
    supported_configs
from harness.programs import py_escape_program as escape_program
from harness.yarp import require_yarp
import ybg
from ybg.backends import RenderOptions, get_backend
from ybg.backends.py import PyBackend
from ybg.backends.py.lower import LoweringError, py_literal
from ybg.compiler.pipeline import compile_text
from ybg.compiler.ir import (Converter, Counter, Default, Field, Input, Literal, Mux, MuxRef, Output, Program,
                             Struct, Timestamp, TypeRef)

# on YARP 3.5 and 4.0.0: 3.12.3 is the version tests' (docs/yarp-versions.md)
pytestmark = pytest.mark.yarp_ends


# --------------------------------------------------------------------------
# a program of this backend's own tests (the harness's, and those of its golden
# files: tests/harness/programs.py)


def jointstate(module="thesis_figure5_rviz", names=None, frame="0"):
    """The thesis' figure 5: one arm in degrees -> sensor_msgs/JointState on ROS 1."""
    names = names or ("l_shoulder_scapula_joint", "l_shoulder_flection_joint",
                      "l_shoulder_abduction_joint", "l_shoulder_rotation_joint",
                      "l_elbow_flection_joint", "l_forearm_pronation_joint",
                      "l_wrist_abduction_joint", "l_wrist_flection_joint")
    return Program(
        module=module, source=f"{module}.ini",
        muxes=(Mux("mux1", (Input("/vizzySim/left_shoulder_arm/state:o"),),
                   (Converter("deg_to_rad", scale=DEG),), verbose=True),),
        message=Struct((
            Field("header", Struct((
                Field("seq", Counter("uint32"), TypeRef("uint32")),
                Field("stamp", Timestamp(), TypeRef("time")),
                Field("frame_id", Literal((frame,), "string"), TypeRef("string")),
            ), "std_msgs/Header"), TypeRef("std_msgs/Header")),
            Field("name", Literal(tuple(names), "string", True), TypeRef("string", "sequence")),
            Field("position", MuxRef("mux1"), TypeRef("float64", "sequence")),
            Field("velocity", Literal((), "float64", True), TypeRef("float64", "sequence")),
            Field("effort", Default(), TypeRef("float64", "sequence")),
        ), "sensor_msgs/JointState"),
        output=Output("ros1", "/yarp/joint_states", "sensor_msgs/JointState",
                      node=f"/yarp/{module}"),
        ros="ros1", distro="noetic")


# --------------------------------------------------------------------------
# helpers


def render(program) -> tuple[str, str]:
    """The module's file (name, text), without the runtime beside it."""
    return module_file(PyBackend().render(program), ".py")


# --------------------------------------------------------------------------
# the behaviour harness on the Python module (its Launcher: harness/launchers.py)


class TestPyBehaviour(BridgeBehaviour, Ros1Behaviour, ModuleCommandLine):
    backend = "py"
    help_options = ("--name P", "--prefix P", "--rate HZ", "--timeout S", "--verbose", "--from FILE", "--context CTX",
                    "--help")

    @pytest.fixture
    def modules(self, tmp_path) -> PyModules:
        require_yarp()
        return PyModules(tmp_path)


# --------------------------------------------------------------------------
# generation (no middleware)


def test_backend_registered():
    backend = get_backend("py")
    assert isinstance(backend, PyBackend)
    assert backend.output_kinds == {"yarp", "ros1"}
    assert backend.input_kinds == {"yarp", "ros1"}


def _imported(text: str) -> set[str]:
    imported = set()
    for node in ast.walk(ast.parse(text)):
        if isinstance(node, ast.Import):
            imported.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            imported.add(node.module.split(".")[0])
    return imported


@pytest.mark.parametrize("stem", sorted(GOLDEN_PROGRAMS))
def test_module_needs_only_yarp_and_its_runtime(stem):
    """The module imports the runtime beside it and nothing else outside
    the standard library; with --single-file, only yarp."""
    program = GOLDEN_PROGRAMS[stem]()
    name, text = render(program)
    first = text.splitlines()[0]
    assert re.match(r"# Generated by ybgc [0-9.]+ from ", first)
    assert _imported(text) - set(sys.stdlib_module_names) == {"ybgc_runtime"}
    single_files = PyBackend().render(program, RenderOptions(single_file=True))
    assert sorted(single_files) == sorted([name, f"{program.module}.xml"])  # and its yarpmanager application
    single_name, single = name, single_files[name]
    assert single_name == name
    assert _imported(single) - set(sys.stdlib_module_names) == {"yarp"}
    for block in ("imports", "setup", "compute"):
        assert f"# ybgc:user-begin {block}\n" in text
        assert f"# ybgc:user-end {block}\n" in text
    assert text.count("ybgc:user-begin") == text.count("ybgc:user-end") == 3


def test_escaping_is_one_function():
    # repr based: every string evaluates back to itself, on one line
    for s in (EVIL, "", "\n", "\\", "'''", '"""', "\x00", "\ud800", "a\rb"):
        lit = py_literal(s)
        assert "\n" not in lit and "\r" not in lit
        assert ast.literal_eval(lit) == s
    assert ast.literal_eval(py_literal((1, 2.5, "x", None, True))) == (1, 2.5, "x", None, True)
    assert py_literal(float("nan")) == "float('nan')"
    assert py_literal(DEG) == repr(DEG)
    _, text = render(escape_program())
    assert text.splitlines()[0] == (f"# Generated by ybgc {ybg.__version__} from " + py_literal("we'ird \"name\"\n# ''' ü.ini")
                                    + "; do not edit except inside the user blocks.")
    # nothing of the config pasted: no value broke a line
    assert not any(line.lstrip().startswith("new line */") for line in text.splitlines())
    assert text.count(py_literal(EVIL)) == 3  # field name, value, list item


def test_generated_module_imports_and_exposes_its_data(tmp_path):
    require_yarp()
    path = write_module(escape_program(), tmp_path)
    mod, runtime = load_module(path, "escape_bridge_mod")  # runs nothing: main() only under __main__
    assert mod.SPEC.config == "we'ird \"name\"\n# ''' ü.ini"
    ctx = runtime["core"].Context({"m": [1.0, 2.0]}, 0, {"m": None})
    msg = mod.build_message(ctx)
    assert msg.fields[0][0] == EVIL and msg.fields[0][1].value == EVIL
    assert msg.fields[1][1].values == (EVIL, "", "'", '"', "\\")


PARSE_CHECK = r"""
import importlib.util, json, math, sys, time
import yarp
import os
sys.path.insert(0, os.path.dirname(os.path.abspath(sys.argv[1])))  # the runtime beside the module
from ybgc_runtime.yarp_inputs import parse_bottle
yarp.Network.init()
out, inp = yarp.BufferedPortBottle(), yarp.BufferedPortBottle()
inp.setStrict(True)
assert out.open("/test/parse:o") and inp.open("/test/parse:i")
assert yarp.Network.connect("/test/parse:o", "/test/parse:i")
cases = [[1.5, -2.25, 1e300, float("nan"), 0.0], [1.5, 2, 3.5], [],
         [0.1, -0.0, 5e-324, float("inf"), -float("inf"), 1.7976931348623157e308, 1 / 3]
         + [k * 0.7318 - 17.2 for k in range(50)]]
report = []
for values in cases:
    b = out.prepare()
    b.clear()
    for x in values:
        if isinstance(x, int):
            b.addInt32(x)
        else:
            b.addFloat64(x)
    out.write(True)
    got = inp.read(True)
    row = {"special": got.getSpecialization()}
    for types in (None, ("float64",) * len(values), ("float32",) * 3):
        # repr of the list: the exact value of every float
        for drop_nan in (False, True):
            fast = parse_bottle(got, types, False, drop_nan, None, True)
            slow = parse_bottle(got, types, False, drop_nan, None, False)
            row.setdefault("pairs", []).append([repr(fast), repr(slow)])
    report.append(row)
print("report " + json.dumps(report), flush=True)
print("float64 " + json.dumps(yarp.BOTTLE_TAG_FLOAT64), flush=True)
out.close(); inp.close()
"""


def test_float64_fast_path_reads_what_the_checked_path_reads(yarp, yarp_server, tmp_path):
    """A Bottle read from the network whose items are all float64 is taken
    whole (no per-element type checks); whatever the Bottle, the result and
    the reason for a drop are those of the checked path."""
    path = write_module(simple_program("parse_bridge"), tmp_path)
    script = tmp_path / "parse_check.py"
    script.write_text(PARSE_CHECK, encoding="utf-8")
    r = subprocess.run([VENV_PYTHON, str(script), str(path)], env=yarp_server.env,
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr[-3000:]
    line, = [l for l in r.stdout.splitlines() if l.startswith("report ")]
    report = json.loads(line[len("report "):])
    tag, = [json.loads(l.split()[1]) for l in r.stdout.splitlines() if l.startswith("float64 ")]
    assert tag == (20 if yarp.key >= (4,) else 10)  # YARP 4 changed the tags
    assert [row["special"] for row in report] == [tag, 0, 0, tag]  # all float64: the fast path
    for row in report:
        for fast, slow in row["pairs"]:
            assert fast == slow  # repr: every bit of every float (-0.0, 5e-324, inf)
    assert "element 3 is NaN" in report[0]["pairs"][1][0]  # drop_nan: the same reason



def test_unsupported_output_is_refused():
    program = simple_program("ros2_out")
    program = Program(program.module, program.source, program.muxes, program.message,
                      Output("ros2", "/topic", "std_msgs/Float64MultiArray"))
    with pytest.raises(LoweringError):
        PyBackend().render(program)



def test_queue_setting_reaches_the_module():
    """`queue` in [output] goes into the IR and the generated module."""
    text = "[output]\nport = /q/out:o\nqueue = 1\n\n[mux m]\nports = /q/a:o\n\n[message]\nv = m\n"
    result = compile_text(text, "q.ini")
    assert result.program is not None, result.diagnostics
    assert result.program.timing.queue == 1
    assert compile_text(text.replace("queue = 1\n", ""), "q.ini").program.timing.queue == 64
    _, code = render(result.program)
    assert "    queue=1,\n" in code



# --------------------------------------------------------------------------
# every example and legacy config this backend supports (their golden files:
# tests/test_golden.py)


try:
    SUPPORTED = supported_configs("py")
    COLLECT_ERROR = None
except Exception as e:  # the front end is broken: one failing test says so
    SUPPORTED, COLLECT_ERROR = [], e


def test_configs_found():
    if COLLECT_ERROR is not None:
        pytest.fail(f"compiling the configs failed: {COLLECT_ERROR!r}")
    stems = {p.stem for p in SUPPORTED}
    assert {"thesis_figure5_rviz", "vizzy_upper_body", "rviz_joint_states_ros1",
            "fixation_point_goal"} <= stems


def test_counter_wraps_like_its_ros_type(tmp_path):
    """The counter of a uint32 seq wraps at 2**32 and goes out as YARP's
    int32 tag on a ROS 1 output, as the C++ module casts it."""
    require_yarp()
    import yarp
    path = write_module(jointstate(), tmp_path)
    mod, runtime = load_module(path, "thesis_wrap_mod")
    for counter, seq in ((2**32 + 3, 3), (2**31, -2**31), (7, 7)):
        msg = mod.build_message(runtime["core"].Context({"mux1": [1.0, 2.0]}, counter, {"mux1": None}))
        bottle = runtime["yarp_io"].fill_bottle(yarp.Bottle(), msg, mod.WIRE)
        header = bottle.get(0).asList()
        assert header.get(0).isInt32() and header.get(0).asInt32() == seq
        assert header.get(1).asList().get(0).isInt32()  # time (secs nsecs): uint32 -> int32
        assert bottle.size() == 5 and bottle.get(3).asList().size() == 0
