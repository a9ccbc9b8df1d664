"""``ybgc probe``: configs against a live YARP name server and ROS 2 graph,
with real peers (one yarpserver, one ROS 2 domain and the peers shared by
the whole file): a YARP producer sending another layout than declared, a
missing port, a port that sends nothing within the wait, a taken output
port, an rclpy subscriber with an incompatible QoS (and the override that
mends it), a subscriber of ybg_demo_msgs/Polygon built from another
definition (tests/harness/variant.py: one type name, two type hashes), a
clean robot (exit 0), and no name server (exit 2). The probe runs as a user
runs it: the ybgc command, in a process of its own. Pure parts (layouts,
overrides, the plan, what the graph says) are tested without middleware."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from harness.env import ROOT, yarp_install
from harness.generated import YBGC
from harness.ros2 import QosSubscriber, Ros2Domain, Ros2Subscriber, ros2_environment
from harness.variant import TYPE as POLYGON, variant_env
from harness.yarp import YarpProducer, YarpServer
from ybg.compiler import ir
from ybg.compiler.diagnostics import CODES, PROBE_CODES
from ybg.compiler.pipeline import compile_text
from ybg.compiler.diagnostics import Sink
from ybg.compiler.options import Options
from ybg.compiler.pipeline import compile_path
from ybg.probe import layout, qos
from ybg.probe.findings import service_findings
from ybg.probe.plan import plan_of
from ybg.probe.ros2_graph import Ros2Seen

ARM = "/probe/arm/state:o"      # sends int32 x6; declared (float64 x8)
HEAD = "/probe/head/state:o"    # sends float64 x6, as declared
MISSING = "/probe/legs/state:o"  # nobody opens it
SILENT = "/probe/hand/state:o"   # open, sends nothing

WRONG_YARP = f"""\
[module]
name = probe_wrong

[output]
port = {HEAD}
rate = 10

[mux arm]
ports = {ARM} (float64 x8)

[mux legs]
ports = {MISSING} (float64 x4)

[mux hand]
ports = {SILENT} (float64 x9)

[message]
arm = [arm]
legs = [legs]
hand = [hand]
"""

JOINTS = """\
[module]
name = {name}

[output]
topic = {topic}
type = sensor_msgs/JointState
via = ros2
rate = 10
{extra}
[mux head]
ports = {head} (float64 x6)

[message]
header.stamp = timestamp
position = head
"""

POLYGON_CONFIG = """\
[module]
name = probe_polygon

[output]
topic = /probe/polygon
type = ybg_demo_msgs/Polygon
via = ros2
rate = 10

[message]
label = "square"
"""


CONFIGS = {
    "wrong": WRONG_YARP,
    "qos": JOINTS.format(name="probe_qos", topic="/probe/qos/joint_states", head=HEAD,
                         extra="reliability = best_effort\n"),
    "clean": JOINTS.format(name="probe_clean", topic="/probe/clean/joint_states", head=HEAD, extra=""),
    "polygon": POLYGON_CONFIG,
}
#: the override that the hint of the incompatible QoS gives
MENDS = "qos_overrides./probe/qos/joint_states.publisher.reliability:=reliable"
#: seconds for discovery: twice what a loaded machine of 2 cores was seen to need
WAIT = 4


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    """A name server and a ROS 2 domain in one environment, with the peers
    every test of the file probes against."""
    tmp = tmp_path_factory.mktemp("probe")
    for name, text in CONFIGS.items():
        (tmp / f"{name}.ini").write_text(text, encoding="utf-8")
    with YarpServer(install=yarp_install("3.5")) as server, Ros2Domain() as domain:
        env = ros2_environment(server.env, domain)
        peers = [YarpProducer(env, ARM, bottles=[[1, 2, 3, 4, 5, 6]], rate=50),
                 YarpProducer(env, HEAD, bottles=[[0.5] * 6], rate=50),
                 YarpProducer(env, SILENT),
                 QosSubscriber(env, "/probe/clean/joint_states", "sensor_msgs/msg/JointState"),
                 QosSubscriber(env, "/probe/qos/joint_states", "sensor_msgs/msg/JointState",
                               ir.QoS(reliability="reliable")),
                 Ros2Subscriber(variant_env(env), "/probe/polygon", POLYGON, node="variant_sub")]
        try:
            for p in peers:
                p.start()
            yield env, tmp
        finally:
            for p in peers:
                p.stop()


def probe(env, tmp: Path, names: list[str], *args) -> subprocess.CompletedProcess:
    """``ybgc probe <name>.ini... ARGS`` in the folder of the configs."""
    return subprocess.run([str(YBGC), "probe", *(f"{n}.ini" for n in names), *map(str, args)], cwd=tmp, env=env,
                          capture_output=True, text=True, timeout=60)


def found(r: subprocess.CompletedProcess) -> dict:
    """code -> (line, column, message) of a JSON report's errors and warnings."""
    return {d["code"]: (d["line"], d["column"], d["message"]) for d in json.loads(r.stdout) if d["severity"] != "note"}


def test_another_layout_a_missing_port_and_a_taken_output(robot):
    env, tmp = robot
    r = probe(env, tmp, ["wrong"], "--format", "json", "--wait", "2")
    assert r.returncode == 1, r.stderr
    got = found(r)
    assert set(got) == {"E370", "E371", "E372", "W570"}, got
    line, col, message = got["E371"]
    assert (line, col) == (9, 9)  # the declaration of /probe/arm/state:o in [mux arm]
    assert "sends 6 values: int32 x6" in message and "(float64 x8)" in message, message
    assert got["E370"][:2] == (12, 9) and MISSING in got["E370"][2]
    assert HEAD in got["E372"][2]
    assert got["W570"][:2] == (15, 9) and "sent no Bottle within 2 s" in got["W570"][2]
    assert all(d["title"] == PROBE_CODES[d["code"]] for d in json.loads(r.stdout))
    r = probe(env, tmp, ["wrong"], "--format", "github", "--wait", "0.5")
    assert r.returncode == 1, r.stderr
    lines = r.stdout.splitlines()
    assert [line.split("::")[1] for line in lines] == [
        "error file=wrong.ini,line=5,col=1,title=E372", "error file=wrong.ini,line=9,col=9,title=E371",
        "error file=wrong.ini,line=12,col=9,title=E370", "warning file=wrong.ini,line=15,col=9,title=W570"], lines


def test_an_incompatible_qos_and_a_type_hash_of_another_definition(robot):
    """Two configs, one discovery: the module's best-effort publisher
    against a reliable subscriber; a Polygon subscriber of the variant."""
    env, tmp = robot
    r = probe(env, tmp, ["qos", "polygon"], "--msg-path", ROOT / "msgpkgs", "--wait", WAIT, "--format", "json")
    assert r.returncode == 1, r.stderr
    by_file = {(d["file"], d["code"]): d for d in json.loads(r.stdout) if d["severity"] != "note"}
    assert set(by_file) == {("qos.ini", "E375"), ("polygon.ini", "E374")}, r.stdout
    qos_d, hash_d = by_file["qos.ini", "E375"], by_file["polygon.ini", "E374"]
    assert (qos_d["line"], qos_d["column"]) == (7, 1)  # the output (its `via`)
    assert "Best effort publisher and reliable subscription" in qos_d["message"], qos_d
    assert qos_d["hint"].startswith(f"start the module with -p {MENDS}, and probe with the same; or set "
                                    "`reliability = reliable` in the config's [output]"), qos_d
    assert (hash_d["line"], hash_d["column"]) == (6, 8)  # the output's type
    hashes = re.findall(r"RIHS01_[0-9a-f]{64}", hash_d["message"])
    assert len(hashes) == 2 and hashes[0] != hashes[1], hash_d
    assert "/variant_sub's subscription has ybg_demo_msgs/msg/Polygon" in hash_d["message"], hash_d


def test_a_clean_robot_and_the_override_that_mends_the_qos(robot):
    env, tmp = robot
    r = probe(env, tmp, ["clean", "qos"], "--wait", WAIT, "-v",
              "-p", MENDS)
    assert r.returncode == 0, r.stderr
    notes = [line for line in r.stderr.splitlines() if " note N670 " in line]
    assert all(not re.search(r": (error|warning) ", line) for line in r.stderr.splitlines()), r.stderr
    seen = "\n".join(notes)
    assert "clean.ini:11:9: note N670 input 0 of mux `head`: /probe/head/state:o sends 6 values: float64 x6" in seen
    for topic, mine in (("/probe/clean/joint_states", "reliable"), ("/probe/qos/joint_states", "reliable")):
        assert re.search(f"the topic {topic} \\(the module's publisher, {mine}, volatile, keep_last 10\\): "
                         "/ybg_test_qos_sub's subscription of sensor_msgs/msg/JointState", seen), seen


def test_a_folder_is_probed_as_its_configs(robot, tmp_path):
    """`ybgc probe DIR`: the folder's configs, as `ybgc probe` in it and as
    the configs named; a folder and a file mixed; the exact report."""
    env, tmp = robot
    folder = tmp_path / "robot"
    folder.mkdir()
    for name in ("wrong", "clean"):
        (folder / f"{name}.ini").write_text(CONFIGS[name], encoding="utf-8")
    (tmp_path / "qos.ini").write_text(CONFIGS["qos"], encoding="utf-8")
    expected = ["::error file=robot/wrong.ini,line=5,col=1,title=E372",
                "::error file=robot/wrong.ini,line=9,col=9,title=E371",
                "::error file=robot/wrong.ini,line=12,col=9,title=E370",
                "::warning file=robot/wrong.ini,line=15,col=9,title=W570"]

    def run(cwd: Path, *args) -> list[str]:
        r = subprocess.run([str(YBGC), "probe", *map(str, args), "--format", "github", "--wait", str(WAIT)], cwd=cwd,
                           env=env, capture_output=True, text=True, timeout=60)
        assert r.returncode == 1 and r.stderr == "", r.stderr
        return ["::" + line.split("::")[1] for line in r.stdout.splitlines()]

    assert run(tmp_path, "robot") == expected
    assert run(tmp_path, "robot/wrong.ini", "robot/clean.ini") == expected
    assert run(folder) == [line.replace("robot/", "") for line in expected]
    mixed = run(tmp_path, "robot", "qos.ini")
    assert mixed[:4] == expected and mixed[4:] == ["::error file=qos.ini,line=7,col=1,title=E375"], mixed


def test_no_name_server_is_a_usage_error(robot, tmp_path):
    env, tmp = robot
    conf = tmp_path / "yarp"
    conf.mkdir()
    (conf / "yarp.conf").write_text("127.0.0.1 9 yarp\n")
    r = probe({**env, "YARP_CONFIG_HOME": str(conf)}, tmp, ["wrong"])
    assert r.returncode == 2 and "no YARP name server answers" in r.stderr and "hint:" in r.stderr, r.stderr


# --------------------------------------------------------------------------
# without middleware


def test_probe_codes_are_documented_apart_from_checks():
    doc = (ROOT / "docs" / "diagnostics.md").read_text(encoding="utf-8")
    section = doc.split("## Codes of `ybgc probe`", 1)[1]
    rows = dict(re.findall(r"^\| `([EWN][0-9]{3})` \| ([^|]+?) \|", section, re.M))
    assert rows == PROBE_CODES and not set(PROBE_CODES) & set(CODES)


@pytest.mark.parametrize("declared, elements, why", [
    ((ir.ElementGroup("float64", 2),), [("int32", 1), ("float64", 2.0)], None),
    ((ir.ElementGroup("float64", 8),), [("int32", 1)] * 6, "6 elements, not 8"),
    ((ir.ElementGroup("int32", 1),), [("float64", 1.0)], "element 0 is float64, not int32"),
    ((ir.ElementGroup("bool", 2),), [("int32", 1), ("int32", 2)], "element 1 is int32, not bool"),
    ((ir.ElementGroup("string", 1),), [("string", "a")], None),
    (None, [("int64", 3), ("float32", 1.0)], None),
    (None, [("float64", 1.0), ("list", None)], "element 1 is list, not a number"),
])
def test_layouts_as_the_modules_take_them(declared, elements, why):
    assert layout.mismatch(declared, elements) == why


def test_what_a_bottle_holds_in_the_configs_notation():
    assert layout.seen([("int32", 1)] * 6) == "6 values: int32 x6"
    assert layout.seen([("float64", 1.0), ("float64", 1.0), ("string", "a")]) == "3 values: float64 x2, string x1"
    assert layout.declared((ir.ElementGroup("float64", 8),)) == "(float64 x8)"


def test_overrides_as_the_module_takes_them():
    o = qos.parse_parameter("qos_overrides./joint_states.publisher.reliability:=best_effort")
    assert o == qos.Override("/joint_states", "publisher", "reliability", "best_effort")
    assert qos.parse_parameter("rate:=20") is None
    p = qos.overridden(qos.Profile(), "/joint_states", "publisher", [o, qos.Override("/x", "publisher", "depth", 1)])
    assert p == qos.Profile(reliability="best_effort")
    for bad in ("qos_overrides./a.publisher.deadline:=1", "qos_overrides./a.publisher.depth:=0",
                "qos_overrides./a.publisher.reliability:=sometimes", "qos_overrides.a.reliability:=reliable",
                "qos_overrides./a.publisher.depth"):
        with pytest.raises(qos.OverrideError):
            qos.parse_parameter(bad)


def test_the_plan_of_a_bridge():
    program = compile_text(JOINTS.format(name="m", topic="/js", head=HEAD, extra=""), "m.ini").program
    plan = plan_of(program)
    assert [r.name for r in plan.reads] == [HEAD]
    assert [o.name for o in plan.opens] == ["/m/rpc:i", "/m/head/in0:i"]
    assert [(t.topic, t.role) for t in plan.topics] == [("/js", "publisher"), ("/diagnostics", "publisher")]
    assert [o.name for o in plan_of(program, "/other").opens][0] == "/other/rpc:i"


def test_the_plan_of_commands_and_what_the_graph_says_of_their_services():
    home = compile_path(ROOT / "examples" / "home_arm_trigger.ini", Options()).program
    plan = plan_of(home)
    assert [(r.name, r.call) for r in plan.reads] == [("/icub/left_arm/homing/rpc:i", True)]
    assert [(s.name, s.srv_type, s.role) for s in plan.services] == [("/icub/left_arm/home", "std_srvs/Trigger",
                                                                      "server")]
    gate = plan_of(compile_path(ROOT / "examples" / "yarp_rpc_to_ros2.ini", Options()).program)
    assert [o.name for o in gate.opens] == ["/robot_gate/rpc:i"]  # its own RPC port serves the commands
    assert [(s.name, s.role) for s in gate.services] == [("/robot/home", "client"), ("/tracker/enable", "client")]
    seen = Ros2Seen(service_types={"/icub/left_arm/home": ["std_srvs/srv/SetBool"]}, servers={"/icub/left_arm/home": 1})
    sink = Sink("home.ini")
    service_findings(plan, seen, sink)
    assert sorted(d.code for d in sink.items) == ["E373", "E376"]
    sink = Sink("gate.ini")
    service_findings(gate, Ros2Seen(), sink)
    assert [d.code for d in sink.sorted()] == ["W572", "W572"]


def test_what_the_graph_says_of_topics():
    """Each endpoint of a topic: another type, another hash, QoS that rmw
    refuses (the hint's override, or the peer's deadline, which the module
    cannot offer), QoS rmw cannot tell about."""
    from ybg.probe.findings import ros2_findings
    from ybg.probe.ros2_graph import Endpoint

    text = JOINTS.format(name="m", topic="/js", head=HEAD, extra="durability = transient_local\n")
    plan = plan_of(compile_text(text, "m.ini").program)
    js = "sensor_msgs/msg/JointState"
    seen = Ros2Seen(endpoints={"/js": [
        Endpoint("/a", "subscription", "std_msgs/msg/String", None, ""),
        Endpoint("/b", "subscription", js, "RIHS01_" + "1" * 64, ""),
        Endpoint("/c", "subscription", js, None, "", "error", "ERROR: Subscription has a deadline", "reliable",
                 "volatile"),
        Endpoint("/d", "subscription", js, None, "", "warning", "WARNING: unknown", "reliable", "volatile"),
        Endpoint("/e", "publisher", js, None, "", None, "", "best_effort", "volatile")]})
    profiles = {(t.topic, t.role): qos.Profile.of(t.qos) for t in plan.topics}
    sink = Sink("m.ini")
    ros2_findings(plan, seen, {"sensor_msgs/JointState": "RIHS01_" + "2" * 64}, profiles, sink)
    got = {d.message.split("'s ")[0].rsplit(" ", 1)[-1]: (d.code, d.hint) for d in sink.items if d.code != "N670"}
    assert {k: v[0] for k, v in got.items()} == {"/a": "E373", "/b": "E374", "/c": "E375", "/d": "W571"}
    assert got["/c"][1].startswith("/c asks for what the module does not offer")
    reader = plan_of(compile_path(ROOT / "examples" / "ros2_to_yarp_gaze.ini", Options()).program)
    assert [(t.topic, t.role, t.qos) for t in reader.topics] == [
        ("/fixation_point", "subscription", ir.QoS("best_effort", "volatile", 1)),
        ("/diagnostics", "publisher", ir.QoS(depth=1))]
    e = Endpoint("/pub", "publisher", "geometry_msgs/msg/PointStamped", None, "", "error", "ERROR: ...",
                 "reliable", "volatile")
    sink = Sink("gaze.ini")
    profiles = {(t.topic, t.role): qos.Profile("reliable", "transient_local", 1) for t in reader.topics}
    ros2_findings(reader, Ros2Seen(endpoints={"/fixation_point": [e]}), {}, profiles, sink)
    (d,) = [d for d in sink.items if d.code == "E375"]
    assert d.hint.startswith("start the module with -p qos_overrides./fixation_point.subscription.durability:=volatile"
                             ", and probe with the same; or change /pub's QoS"), d.hint


def test_check_and_the_probe_load_no_middleware_until_probing(tmp_path):
    """rclpy and YARP are slow to load: `ybgc check` never loads them, nor
    does loading the probe; only probing does."""
    cfg = tmp_path / "clean.ini"
    cfg.write_text(CONFIGS["clean"], encoding="utf-8")
    code = ("import sys; from ybg.cli import main; status = main(['check', sys.argv[1]]); import ybg.probe; "
            "loaded = [m for m in ('rclpy', 'yarp') if m in sys.modules]; "
            "assert status == 0 and not loaded, (status, loaded)")
    r = subprocess.run([sys.executable, "-c", code, str(cfg)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
