"""The ``py`` backend: generated Python modules run against real YARP (and
ROS 1), with real producer and reader processes.

Each behaviour test generates a module from a Program, starts it as a script
with the venv's Python, drives it with producer peers and checks what a
reader peer (or a rospy subscriber) receives, and what the module prints.
"""
from __future__ import annotations

import ast
import json
import importlib.util
import math
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from generated import load_module, module_file, without_runtime, write_generated
from middleware import (ROS1_PYTHON, VENV_PYTHON, Proc, RospySubscriber, YarpProducer, YarpReader,
                        require_yarp)
import ybg
from ybg.backends import RenderOptions, check_result, get_backend
from ybg.backends.py import PyBackend
from ybg.backends.py.lower import LoweringError, py_literal
from ybg.compiler import ir
from ybg.compiler.pipeline import compile_text
from ybg.compiler.ir import (Converter, Counter, Default, ElementGroup, Field, Input, Literal,
                             Mux, MuxRef, Output, Policy, Program, Seconds, Struct, Timestamp,
                             Timing, TypeRef)

GOLDEN = Path(__file__).resolve().parent / "golden" / "py"
DEG = math.pi / 180.0

#: a string that breaks naive code generation in every way we know of
EVIL = ("q\"uo'te \\back\\slash\\\nnew line */ /* ''' \"\"\" # ; {{ x }} {% raw %} "
        "\t tab ünïcødé 日本語 \u2028 end\\")


# --------------------------------------------------------------------------
# programs built by hand (the front end is written concurrently)


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


def values_program(rate=None, trigger="all"):
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


def simple_program(module, *, rate=None, trigger="all", layout=None, on_stale="skip",
                   on_nan="pass", timeout=1.0, inputs=("/test/a:o",), envelope=False,
                   big=0, queue=64):
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


def escape_program():
    """Config strings full of quotes, backslashes, newlines, comment and
    template delimiters and non-ASCII text, in every place a string goes."""
    return Program(
        module="escape_bridge", source="we'ird \"name\"\n# ''' ü.ini",
        muxes=(Mux("m", (Input("/test/esc:o"),)),),
        message=Struct((
            Field(EVIL, Literal((EVIL,), "string")),
            Field("list" + EVIL, Literal((EVIL, "", "'", '"', "\\"), "string", True)),
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


GOLDEN_PROGRAMS = {
    "values_bridge": values_program,
    "escape_bridge": escape_program,
    "tutorial_rpc": legacy_splice_program,
    "fixed_rate_hold": lambda: simple_program("fixed_rate_hold", rate=50.0, on_stale="hold",
                                              layout=(ElementGroup("float64", 3),),
                                              on_nan="drop", envelope=True),
}


# --------------------------------------------------------------------------
# helpers


def render(program) -> tuple[str, str]:
    """The module's file (name, text), without the runtime beside it."""
    return module_file(PyBackend().render(program), ".py")


def write_module(program, folder: Path) -> Path:
    """The module and its runtime written in ``folder``; the module's path."""
    files = PyBackend().render(program)
    write_generated(folder, files)
    return folder / module_file(files, ".py")[0]


class Bridge(Proc):
    """A generated module run as a script by the venv's Python."""

    def __init__(self, env, program, folder, *args, gate_output=False):
        self.path = write_module(program, folder)
        super().__init__([VENV_PYTHON, self.path, *args], env=env, name=program.module,
                         gate_output=gate_output)

    def wait_log(self, text, timeout=60.0, count=1):
        end = time.monotonic() + timeout
        while True:
            log = self.log_text()
            if log.count(text) >= count:
                return log
            if not self.alive:
                raise AssertionError(f"{self.name} exited; log:\n{log[-3000:]}")
            if time.monotonic() > end:
                raise AssertionError(f"no {text!r} in the log of {self.name}:\n{log[-3000:]}")
            time.sleep(0.05)

    def interrupt(self, sig=signal.SIGINT, within=2.0):
        """Send ``sig`` to the module alone; returns (status, seconds to exit)."""
        t0 = time.monotonic()
        os.kill(self.pid, sig)
        try:
            rc = self.popen.wait(within + 3.0)
        except subprocess.TimeoutExpired:
            rc = None
        return rc, time.monotonic() - t0


def module_log_body(log: str) -> str:
    """The module's own lines (without YARP's [INFO] lines)."""
    return "\n".join(l for l in log.splitlines() if not l.startswith("[") or l.startswith("[m"))


def totals(log: str) -> dict:
    """{source: (received, dropped, stale periods)} and 'published' from the exit totals."""
    out = {}
    for m in re.finditer(r"input (\S+): received (\d+), dropped (\d+), stale periods (\d+)", log):
        out[m.group(1)] = tuple(int(x) for x in m.groups()[1:])
    m = re.search(r"published (\d+) messages, skipped (\d+) cycles", log)
    if m:
        out["published"] = int(m.group(1))
        out["skipped"] = int(m.group(2))
    return out


def registered(server, port: str) -> bool:
    r = server.yarp("name", "query", port)
    return r.returncode == 0 and "registration name" in r.stdout and port in r.stdout


def assert_clean_exit(server, bridge, rc, seconds, ports):
    log = bridge.log_text()
    assert rc == 0, f"exit status {rc}; log:\n{log[-3000:]}"
    assert seconds < 2.0, f"took {seconds:.2f} s to exit"
    assert "Traceback" not in log, log[-3000:]
    assert "totals:" in log
    for p in ports:
        assert not registered(server, p), f"{p} still registered after exit"


def start_pipeline(env, program, folder, *args, producers=(), reader_port="/test/reader"):
    """Start the module, its producers and a reader of its output; wait until
    every connection is up."""
    bridge = Bridge(env, program, folder, *args).start()
    prods = [YarpProducer(env, p).start() for p in producers]
    reader = YarpReader(env, reader_port, source=program.output.name).start()
    for p in prods:
        p.wait_outputs(1, timeout=60)
    reader.wait_connected(timeout=60)
    return bridge, prods, reader


# --------------------------------------------------------------------------
# generation (no middleware)


def test_backend_registered():
    backend = get_backend("py")
    assert isinstance(backend, PyBackend)
    assert backend.output_kinds == {"yarp", "ros1"}
    assert backend.input_kinds == {"yarp", "ros1"}


@pytest.mark.parametrize("stem", sorted(GOLDEN_PROGRAMS))
def test_golden_files(stem, update_goldens):
    program = GOLDEN_PROGRAMS[stem]()
    files = PyBackend().render(program)
    assert files == PyBackend().render(program), "output is not deterministic"
    for name, text in without_runtime(files).items():
        path = GOLDEN / stem / name
        if update_goldens or os.environ.get("YBG_UPDATE_GOLDENS") == "1":
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
        assert path.exists(), f"missing golden file {path}; run pytest --update-goldens"
        assert path.read_text(encoding="utf-8") == text, f"{path} differs from the generated file"


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
    (single_name, single), = PyBackend().render(program, RenderOptions(single_file=True)).items()
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
from ybgc_runtime.yarp_io import parse_bottle
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


def test_help_without_a_name_server(tmp_path):
    require_yarp()
    path = write_module(values_program(), tmp_path)
    r = subprocess.run([VENV_PYTHON, path, "--help"], capture_output=True, text=True, timeout=30)
    assert r.returncode == 0, r.stderr
    for opt in ("--prefix", "--rate", "--timeout", "--verbose", "--help"):
        assert opt in r.stdout
    assert "module values_bridge: 2 input(s) in 2 mux(es)" in r.stdout


def test_unsupported_output_is_refused():
    program = simple_program("ros2_out")
    program = Program(program.module, program.source, program.muxes, program.message,
                      Output("ros2", "/topic", "std_msgs/Float64MultiArray"))
    with pytest.raises(LoweringError):
        PyBackend().render(program)


# --------------------------------------------------------------------------
# behaviour against a real yarpserver


def test_values_order_nesting_counter_timestamp(yarp_server, tmp_path):
    env = yarp_server.env
    program = values_program()
    bridge, (arm, sens), reader = start_pipeline(
        env, program, tmp_path, producers=("/test/arm:o", "/test/sens:o"))
    try:
        arm_in = [0.0, 90.0, 180.0, 45.5, 30]
        arm.write(arm_in)
        time.sleep(0.2)
        assert reader.bottles == [], "published before every input had new data (trigger all)"
        sens.write([7, -3, 2.5])
        (got,) = reader.wait_for(1)
        arm.write([1.0, 2.0, 3.0])
        sens.write([8, 9, -0.25])
        got2 = reader.wait_for(2)[1]
    finally:
        rc, seconds = bridge.interrupt(signal.SIGINT)
        for p in (arm, sens, reader):
            p.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds,
                      ["/values_bridge/out:o", "/values_bridge/arm/in0:i", "/values_bridge/sens/in0:i"])

    rad = [x * DEG for x in arm_in]
    label, count, stamp, seconds_, arm_out, first, *rest = got.data
    spliced, nested, empty = rest[:3], rest[3], rest[4]
    assert len(got.data) == 11
    assert label == "hello" and count == 0
    assert len(arm_out) == 5 and all(abs(a - b) <= 1e-12 for a, b in zip(arm_out, rad))
    assert arm_out[1] == pytest.approx(math.pi / 2, abs=1e-12)
    assert arm_out[2] == pytest.approx(math.pi, abs=1e-12)
    assert first == 7
    assert spliced == [7, -3, 2.5 * 2.0 + 1.0]
    assert nested[0] == [1, 2, 3]
    assert nested[1] == pytest.approx(rad[:3], abs=1e-12)
    assert empty == []
    # wire types: docs/runtime.md for an untyped YARP output
    assert got.types[:4] == ["string", "int32", ["int64", "int64"], "float64"]
    assert got.types[4] == ["float64"] * 5
    assert got.types[5:9] == ["int32", "int32", "int32", "float64"]
    assert got.types[9] == [["int32"] * 3, ["float64"] * 3]
    # time stamps within a second of the reader's clock
    assert abs(stamp[0] + stamp[1] / 1e9 - got.t) < 1.0 and 0 <= stamp[1] < 10**9
    assert abs(seconds_ - got.t) < 1.0
    # the counter goes on
    assert got2.data[1] == 1
    assert got2.data[5:9] == [8, 8, 9, -0.25 * 2.0 + 1.0]
    assert got2.data[4] == pytest.approx([DEG, 2 * DEG, 3 * DEG], abs=1e-12)
    log = bridge.log_text()
    assert totals(log)["published"] == 2
    assert totals(log)["/test/arm:o"] == (2, 0, 0)


def test_event_driven_wakes_on_arrival(yarp_server, tmp_path):
    """Event-driven: each arrival is published at once (no polling sleep),
    trigger "any" publishes on one of two inputs."""
    env = yarp_server.env
    program = simple_program("wake_bridge", trigger="any", inputs=("/test/a:o", "/test/b:o"),
                             on_stale="hold")
    bridge, (a, b), reader = start_pipeline(env, program, tmp_path,
                                            producers=("/test/a:o", "/test/b:o"))
    try:
        a.write([1.0])
        time.sleep(0.2)
        assert reader.bottles == [], "published before every input had delivered (hold)"
        b.write([2.0])
        reader.wait_for(1)
        latencies = []
        for k in range(20):
            sent = a.write([float(k)])
            got = reader.wait_for(2 + k)[-1]
            latencies.append(got.t - sent["t"])
            time.sleep(0.02)
        data = [x.data for x in reader.bottles]
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        for p in (a, b, reader):
            p.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds, ["/wake_bridge/out:o"])
    assert data[0] == [0, [1.0, 2.0]]
    # "any": every new Bottle of a alone is published, with b's last values
    assert [d[1] for d in data[1:]] == [[float(k), 2.0] for k in range(20)]
    assert [d[0] for d in data] == list(range(21))
    latencies.sort()
    assert latencies[len(latencies) // 2] < 0.05, latencies


#: the runtime's bound on unread Bottles (docs/runtime.md, "Reading"): a
#: reader more than this far behind skips the oldest unread
BACKLOG = 64


def test_a_burst_within_the_backlog_is_relayed_whole_and_in_order(yarp_server, tmp_path):
    """Inputs are read strictly and queued: bursts of 65 Bottles written back
    to back (as fast as the connection takes them) all come out, in order,
    none overwritten or skipped; the totals say so. Forced: each burst is as
    long as the runtime may ever have to hold (while it handles one Bottle,
    at most 64 are unread), and the next starts once every message of the
    last one is out: the result does not depend on the machine's speed."""
    env = yarp_server.env
    bursts, size = 8, BACKLOG + 1
    n = bursts * size
    program = simple_program("burst_bridge")
    bridge, (producer,), reader = start_pipeline(env, program, tmp_path, producers=("/test/a:o",))
    try:
        for b in range(bursts):
            producer.burst([[float(k)] for k in range(b * size, (b + 1) * size)])
            got = reader.wait_for((b + 1) * size, timeout=60)
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        producer.stop()
        reader.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds, ["/burst_bridge/out:o"])
    assert [b.data for b in got] == [[k, [float(k)]] for k in range(n)]
    assert re.search(rf"input /test/a:o: received {n}, dropped 0, stale periods \d+, unused 0",
                     bridge.log_text())


def test_a_reader_held_up_skips_the_oldest_and_says_so(yarp_server, tmp_path):
    """An input thread more than 64 Bottles behind skips the oldest unread
    Bottles so that it catches up, counts them as unused, and keeps the
    order of what it relays (docs/runtime.md, "Reading").
    Forced: the module's input thread is held up (it blocks printing its
    --verbose values on a held stdout) while the producer writes a burst
    that the module's port accepts whole (strict writes, each acknowledged);
    then it is let go. Exactly the Bottles read before the hold and the
    last 65 come out: the ones in between were more than 64 behind."""
    env = yarp_server.env
    m = 300
    program = simple_program("behind_bridge", timeout=60.0)
    bridge = Bridge(env, program, tmp_path, "--verbose", gate_output=True).start()
    producer = YarpProducer(env, "/test/a:o").start()
    reader = YarpReader(env, "/test/reader", source=program.output.name).start()
    try:
        producer.wait_outputs(1, timeout=60)
        reader.wait_connected(timeout=60)
        bridge.wait_log("connected /test/a:o", timeout=60)
        bridge.hold_output()
        held = 0
        while True:  # one at a time, until the input thread is held printing one
            producer.write([float(held)] + [0.5] * 15)
            held += 1
            k = held
            reader.wait(lambda: len(reader.bottles) >= k or bridge.output_blocked(), 60,
                        f"message {k} or a held stdout")
            if len(reader.bottles) < k:
                bridge.wait_output_blocked()
                break
            assert held < 500, "never blocked on its held stdout"
        n = held + m
        producer.burst([[float(k)] for k in range(held, n)])
        assert bridge.output_blocked() and len(reader.bottles) == held - 1
        bridge.release_output()
        keep = list(range(held)) + list(range(n - BACKLOG - 1, n))
        got = reader.wait_for(len(keep), timeout=60)
        bridge.wait_log("[m] 0: %r\n" % float(n - 1), timeout=60)
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        producer.stop()
        reader.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds, ["/behind_bridge/out:o"])
    assert [b.data[0] for b in got] == list(range(len(keep)))  # the module's counter
    assert [b.data[1][0] for b in got] == [float(k) for k in keep]
    unused = n - len(keep)
    log = bridge.log_text()
    assert re.search(rf"input /test/a:o: received {n}, dropped 0, stale periods \d+, unused {unused}\n",
                     log), log[-1500:]
    assert totals(log)["published"] == len(keep)


def rate_from_counters(bottles, skipped: int, nominal: float) -> tuple:
    """(lowest, highest) rate a fixed-rate module can have had, from the
    message counters (data[0]) and receive times of ``bottles``: between the
    message received soonest after its cycle in the first second and the
    same in the last second (a reader held up by the machine only delays a
    receive time, never advances it), the module published the counter
    difference and skipped at most ``skipped`` cycles."""
    per = max(1, int(nominal))
    def soonest(part):
        return min(part, key=lambda b: b.t - b.data[0] / nominal)
    a, b = soonest(bottles[:per]), soonest(bottles[-per:])
    span = b.t - a.t
    published = b.data[0] - a.data[0]
    return published / span, (published + skipped) / span


def test_fixed_rate_50hz(yarp_server, tmp_path):
    """rate = 50: a true period over 4 s (200 cycles), though the input comes
    at 100 Hz. Forced: the rate is read from the module's message counter
    against the receive times least delayed by the machine, and cycles it
    had to skip (counted in its totals) are allowed for."""
    env = yarp_server.env
    program = simple_program("rate_bridge", rate=50.0)
    stream = YarpProducer(env, "/test/a:o", bottles=[[1.0, 2.0]], rate=100)
    bridge, (), reader = start_pipeline(env, program, tmp_path)
    try:
        stream.start()
        stream.wait_outputs(1, timeout=60)
        first = reader.wait_for(10, timeout=60)[-1]
        reader.wait(lambda: reader.bottles[-1].t - first.t >= 4.0, 60, "4 s of messages")
        got = list(reader.bottles)
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        stream.stop()
        reader.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds, ["/rate_bridge/out:o"])
    counters = [b.data[0] for b in got]
    assert counters == list(range(counters[0], counters[0] + len(got)))
    skipped = totals(bridge.log_text())["skipped"]
    low, high = rate_from_counters(got[10:], skipped, 50.0)
    assert low <= 50.5 and high >= 49.5, (low, high, skipped)


def test_queue_setting_reaches_the_module():
    """`queue` in [output] goes into the IR and the generated module."""
    text = "[output]\nport = /q/out:o\nqueue = 1\n\n[mux m]\nports = /q/a:o\n\n[message]\nv = m\n"
    result = compile_text(text, "q.ini")
    assert result.program is not None, result.diagnostics
    assert result.program.timing.queue == 1
    assert compile_text(text.replace("queue = 1\n", ""), "q.ini").program.timing.queue == 64
    _, code = render(result.program)
    assert "    queue=1,\n" in code


@pytest.mark.parametrize("queue, expected", [(64, [(1, 1), (2, 2)]), (1, [(2, 1)])])
def test_queue_one_keeps_the_newest_bottle_only(yarp_server, tmp_path, queue, expected):
    """Two stamped Bottles on a before any on b: with the default queue both
    are paired with b's Bottles of the same stamps; with `queue = 1` (YARP's
    newest-only reading) the first is replaced before b delivers, and the
    message pairs the newest of a with b's first."""
    env = yarp_server.env
    program = simple_program(f"queue{queue}_bridge", inputs=("/test/a:o", "/test/b:o"), queue=queue)
    bridge, (a, b), reader = start_pipeline(env, program, tmp_path, producers=("/test/a:o", "/test/b:o"))
    try:
        a.write([1.0], stamp=[1, 500.001])
        time.sleep(0.1)  # read one by one, even by a newest-only port
        a.write([2.0], stamp=[2, 500.002])
        time.sleep(0.3)
        b.write([10.0], stamp=[1, 500.001])
        time.sleep(0.1)
        b.write([20.0], stamp=[2, 500.002])
        reader.wait_for(len(expected))
        time.sleep(0.3)
        got = [tuple(int(x) for x in d.data[1]) for d in reader.bottles]
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        for p in (a, b, reader):
            p.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds, [f"/queue{queue}_bridge/out:o"])
    assert [(x, y // 10) for x, y in got] == expected
    unused = re.search(r"input /test/a:o: received 2, dropped 0, stale periods \d+, unused (\d+)",
                       bridge.log_text())
    assert unused and int(unused.group(1)) == (0 if queue > 1 else 1), bridge.log_text()[-800:]


def test_fixed_rate_skips_overrun_cycles(yarp_server, tmp_path):
    """A module held up for a second at 50 Hz skips the cycles it missed and
    counts them; it does not catch up with a burst, and goes on afterwards.
    Forced: the module is stopped (SIGSTOP, as a machine under load would)
    for a time the test measures, d. The cycles missed (50 d, less the one
    it may publish late) must be counted as skipped, and published + skipped
    can never exceed the cycles of its life: a catch-up burst fails one or
    the other, whatever the machine's speed (other overruns only add skips)."""
    env = yarp_server.env
    program = simple_program("skip_bridge", rate=50.0)
    bridge, (), reader = start_pipeline(env, program, tmp_path)
    stream = YarpProducer(env, "/test/a:o", bottles=[[1.0]], rate=100, wait_connected=True)
    try:
        stream.start()
        reader.wait_for(10, timeout=60)
        first_write = stream.sent[0]["t"]  # no message before the first Bottle
        os.kill(bridge.pid, signal.SIGSTOP)
        t0 = time.monotonic()
        time.sleep(1.0)
        d = time.monotonic() - t0
        os.kill(bridge.pid, signal.SIGCONT)
        reader.wait_for(len(reader.bottles) + 50, timeout=60)  # it goes on
    finally:
        os.kill(bridge.pid, signal.SIGCONT)
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        end = time.time()
        stream.stop()
        reader.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds, ["/skip_bridge/out:o"])
    t = totals(bridge.log_text())
    assert t["skipped"] >= 50 * d - 2, (t, d)
    assert t["published"] + t["skipped"] <= 50 * (end - first_write) + 2, (t, end - first_write)


def test_producer_never_starts(yarp_server, tmp_path):
    env = yarp_server.env
    program = simple_program("lonely_bridge", rate=20.0)
    bridge = Bridge(env, program, tmp_path).start()
    reader = YarpReader(env, "/test/reader", source="/lonely_bridge/out:o").start()
    try:
        reader.wait_connected(timeout=60)
        bridge.wait_log("waiting for /test/a:o")
        time.sleep(2.5)
        assert bridge.alive
        assert reader.bottles == []
        log = bridge.log_text()
        assert log.count("waiting for /test/a:o") == 1, log
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        reader.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds,
                      ["/lonely_bridge/out:o", "/lonely_bridge/m/in0:i"])
    assert totals(bridge.log_text())["published"] == 0


def test_producer_killed_and_restarted(yarp_server, tmp_path):
    env = yarp_server.env
    program = simple_program("restart_bridge", timeout=0.5)
    bridge, (a,), reader = start_pipeline(env, program, tmp_path, producers=("/test/a:o",))
    try:
        a.write([1.0])
        reader.wait_for(1)
        a.kill()
        bridge.wait_log("input /test/a:o is stale (no data for")
        time.sleep(1.0)
        a.start()
        a.wait_outputs(1, timeout=60)  # the module's watcher connected it again
        a.write([2.0])
        got = reader.wait_for(2)
        bridge.wait_log("input /test/a:o is fresh again")
        a.kill()
        bridge.wait_log("is stale (no data for", count=2)
        a.start()
        a.wait_outputs(1, timeout=60)
        a.write([3.0])
        got = reader.wait_for(3)
    finally:
        rc, seconds = bridge.interrupt(signal.SIGINT)
        a.stop()
        reader.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds, ["/restart_bridge/out:o"])
    assert [g.data for g in got] == [[0, [1.0]], [1, [2.0]], [2, [3.0]]]
    log = bridge.log_text()
    assert log.count("is stale (no data for") == 2  # once per transition, not per cycle
    assert log.count("is fresh again") == 2
    assert totals(log)["/test/a:o"] == (3, 0, 2)


def test_malformed_bottles_dropped_and_counted(yarp_server, tmp_path):
    env = yarp_server.env
    program = simple_program("strict_bridge", on_nan="drop",
                             layout=(ElementGroup("int32", 1), ElementGroup("float64", 2)))
    bridge, (a,), reader = start_pipeline(env, program, tmp_path, producers=("/test/a:o",))
    try:
        a.write([1, 2.0, 3])            # ok: float64 takes an int
        reader.wait_for(1)
        for bad in ([1, 2.0],               # wrong size
                    [1, 2.0, 3.0, 4.0],     # wrong size
                    [1.5, 2.0, 3.0],        # float where int32
                    ["x", 2.0, 3.0],        # string
                    [1, [2.0], 3.0],        # list
                    [1, float("nan"), 3.0]):  # NaN, on_nan = drop
            a.write(bad)
            time.sleep(0.05)  # one at a time: an input keeps only the newest Bottle
        a.write([4, 5.0, 6.0])          # ok
        got = reader.wait_for(2)
        time.sleep(0.3)
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        a.stop()
        reader.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds, ["/strict_bridge/out:o"])
    assert [g.data for g in reader.bottles] == [[0, [1, 2.0, 3.0]], [1, [4, 5.0, 6.0]]]
    assert got[0].types == ["int32", ["int32", "float64", "float64"]]
    log = bridge.log_text()
    assert totals(log)["/test/a:o"] == (8, 6, 0)
    assert log.count("dropped a Bottle") == 1  # the first drop is reported, the rest counted
    assert "2 elements, expected 3" in log
    assert totals(log)["published"] == 2


def test_nan_passes_by_default(yarp_server, tmp_path):
    env = yarp_server.env
    bridge, (a,), reader = start_pipeline(env, simple_program("nan_bridge"), tmp_path,
                                          producers=("/test/a:o",))
    try:
        a.write([float("nan"), 1])
        (got,) = reader.wait_for(1)
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        a.stop()
        reader.stop()
    assert rc == 0
    assert math.isnan(got.data[1][0]) and got.data[1][1] == 1.0
    assert got.types[1] == ["float64", "float64"]  # undeclared: every element a float64


def test_envelope_stamp(yarp_server, tmp_path):
    env = yarp_server.env
    program = simple_program("envelope_bridge", envelope=True)
    bridge, (a,), reader = start_pipeline(env, program, tmp_path, producers=("/test/a:o",))
    try:
        a.write([1.0], stamp=[5, 1234.5])
        reader.wait_for(1)  # (written at once, the second would replace the first: newest only)
        a.write([2.0], stamp=[6, 1700000000.25])
        got = reader.wait_for(2)
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        a.stop()
        reader.stop()
    assert rc == 0
    assert got[0].data == [0, [1.0], [1234, 500000000]]
    sec, nsec = got[1].data[2]
    assert sec == 1700000000 and abs(nsec - 250000000) < 1000


def test_hold_policy_and_cli_options(yarp_server, tmp_path):
    """on_stale = hold keeps publishing the last values; --prefix, --rate,
    --timeout and --verbose act as docs/runtime.md says.
    Forced: every step waits for its event (the watcher's connection, the
    stale notice, 20 held messages) instead of a fixed time; the rate is
    read from the module's own clock (the wall-clock stamp it puts in each
    message), not from when the test process happened to receive them."""
    env = yarp_server.env
    program = simple_program("hold_bridge", on_stale="hold", timeout=5.0, envelope=True)
    bridge = Bridge(env, program, tmp_path, "--prefix", "/other", "--rate", "20",
                    "--timeout", "0.3", "--verbose").start()
    a = YarpProducer(env, "/test/a:o").start()
    reader = YarpReader(env, "/test/reader", source="/hold_bridge/out:o").start()
    try:
        a.wait_outputs(1, timeout=60)
        assert yarp_server.exists("/other/m/in0:i")
        reader.wait_connected(timeout=60)
        a.write([90.0])
        bridge.wait_log("input /test/a:o is stale (no data for 0.3 s)", timeout=60)
        reader.clear()
        held = reader.wait_for(20, timeout=60)
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        a.stop()
        reader.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds, ["/other/m/in0:i", "/hold_bridge/out:o"])
    assert all(h.data[1] == [90.0] for h in held)
    counters = [h.data[0] for h in held]
    assert counters == list(range(counters[0], counters[0] + len(held)))
    stamps = [sec + nsec / 1e9 for sec, nsec in (h.data[2] for h in held)]
    gaps = sorted(b - a for a, b in zip(stamps, stamps[1:]))
    assert 0.04 <= gaps[len(gaps) // 2] <= 0.06, gaps  # 20 Hz, not event-driven (the config's)
    assert "[m] 0: 90.0" in bridge.log_text()


def test_escaped_strings_arrive_exactly(yarp_server, tmp_path):
    env = yarp_server.env
    program = escape_program()
    bridge, (a,), reader = start_pipeline(env, program, tmp_path, producers=("/test/esc:o",))
    try:
        a.write([1.0])
        (got,) = reader.wait_for(1)
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        a.stop()
        reader.stop()
    assert_clean_exit(yarp_server, bridge, rc, seconds, ["/escape_bridge/out:o"])
    assert got.data == [EVIL, [EVIL, "", "'", '"', "\\"], [1.0]]


def test_stalled_consumer(yarp_server, tmp_path):
    """A reader that stops reading (SIGSTOP) neither blocks the module nor
    makes its memory grow.
    Forced: the stalled reader stays stopped while the other reader waits
    for 300 messages (enough 16 kB messages to fill the stalled
    connection's buffers: a module that waited for it would publish none),
    then for 300 more between two readings of the module's memory; counts
    of messages, not durations, so a slow machine only takes longer."""
    env = yarp_server.env
    program = simple_program("stall_bridge", rate=100.0, on_stale="hold", big=2000)
    bridge, (a,), reader = start_pipeline(env, program, tmp_path, producers=("/test/a:o",))
    fast = YarpReader(env, "/test/fast", source="/stall_bridge/out:o").start()

    def rss_kb():
        with open(f"/proc/{bridge.pid}/status") as f:
            return int(re.search(r"VmRSS:\s+(\d+)", f.read()).group(1))
    try:
        fast.wait_connected(timeout=60)
        a.write([1.0])
        reader.wait_for(1, timeout=60)
        os.kill(reader.pid, signal.SIGSTOP)
        fast.clear()
        fast.wait_for(300, timeout=60)  # the stalled connection's buffers fill up
        rss0 = rss_kb()
        fast.clear()
        got = fast.wait_for(300, timeout=60)
        rss1 = rss_kb()
        assert bridge.alive
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        os.kill(reader.pid, signal.SIGCONT)
        for p in (a, reader, fast):
            p.stop()
    assert rss1 - rss0 < 8 * 1024, f"memory grew from {rss0} kB to {rss1} kB"
    counters = [g.data[0] for g in got]
    assert counters == sorted(set(counters)), "messages out of order"
    assert_clean_exit(yarp_server, bridge, rc, seconds, ["/stall_bridge/out:o"])


# --------------------------------------------------------------------------
# ROS 1: the thesis' Rviz scenario


def test_thesis_jointstate_to_rospy(yarp_ros_server, tmp_path):
    env = yarp_ros_server.env
    program = jointstate()
    bridge = Bridge(env, program, tmp_path).start()
    sub = RospySubscriber(env, "/yarp/joint_states").start()
    arm = YarpProducer(env, "/vizzySim/left_shoulder_arm/state:o").start()
    degrees = [0.0, 10.0, -45.0, 90.0, 180.0, 12.5, -90.0, 33.0]
    try:
        sub.wait_publishers(1, timeout=60)
        arm.wait_outputs(1, timeout=60)
        for k in range(3):
            arm.write([d + k for d in degrees])
            sub.wait_for(k + 1, timeout=60)
        msgs = sub.wait_for(3)
    finally:
        rc, seconds = bridge.interrupt(signal.SIGINT)
        arm.stop()
        sub.stop()
    log = bridge.log_text()
    assert rc == 0 and seconds < 2.0 and "Traceback" not in log, log[-3000:]
    assert not registered(yarp_ros_server, "/yarp/joint_states@/yarp/thesis_figure5_rviz")
    for k, m in enumerate(msgs):
        msg = m.msg
        assert msg["name"] == list(jointstate().message.fields[1].source.values)
        assert msg["position"] == pytest.approx([(d + k) * DEG for d in degrees], abs=1e-12)
        assert msg["velocity"] == [] and msg["effort"] == []
        assert msg["header"]["frame_id"] == "0"
        assert msg["header"]["seq"] == k
        stamp = msg["header"]["stamp"]
        assert abs(stamp["secs"] + stamp["nsecs"] / 1e9 - m.t) < 1.0
    assert "[mux1] 1: " + repr(10.0 * DEG) in log


# --------------------------------------------------------------------------
# every example and legacy config this backend supports, from the real file

ROOT = Path(__file__).resolve().parents[1]
CONFIG_DIRS = (ROOT / "examples", ROOT.parent / "shared" / "legacy")


def _config_paths():
    paths = []
    for d in CONFIG_DIRS:
        paths.extend(sorted(d.glob("*.ini")))
    return paths


def _compile(path):
    from ybg.compiler.pipeline import compile_path
    return check_result(compile_path(path), "py")


def _supported_configs():
    out = []
    for path in _config_paths():
        result = _compile(path)
        if result.ok:
            out.append(path)
        else:
            codes = {d.code for d in result.errors}
            # only "this backend cannot build it" may keep a config out
            assert codes == {"E318"}, f"{path}: {[str(d) for d in result.errors]}"
    return out


try:
    SUPPORTED = _supported_configs()
    COLLECT_ERROR = None
except Exception as e:  # the front end is broken: one failing test says so
    SUPPORTED, COLLECT_ERROR = [], e


def _id(path):
    return path.stem


def test_configs_found():
    if COLLECT_ERROR is not None:
        pytest.fail(f"compiling the configs failed: {COLLECT_ERROR!r}")
    stems = {p.stem for p in SUPPORTED}
    assert {"thesis_figure5_rviz", "vizzy_upper_body", "rviz_joint_states_ros1",
            "fixation_point_goal"} <= stems


@pytest.mark.parametrize("path", SUPPORTED, ids=_id)
def test_config_golden(path, update_goldens):
    program = _compile(path).program
    files = PyBackend().render(program)
    assert files == PyBackend().render(_compile(path).program), "output is not deterministic"
    for name, text in without_runtime(files).items():
        golden = GOLDEN / path.stem / name
        if update_goldens or os.environ.get("YBG_UPDATE_GOLDENS") == "1":
            golden.parent.mkdir(parents=True, exist_ok=True)
            golden.write_text(text, encoding="utf-8")
        assert golden.exists(), f"missing golden file {golden}; run pytest --update-goldens"
        assert golden.read_text(encoding="utf-8") == text, f"{golden} differs"
        compile(text, name, "exec")


# -- a reference of docs/runtime.md's Bottle layout, independent of the backend

TIME = object()  # a time stamp: checked for plausibility, not equality
COUNTER = object()  # the message counter: an integer >= 2 (the third message or later)


def sample_input(inp: ir.Input, k: int) -> list:
    """Values a producer writes on ``inp`` (the k-th Bottle)."""
    if inp.layout is None:
        return [10.0 * j + k + 0.5 for j in range(8)]
    out = []
    for j, t in enumerate(inp.element_types):
        if t in ir.FLOAT_TYPES:
            out.append(10.0 * j + k + 0.25)
        elif t == "string":
            out.append(f"s{j}_{k}")
        elif t == "bool":
            out.append((j + k) % 2)
        else:
            out.append(j + k)
    return out


def reference_mux(mux: ir.Mux, data: list) -> list:
    values = []
    for inp, d in zip(mux.inputs, data):
        values.extend(float(x) for x in d) if inp.layout is None else values.extend(d)
    for c in mux.converters:
        stop = len(values) if c.stop is None else c.stop
        for j in range(c.start, min(stop, len(values))):
            y = values[j] * c.scale + c.offset
            values[j] = float(y) if c.to_float else y
    return values


def _default(typ: ir.TypeRef):
    if typ.array == "sequence":
        return []
    if typ.base in ("time", "duration"):
        return TIME
    d = 0.0 if typ.base in ir.FLOAT_TYPES else "" if typ.base == "string" else 0
    return [d] * typ.size if typ.array == "fixed" else d


def reference(node, muxes: dict, counter: int, named: bool):
    """The message as Bottle items (named=False) or as a dict of fields (True)."""
    if isinstance(node, ir.Struct):
        if named:
            return {f.name: reference_field(f, muxes, counter, named) for f in node.fields}
        items = []
        for f in node.fields:
            if isinstance(f.source, ir.MuxRef) and f.source.splice:
                items.extend(reference_field(f, muxes, counter, named))
            else:
                items.append(reference_field(f, muxes, counter, named))
        return items
    raise TypeError(node)


def reference_field(f: ir.Field, muxes, counter, named):
    src = f.source
    if isinstance(src, ir.Struct):
        return reference(src, muxes, counter, named)
    if isinstance(src, ir.Literal):
        values = [bool(v) if src.element_type == "bool" and named else v for v in src.values]
        return values if src.is_list else values[0]
    if isinstance(src, ir.MuxRef):
        v = muxes[src.mux]
        if src.index is not None:
            return v[src.index]
        part = v[src.start:src.stop]
        if src.into_fields is not None:
            return dict(zip(src.into_fields, part)) if named else part
        return part
    if isinstance(src, ir.Counter):
        return counter
    if isinstance(src, (ir.Timestamp, ir.Seconds)):
        return TIME
    if isinstance(src, ir.Default):
        return _default(f.type)
    raise TypeError(src)


def assert_matches(got, want, now, path="msg"):
    if want is COUNTER:
        assert isinstance(got, int) and got >= 2, f"{path}: counter {got!r}"
    elif want is TIME:
        if isinstance(got, dict):
            got = [got.get("secs", got.get("sec")), got.get("nsecs", got.get("nanosec"))]
        t = got[0] + got[1] / 1e9 if isinstance(got, list) else got
        assert abs(t - now) < 1.0, f"{path}: time {got} is not within a second of {now}"
    elif isinstance(want, dict):
        assert isinstance(got, dict) and set(got) >= set(want), f"{path}: {got!r}"
        for k in want:
            assert_matches(got[k], want[k], now, f"{path}.{k}")
    elif isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), f"{path}: {got!r} != {want!r}"
        for k, (g, w) in enumerate(zip(got, want)):
            assert_matches(g, w, now, f"{path}[{k}]")
    elif isinstance(want, float):
        assert got == pytest.approx(want, abs=1e-12), f"{path}: {got!r} != {want!r}"
    else:
        assert got == want, f"{path}: {got!r} != {want!r}"


ROSPY_PUBLISHER = r"""
import sys, time, rospy
from geometry_msgs.msg import Point
rospy.init_node("ybg_test_point_pub", anonymous=True, disable_signals=True)
pub = rospy.Publisher(sys.argv[1], Point, queue_size=10)
while True:
    pub.publish(Point(1.5, -2.0, 0.25))
    time.sleep(0.05)
"""


def _ros1_type_known(msg_type):
    pkg, _, name = (msg_type or "").partition("/")
    return bool(name) and Path(f"/usr/share/{pkg}/msg/{name}.msg").exists()


def _runnable(path):
    out = _compile(path).program.output
    return out.kind == "yarp" or _ros1_type_known(out.msg_type)


RUNNABLE = [p for p in SUPPORTED if _runnable(p)]


def _needs_ros(program) -> bool:
    return program.output.kind == "ros1" or any(i.kind == "ros1" for m in program.muxes for i in m.inputs)


@pytest.mark.parametrize("path", RUNNABLE, ids=_id)
def test_config_end_to_end(path, yarp, request, tmp_path):
    """The module generated from the config, fed by real producers (YARP
    ports, or a rospy publisher of geometry_msgs/Point for ROS 1 inputs),
    publishes what docs/runtime.md's Bottle layout says, to a YARP reader or
    a rospy subscriber. Where YARP has no ROS 1 (3.10 and later), a ROS 1
    module stops at start and says why."""
    program = _compile(path).program
    if _needs_ros(program) and not yarp.has_ros1:
        env = request.getfixturevalue("yarp_server").env
        script = write_module(program, tmp_path)
        r = subprocess.run([VENV_PYTHON, script], env=env, capture_output=True, text=True, timeout=60)
        assert r.returncode == 1 and "cannot use ROS 1 topics" in r.stdout, r.stdout + r.stderr
        return
    env = request.getfixturevalue("yarp_ros_server" if _needs_ros(program) else "yarp_server").env
    out = program.output
    # fixed-rate configs run at their rate; event-driven ones publish per arrival
    bridge = Bridge(env, program, tmp_path).start()
    producers, extra = [], []
    try:
        ros_inputs = [i for m in program.muxes for i in m.inputs if i.kind == "ros1"]
        for topic in {i.name for i in ros_inputs}:
            script = tmp_path / "point_pub.py"
            script.write_text(ROSPY_PUBLISHER)
            extra.append(Proc(["/usr/bin/python3", script, topic], env=env,
                              name="point_pub").start())
        yarp_inputs = [i for m in program.muxes for i in m.inputs if i.kind == "yarp"]
        data = {i.name: sample_input(i, 0) for i in yarp_inputs}
        producers = [YarpProducer(env, i.name, bottles=[data[i.name]], rate=20).start()
                     for i in yarp_inputs]
        if out.kind == "yarp":
            if out.connect_to:  # the module connects itself to this port
                sink = YarpReader(env, out.connect_to).start()
            else:
                sink = YarpReader(env, "/test/sink", source=out.name).start()
            extra.append(sink)
            got = sink.wait_for(3, timeout=60)[-1]
            received, now = got.data, got.t
        else:
            sink = RospySubscriber(env, out.name, msg_type=out.msg_type).start()
            extra.append(sink)
            got = sink.wait_for(3, timeout=60)[-1]
            received, now = got.msg, got.t
    finally:
        rc, seconds = bridge.interrupt(signal.SIGTERM)
        for p in producers + extra:
            p.stop()
    log = bridge.log_text()
    assert rc == 0 and seconds < 2.0 and "Traceback" not in log, log[-3000:]

    # a ROS 1 input: the Point (1.5, -2.0, 0.25), flattened into three float64
    data.update({i.name: [1.5, -2.0, 0.25] for i in ros_inputs})
    muxes = {m.name: reference_mux(m, [data[i.name] for i in m.inputs]) for m in program.muxes}
    want = reference(program.message, muxes, COUNTER, named=out.kind != "yarp")
    assert_matches(received, want, now)



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


TYPED_ROS1_INPUT = """\
[module]
name = typed_ros_input_py

[output]
port = /typed_ros_input_py/out:o

[mux g]
topics = /ybg_goal_py (geometry_msgs/PointStamped point)
via = ros1

[message]
label = "xyz"
p = g
"""

ROSPY_POINT_STAMPED = r"""
import json, sys, time
import rospy
from geometry_msgs.msg import Point, PointStamped
from std_msgs.msg import Header
cfg = json.loads(sys.argv[1])
rospy.init_node("ybg_py_test_pub", anonymous=True, disable_signals=True)
pub = rospy.Publisher(cfg["topic"], PointStamped, queue_size=10)
msg = PointStamped(header=Header(frame_id="cam"), point=Point(*cfg["point"]))
while True:
    pub.publish(msg)
    time.sleep(0.05)
"""


def test_typed_ros1_topic_input(yarp_ros_server, tmp_path):
    """A ROS 1 topic of a known type, from a real config: the module takes the
    fields the config names, at the Bottle positions the checker computed
    (the header's seq, stamp and frame_id are not part of the mux)."""
    cfg = tmp_path / "typed_ros_input_py.ini"
    cfg.write_text(TYPED_ROS1_INPUT)
    from ybg.compiler.pipeline import compile_path

    result = check_result(compile_path(cfg), "py")
    assert result.ok, result.diagnostics
    (inp,) = result.program.muxes[0].inputs
    assert inp.positions == ((1, 0), (1, 1), (1, 2))
    env = yarp_ros_server.env
    with Bridge(env, result.program, tmp_path) as bridge, \
            YarpReader(env, "/test/typed_py:i", source="/typed_ros_input_py/out:o") as reader, \
            Proc([ROS1_PYTHON, "-c", ROSPY_POINT_STAMPED,
                  json.dumps({"topic": "/ybg_goal_py", "point": [1.5, -2.0, 1e-3]})], env=env, name="rospy_pub"):
        got = reader.wait_for(3, timeout=30)
        rc, elapsed = bridge.interrupt()
    assert rc == 0 and elapsed < 2.0
    assert got[-1].data == ["xyz", 1.5, -2.0, 1e-3]
    assert "dropped" not in bridge.log_text().split("totals:")[0]
