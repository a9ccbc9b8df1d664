"""Every default the documentation states is the one the code uses.

The defaults are read from the text of README.md and docs/*.md, never from a
copy: the tables whose header has a `default` column (docs/config.md's
[module], [output] and [mux <name>] keys, docs/runtime.md's command line)
and the sentences that give a default in prose (a QoS, a timeout, a period,
an option's value). Each is compared with what the code uses: the named
constant it reads (ybg.compiler.ir, the passes, the runtime, the command's
parser), and, where a default is something the checker decides, with the
checked program of a config that leaves the key out, so that a constant
the code no longer reads cannot pass for the code's default.

A table row with a default and no check here fails, and so does every
occurrence of the word "default" in the documentation that is neither
inside a table or sentence checked here nor in ``NOT_A_VALUE`` (the word
used of something else: a message's field defaults, YARP's own defaults):
a default newly documented is held to the code from the start.
"""
from __future__ import annotations

import importlib.util
import re
from collections.abc import Callable
from types import SimpleNamespace

import pytest

from harness.markdown import ROOT, Table, documents, name_of, tables
from ybg import cli
from ybg.backends import get_backend
from ybg.compiler import fmt, ir, msgtypes
from ybg.compiler.options import Options
from ybg.compiler.passes import images, inputs, output
from ybg.compiler.pipeline import compile_path, compile_text
from ybg.lower.rosnames import node_parameters
from ybg.probe.plan import plan_of
from ybg.runtime import core

# --------------------------------------------------------------------------
# configs that leave every key with a default out

HEADER = "[module]\nname = m\n\n"
YARP_TO_PORT = HEADER + """[output]
port = /m/out:o

[mux arm]
ports = /robot/arm:o (float64 x2)

[message]
a = arm
"""
JOINT_STATE = HEADER + """[output]
topic = /js
type = sensor_msgs/JointState

[mux arm]
ports = /robot/arm:o (float64 x2)

[message]
position = arm
"""
ROS1_JOINT_STATE = JOINT_STATE.replace("type = sensor_msgs/JointState", "via = ros1\ntype = sensor_msgs/JointState")
IMAGE = HEADER + """[output]
topic = /cam/image_raw
type = sensor_msgs/Image

[mux eye]
ports = /cam (image rgb8)

[message]
data = eye
"""
TOPIC_TO_PORT = HEADER + """[output]
port = /m/goal:o
{output}
[mux goal]
topics = /goal (geometry_msgs/Point)
via = ros2
{mux}
[message]
a = goal
"""
SERVICE = HEADER + """[service home]
serve = /robot/home (std_srvs/SetBool)
call = /robot/rpc:i (string x1)
send = "home"
response.success = reply[0]
"""


def program(text: str, name: str = "m.ini"):
    result = compile_text(text, name)
    assert result.ok, [str(d) for d in result.diagnostics]
    return result.program


def topic_to_port(output_keys: str = "", mux_keys: str = ""):
    return program(TOPIC_TO_PORT.format(output=output_keys, mux=mux_keys))


def matched(pattern: str, text: str) -> re.Match:
    m = re.fullmatch(pattern, text, re.S)
    assert m, f"the documentation now reads {text!r}, not /{pattern}/: read its new default here"
    return m


# --------------------------------------------------------------------------
# the tables of defaults, row by row: (document, heading, first cell) ->
# a check of the row's default cell


def module_name(cell: str) -> None:
    matched(r"the config's file name", cell)
    assert program(YARP_TO_PORT.replace(HEADER, ""), "robot_arm.ini").module == "robot_arm"


def module_distro(cell: str) -> None:
    ros1, ros2 = matched(r"`(\w+)` for ROS 1, `(\w+)` for ROS 2", cell).groups()
    assert msgtypes.DEFAULT_DISTRO == {"ros1": ros1, "ros2": ros2}
    assert program(ROS1_JOINT_STATE).distro == ros1 and program(JOINT_STATE).distro == ros2


def output_via(cell: str) -> None:
    port, topic = matched(r"`(\w+)` with `port`, `(\w+)` with `topic`", cell).groups()
    assert program(YARP_TO_PORT).output.kind == port and program(JOINT_STATE).output.kind == topic


def output_type(cell: str) -> None:
    matched(r"untyped Bottle", cell)
    assert program(YARP_TO_PORT).message.msg_type is None


def output_node(cell: str) -> None:
    node = matched(r"`(/\S+)`", cell).group(1)
    assert output.ROS1_NODE.format(module="<module>") == node
    assert program(ROS1_JOINT_STATE).output.node == node.replace("<module>", "m")


def event_driven(cell: str) -> None:
    matched(r"event-driven", cell)
    assert program(YARP_TO_PORT).timing.rate is None


def output_trigger(cell: str) -> None:
    trigger = matched(r"`(\w+)`", cell).group(1)
    assert ir.DEFAULT_TRIGGER == trigger and program(YARP_TO_PORT).timing.trigger == trigger


def output_queue(cell: str) -> None:
    queue = int(matched(r"`(\d+)`", cell).group(1))
    assert ir.DEFAULT_QUEUE == queue and program(YARP_TO_PORT).timing.queue == queue


def output_timeout(cell: str) -> None:
    timeout = float(matched(r"`([\d.]+)`", cell).group(1))
    assert inputs.DEFAULT_TIMEOUT == timeout
    assert [i.timeout for m in program(YARP_TO_PORT).muxes for i in m.inputs] == [timeout]


def output_on_stale(cell: str) -> None:
    word = matched(r"`(\w+)`", cell).group(1)
    assert ir.DEFAULT_ON_STALE == word and program(YARP_TO_PORT).policy.on_stale == word


def output_on_nan(cell: str) -> None:
    word = matched(r"`(\w+)`", cell).group(1)
    assert ir.DEFAULT_ON_NAN == word and program(YARP_TO_PORT).policy.on_nan == word


def output_publish(cell: str) -> None:
    commands, other = matched(r"`(\w+)` for a bridge from ROS topics to a YARP port \(.*\), else `(\w+)`",
                              cell).groups()
    assert topic_to_port("rate = 10\n").timing.publish == commands
    assert program(YARP_TO_PORT.replace("[output]", "[output]\nrate = 10")).timing.publish == other
    assert program(JOINT_STATE.replace("[output]", "[output]\nrate = 10")).timing.publish == other


#: the words docs/config.md names the sensor data types by
SENSOR_WORDS = {"camera": {"sensor_msgs/Image", "sensor_msgs/CompressedImage"}, "laser": {"sensor_msgs/LaserScan"},
                "point cloud": {"sensor_msgs/PointCloud", "sensor_msgs/PointCloud2"}, "IMU": {"sensor_msgs/Imu"}}


def output_defaults_and_sensor_data(text: str) -> None:
    """`reliable`, `volatile`, 10; for camera, laser, point cloud and IMU
    types `best_effort`[, `volatile`], [depth ]5: the two QoS an output has
    when its config gives none."""
    m = matched(r"`(\w+)`, `(\w+)`, (\d+); for ([\w ,]+?) types `(\w+)`, (?:`(\w+)`, )?(?:depth )?(\d+)"
                r"(?:,? \(?ROS's sensor-data profile\)?.*)?", text)
    rel, dur, depth, kinds, s_rel, s_dur, s_depth = m.groups()
    assert ir.OUTPUT_QOS == ir.QoS(rel, dur, int(depth))
    assert ir.SENSOR_DATA_QOS == ir.QoS(s_rel, s_dur or dur, int(s_depth))
    words = [w.strip() for w in re.split(r",| and ", kinds) if w.strip()]
    assert set().union(*(SENSOR_WORDS[w] for w in words)) == output.SENSOR_DATA_TYPES, words
    assert program(JOINT_STATE).output.qos == ir.OUTPUT_QOS
    assert program(IMAGE).output.qos == ir.SENSOR_DATA_QOS


def mux_via(cell: str) -> None:
    other, alone = matched(r"the output's ROS; with a YARP port output, `(\w+)` when another mux says "
                           r"`via = \1`, else `(\w+)`", cell).groups()
    topics = "topics = /arm (sensor_msgs/JointState position)"
    for config, kind in ((ROS1_JOINT_STATE, "ros1"), (JOINT_STATE, "ros2")):
        p = program(config.replace("ports = /robot/arm:o (float64 x2)", topics))
        assert [i.kind for m in p.muxes for i in m.inputs] == [kind]  # the output's ROS
    lone = TOPIC_TO_PORT.format(output="", mux="").replace("via = ros2\n", "")
    assert [i.kind for m in program(lone).muxes for i in m.inputs] == [alone]
    beside = lone.replace("[message]", "[mux arm]\ntopics = /arm (sensor_msgs/JointState position)\n"
                                       f"via = {other}\n\n[message]").replace("a = goal", "a = goal\nb = arm")
    kinds = {m.name: [i.kind for i in m.inputs] for m in program(beside).muxes}
    assert kinds == {"goal": [other], "arm": [other]}, kinds


def mux_convert(cell: str) -> None:
    matched(r"none", cell)
    assert [m.converters for m in program(YARP_TO_PORT).muxes] == [()]


def mux_timeout(cell: str) -> None:
    matched(r"`\[output\] timeout`", cell)
    p = program(YARP_TO_PORT.replace("[output]", "[output]\ntimeout = 2.5"))
    assert [i.timeout for m in p.muxes for i in m.inputs] == [2.5]


def mux_verbose(cell: str) -> None:
    matched(r"`false`", cell)
    assert [m.verbose for m in program(YARP_TO_PORT).muxes] == [False]


def mux_accept(cell: str) -> None:
    matched(r"none", cell)
    assert [i.accepts for m in program(YARP_TO_PORT).muxes for i in m.inputs] == [()]


def mux_qos(cell: str) -> None:
    rel, dur, depth, reliable_depth = matched(
        r"`(\w+)`, `(\w+)`, depth (\d+) \((\d+) when reliable\): matches every publisher", cell).groups()
    assert ir.INPUT_QOS == ir.QoS(rel, dur, int(depth)) and ir.RELIABLE_INPUT_DEPTH == int(reliable_depth)
    [given] = [i.subscription_qos for m in topic_to_port().muxes for i in m.inputs]
    assert given == ir.INPUT_QOS
    [reliable] = [i.subscription_qos for m in topic_to_port(mux_keys="reliability = reliable\n").muxes
                  for i in m.inputs]
    assert reliable == ir.QoS("reliable", dur, int(reliable_depth))


def prefix_option(cell: str) -> None:
    """The port prefix each backend's module starts with, without --name."""
    assert matched(r"`(/<module>)`", cell).group(1) == "/<module>"
    p = program(YARP_TO_PORT)
    written = {
        "py": r"run\(SPEC, argv, '([^']*)'",
        "cpp": r'"([^"]*)",\s*// default --prefix',
    }
    for backend, pattern in written.items():
        files = get_backend(backend).render(p)
        found = {m.group(1) for text in files.values() for m in re.finditer(pattern, text)}
        assert found == {"/m"}, (backend, found)
    files = get_backend("ros2").render(topic_to_port())
    assert {m.group(1) for t in files.values() for m in re.finditer(r"DEFAULT_PREFIX = '([^']*)'", t)} == {"/m"}


def module_options():
    """The options of a generated module given none: the runtime's parser."""
    spec = SimpleNamespace(module="m", description=[], config="m.ini", rate=None, muxes=())
    return core.parse_options(spec, [], "/m")


def config_rate_option(cell: str) -> None:
    matched(r"the config's `rate`", cell)
    assert module_options().rate is None  # none of its own: the config's


def config_timeout_option(cell: str) -> None:
    matched(r"the config's", cell)
    assert module_options().timeout is None


def config_verbose_option(cell: str) -> None:
    matched(r"the config's `verbose`", cell)
    assert module_options().verbose is False  # a flag that only turns it on


def config_accept_option(cell: str) -> None:
    matched(r"the config's `accept`", cell)
    assert not module_options().accept


def init_robot(cell: str) -> None:
    """Without --robot, every port the name server lists (the prefix /)."""
    from ybg.init.survey import under
    assert cell.startswith("`/`") and parsed("init").robot == "/"
    assert under("/icub/head/state:o", parsed("init").robot.rstrip("/"))


def init_output(cell: str) -> None:
    """Without -o, a folder named as the robot: ./icub for --robot /icub."""
    from ybg.init.plan import robot_name
    assert cell.startswith("`./<robot>`") and parsed("init").output is None
    assert robot_name("/icub") == "icub" and robot_name("/") == "robot"


def init_seconds(cell: str) -> None:
    assert parsed("init").seconds == float(cell)


def init_format(cell: str) -> None:
    assert parsed("init").format == cell


ACTION = {"serve": "/arm/follow_joint_trajectory (control_msgs/FollowJointTrajectory)",
          "joints": '"shoulder", "elbow"', "state": "/robot/arm/state:o (float64 x2)",
          "command": "/robot/arm/setpoints:i"}


def action_text(drop: str = "") -> str:
    return "[action follow]\n" + "".join(f"{k} = {v}\n" for k, v in ACTION.items() if k != drop)


def action_required(key: str) -> Callable[[str], None]:
    def check(cell: str) -> None:
        assert cell == "(required)"
        r = compile_text(action_text(drop=key), "a.ini")
        assert any(d.code == "E204" and f"`{key}`" in d.message for d in r.errors), r.errors
    return check


def action_default(attr: str, pattern: str, value) -> Callable[[str], None]:
    def check(cell: str) -> None:
        m = matched(pattern, cell)
        [a] = program(action_text(), "a.ini").actions
        want = value if value is not None or not m.groups() else None
        if m.groups():
            want = float(m.group(1))
        assert getattr(a, attr) == want, (attr, getattr(a, attr), want)
    return check


def action_convert(cell: str) -> None:
    from ybg.lower.actions import joint_conversions
    matched(r"none: the encoders are in the goal's units", cell)
    [a] = program(action_text(), "a.ini").actions
    assert a.converters == () and joint_conversions(a) == ((1.0, 0.0), (1.0, 0.0))


_ACTIONS = ("docs/actions.md", "FollowJointTrajectory from an arm's ports")

TABLE_CHECKS: dict[tuple[str, str, str], Callable[[str], None]] = {
    (*_ACTIONS, "`serve`"): action_required("serve"),
    (*_ACTIONS, "`joints`"): action_required("joints"),
    (*_ACTIONS, "`state`"): action_required("state"),
    (*_ACTIONS, "`command`"): action_required("command"),
    (*_ACTIONS, "`convert`"): action_convert,
    (*_ACTIONS, "`rate`"): action_default("rate", r"^(\d+)$", None),
    (*_ACTIONS, "`feedback_rate`"): action_default("feedback_rate", r"^(\d+)$", None),
    (*_ACTIONS, "`path_tolerance`"): action_default("path_tolerance", r"^none: not checked$", None),
    (*_ACTIONS, "`goal_tolerance`"): action_default("goal_tolerance", r"^none: not checked$", None),
    (*_ACTIONS, "`goal_time_tolerance`"): action_default("goal_time_tolerance", r"^(\d+)$", None),
    (*_ACTIONS, "`stale`"): action_default("stale", r"^([\d.]+)$", None),
    ("docs/config.md", "`[module]` (optional)", "`name`"): module_name,
    ("docs/config.md", "`[module]` (optional)", "`distro`"): module_distro,
    ("docs/config.md", "`[output]`", "`via`"): output_via,
    ("docs/config.md", "`[output]`", "`type`"): output_type,
    ("docs/config.md", "`[output]`", "`node`"): output_node,
    ("docs/config.md", "`[output]`", "`rate`"): event_driven,
    ("docs/config.md", "`[output]`", "`trigger`"): output_trigger,
    ("docs/config.md", "`[output]`", "`queue`"): output_queue,
    ("docs/config.md", "`[output]`", "`timeout`"): output_timeout,
    ("docs/config.md", "`[output]`", "`on_stale`"): output_on_stale,
    ("docs/config.md", "`[output]`", "`publish`"): output_publish,
    ("docs/config.md", "`[output]`", "`on_nan`"): output_on_nan,
    ("docs/config.md", "`[output]`", "`reliability`, `durability`, `depth`"): output_defaults_and_sensor_data,
    ("docs/config.md", "`[mux <name>]` (one or more)", "`via`"): mux_via,
    ("docs/config.md", "`[mux <name>]` (one or more)", "`convert`"): mux_convert,
    ("docs/config.md", "`[mux <name>]` (one or more)", "`timeout`"): mux_timeout,
    ("docs/config.md", "`[mux <name>]` (one or more)", "`verbose`"): mux_verbose,
    ("docs/config.md", "`[mux <name>]` (one or more)", "`accept`"): mux_accept,
    ("docs/config.md", "`[mux <name>]` (one or more)", "`reliability`, `durability`, `depth`"): mux_qos,
    ("docs/runtime.md", "Command line", "`--name P`"): prefix_option,
    ("docs/runtime.md", "Command line", "`--rate HZ`"): config_rate_option,
    ("docs/runtime.md", "Command line", "`--timeout S`"): config_timeout_option,
    ("docs/runtime.md", "Command line", "`--verbose`"): config_verbose_option,
    ("docs/runtime.md", "Command line", "`--accept [PORT=]OTHER`"): config_accept_option,
    ("docs/init.md", "Options", "`--robot PREFIX`"): init_robot,
    ("docs/init.md", "Options", "`-o DIR`"): init_output,
    ("docs/init.md", "Options", "`--seconds S`"): init_seconds,
    ("docs/init.md", "Options", "`--format json`"): init_format,
}


def default_tables() -> list[tuple[str, Table]]:
    return [(name_of(d), t) for d in documents() for t in tables(d.read_text(encoding="utf-8"))
            if "default" in t.header]


def default_rows() -> list[tuple[str, str, str, str]]:
    """(document, heading, first cell, default cell) of every row with a default."""
    out = []
    for doc, table in default_tables():
        col = table.column("default")
        out += [(doc, table.heading, row[0], row[col]) for row in table.rows if row[col]]
    return out


@pytest.mark.parametrize("doc, heading, key, cell", default_rows(), ids=lambda x: x if "`" not in x else None)
def test_each_default_of_a_table_is_the_codes(doc, heading, key, cell):
    check = TABLE_CHECKS.get((doc, heading, key))
    assert check is not None, (f"{doc}, {heading}: the default of {key} ({cell!r}) is not held to the code: "
                               "add its check to TABLE_CHECKS")
    check(cell)


def test_every_check_of_a_table_has_its_row():
    rows = {(doc, heading, key) for doc, heading, key, _ in default_rows()}
    assert set(TABLE_CHECKS) <= rows, sorted(set(TABLE_CHECKS) - rows)
    assert {doc for doc, _ in default_tables()} == {"docs/config.md", "docs/runtime.md", "docs/init.md",
                                                    "docs/actions.md"}


# --------------------------------------------------------------------------
# defaults stated in prose: (document, pattern) -> a check of its match; each
# pattern matches its sentence once, and the check compares what it says


def diagnostics_period(seconds: str) -> None:
    """Both Python runtimes (a bridge's node, a node of commands) and the
    launch files' parameters."""
    ros2_io = pytest.importorskip("ybg.runtime.ros2_io")
    services = pytest.importorskip("ybg.runtime.services")
    assert ros2_io.DIAGNOSTICS_PERIOD == services.DIAGNOSTICS_PERIOD == float(seconds)


def diagnostics_on(word: str) -> None:
    assert dict(node_parameters(program(JOINT_STATE)))["diagnostics"] is {"true": True, "false": False}[word]


def rate_window(seconds: str) -> None:
    ros2_io = pytest.importorskip("ybg.runtime.ros2_io")
    assert ros2_io.RATE_WINDOW * ros2_io.DIAGNOSTICS_PERIOD == float(seconds)


def rate_tolerance(percent: str) -> None:
    ros2_io = pytest.importorskip("ybg.runtime.ros2_io")
    assert round((1 - ros2_io.RATE_TOLERANCE) * 100) == int(percent)


def generated_into_module_folder(run) -> None:
    """`ybgc CONFIG --backend B` without -o: ./<module>, the runtime beside it."""
    tmp_path, ybgc = run.tmp_path, run.ybgc
    (tmp_path / "robot_arm.ini").write_text(YARP_TO_PORT.replace(HEADER, ""), encoding="utf-8")
    status, err = ybgc("robot_arm.ini", "--backend", "py")
    assert status == 0, err
    assert (tmp_path / "robot_arm" / "robot_arm.py").is_file()
    assert (tmp_path / "robot_arm" / "ybgc_runtime" / "core.py").is_file()


def graph_into_module_svg(run) -> None:
    tmp_path, ybgc = run.tmp_path, run.ybgc
    (tmp_path / "robot_arm.ini").write_text(YARP_TO_PORT.replace(HEADER, ""), encoding="utf-8")
    status, err = ybgc("graph", "robot_arm.ini")
    assert status == 0, err
    assert (tmp_path / "robot_arm.svg").read_text().lstrip().startswith("<")


def yarp_target_any(_: str) -> None:
    for command in ("check", "fmt", "ir", "generate", "compose", "graph", "probe"):
        assert parsed(command).yarp is None  # no YARP version assumed


def parsed(command: str, *args: str):
    needs = {"generate": ["--backend", "py"], "compose": ["--backend", "py"]}
    return cli.build_parser().parse_args([command, *needs.get(command, []), *args])


def probe_wait(seconds: str) -> None:
    assert parsed("probe").wait == float(seconds)


def probe_prefix(prefix: str) -> None:
    assert prefix == "/<module>" and parsed("probe").prefix is None  # the module's own
    assert plan_of(program(JOINT_STATE)).opens[0].name == "/m/rpc:i"


def input_qos_newest(*_: str) -> None:
    assert ir.INPUT_QOS.reliability == "best_effort" and ir.INPUT_QOS.depth == 1
    assert [i.subscription_qos for m in topic_to_port().muxes for i in m.inputs] == [ir.INPUT_QOS]


def input_qos_words(depth: str, reliability: str, durability: str) -> None:
    assert ir.INPUT_QOS == ir.QoS(reliability.replace(" ", "_"), durability, int(depth))


def queue_and_backlog(queue: str) -> None:
    assert ir.DEFAULT_QUEUE == int(queue) == core.BACKLOG


def queue_only(queue: str) -> None:
    assert ir.DEFAULT_QUEUE == int(queue)


def on_stale(word: str) -> None:
    assert ir.DEFAULT_ON_STALE == word


def publish_default(commands: str, other: str) -> None:
    assert topic_to_port("rate = 10\n").timing.publish == commands
    assert program(YARP_TO_PORT.replace("[output]", "[output]\nrate = 10")).timing.publish == other


def publish_new_for_commands(word: str) -> None:
    assert topic_to_port("rate = 10\n").timing.publish == word


def native_publisher_qos(text: str) -> None:
    """The QoS of the C++ module's publisher: the IR's, as the module prints it."""
    output_defaults_and_sensor_data(text)
    for config, qos in ((JOINT_STATE, ir.OUTPUT_QOS), (IMAGE, ir.SENSOR_DATA_QOS)):
        files = get_backend("cpp").render(program(config))
        said = {m.group(1) for t in files.values()
                for m in re.finditer(r"The ROS 2 publisher: \{topic, node, reliable, transient_local, depth\}: "
                                     r"(\w+, \w+, depth \d+)\.", t)}
        assert said == {f"{qos.reliability}, {qos.durability}, depth {qos.depth}"}, said


def sensor_data_for_images(reliability: str, depth: str) -> None:
    assert (ir.SENSOR_DATA_QOS.reliability.replace("_", " "), ir.SENSOR_DATA_QOS.depth) == (reliability, int(depth))
    assert "sensor_msgs/Image" in output.SENSOR_DATA_TYPES


def default_distro_ros2(distro: str) -> None:
    assert msgtypes.DEFAULT_DISTRO["ros2"] == distro


def service_timeout(seconds: str) -> None:
    assert ir.SERVICE_TIMEOUT == float(seconds)
    [service] = program(SERVICE).services
    assert service.timeout == float(seconds)


def true_words(words: str) -> None:
    assert tuple(w.strip() for w in words.split(",")) == ir.TRUE_WORDS
    [service] = program(SERVICE).services
    assert service.true_words == ir.TRUE_WORDS


def camera_info_topic(topic: str, example: str) -> None:
    assert images.CAMERA_INFO_TOPIC == topic
    p = compile_path(ROOT / "examples" / "icub_left_eye_ros2.ini", Options()).program
    assert p.output.name.rsplit("/", 1)[0] + "/" + topic == example == p.output.camera_info.topic


def calibration_coefficients(plumb: str, n_plumb: str, plumb_keys: str, fisheye: str, n_fisheye: str,
                             fisheye_keys: str) -> None:
    numbers = {"four": 4, "five": 5, "six": 6, "eight": 8}
    assert images.PLUMB_BOB == (plumb, tuple(plumb_keys.split())) and len(images.PLUMB_BOB[1]) == numbers[n_plumb]
    assert images.EQUIDISTANT == (fisheye, tuple(fisheye_keys.split()))
    assert len(images.EQUIDISTANT[1]) == numbers[n_fisheye]
    # iCub's left eye: its group gives k1 k2 p1 p2, and k3 is 0
    p = compile_path(ROOT / "examples" / "icub_left_eye_ros2.ini", Options()).program
    fields = {f.name: f.source for f in p.output.camera_info.message.fields}
    assert fields["distortion_model"].values == (plumb,)
    assert fields["d"].values == (-0.374173, 0.205428, 0.00282356, 0.00270998, 0.0)


def fmt_width(columns: str) -> None:
    assert fmt.WIDTH == int(columns)


def folder_config(name: str) -> None:
    assert cli.FOLDER_CONFIG == name


def composed_name(run) -> None:
    """The first folder named, else the folder of the first config."""
    tmp_path, ybgc = run.tmp_path, run.ybgc
    robot = tmp_path / "robo"
    robot.mkdir()
    (robot / "a.ini").write_text(YARP_TO_PORT.replace("name = m", "name = a"), encoding="utf-8")
    (robot / "b.ini").write_text(YARP_TO_PORT.replace("name = m", "name = b").replace("/m/out:o", "/b/out:o")
                                 .replace("/robot/arm:o", "/robot/leg:o"), encoding="utf-8")
    status, err = ybgc("compose", "robo", "--backend", "py", "-o", "by_folder")
    assert status == 0, err
    assert (tmp_path / "by_folder" / "robo.py").is_file()
    status, err = ybgc("compose", "robo/a.ini", "robo/b.ini", "--backend", "py", "-o", "by_config")
    assert status == 0, err
    assert (tmp_path / "by_config" / "robo.py").is_file()


def composed_params_file(run) -> None:
    """The launch file of a composed package reads config/<NAME>.yaml unless given another."""
    tmp_path, ybgc = run.tmp_path, run.ybgc
    for backend in ("ros2", "cpp"):
        status, err = ybgc("compose", ROOT / "examples" / "icub_robot" / "head.ini",
                           ROOT / "examples" / "icub_robot" / "torso.ini", "--backend", backend, "--name", "icub",
                           "--package", "-o", backend)
        assert status == 0, err
        [launch] = (tmp_path / backend).rglob("*.launch.py")
        spec = importlib.util.spec_from_file_location(f"launch_{backend}", launch)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        assert module.PARAMS_FILE == "icub.yaml", backend
        assert "DeclareLaunchArgument('params_file', default_value=default" in launch.read_text()
        assert [p.name for p in (tmp_path / backend).rglob("config/icub.yaml")], backend


#: (document, pattern, check): a check takes the pattern's groups
PROSE: list[tuple[str, str, Callable]] = [
    ("README.md", r"publishes\s+its state on `/diagnostics` \(`diagnostic_msgs/DiagnosticArray`\) every (second)",
     lambda _: diagnostics_period("1")),
    ("README.md", r"rate achieved \(Hz\) over the last (\d+) s", rate_window),
    ("README.md", r"WARN when a fixed rate falls below (\d+) % of the configured one", rate_tolerance),
    ("README.md", r"`--yarp VERSION` \(the YARP the module is for, e\.g\. `4\.0`: ROS 1 through YARP is then\s+"
                  r"an error, E320; default (any)\)", yarp_target_any),
    ("README.md", r"The folder's config is `([\w.]+)` if there is one", folder_config),
    ("docs/runtime.md", r"`diagnostics` \(bool, default (true|false)\)", diagnostics_on),
    ("docs/runtime.md", r"`diagnostic_updater\.period` \(seconds, default ([\d.]+)\)", diagnostics_period),
    ("docs/runtime.md", r"every `diagnostic_updater\.period` seconds of the steady\s+clock \(parameter, default "
                        r"([\d.]+)\)", diagnostics_period),
    ("docs/runtime.md", r"over the last (\d+) periods", lambda n: rate_window(n)),
    ("docs/runtime.md", r"\(`Timing\.queue` > 1, the default (\d+)\)", queue_and_backlog),
    ("docs/runtime.md", r"falls more than (\d+)\s+unread Bottles behind", queue_and_backlog),
    ("docs/runtime.md", r"`on_stale = (\w+)` \(default\)", on_stale),
    ("docs/runtime.md", r"The default is `\"(\w+)\"` for a bridge from ROS topics to a YARP port .*?"
                        r"`\"(\w+)\"` otherwise\.", publish_default),
    ("docs/runtime.md", r"else it keeps the newest message, best effort", input_qos_newest),
    ("docs/ros2-native.md", r"\(the defaults: (`\w+`, `\w+`, \d+;\s+for\s+[\w,\s]+? types `\w+`, `\w+`, \d+),\s+"
                            r"ROS's sensor-data profile: docs/config\.md, `\[output\]`\), as the rclpy\s+node's",
     lambda text: native_publisher_qos(re.sub(r"\s+", " ", text))),
    ("docs/ros2-native.md", r"else history keep-last (\d+),\s+(best effort) \(which takes the messages of reliable "
                            r"and best-effort\s+publishers alike\), (volatile)", input_qos_words),
    ("docs/ros2-native.md", r"\(`queue` in\s+\[output\], (\d+) by default\)", queue_only),
    ("docs/ros2-native.md", r"its port up to (\d+) unread", lambda n: queue_and_backlog(n)),
    ("docs/probe.md", r"\(`--wait`, default ([\d.]+) s\)", probe_wait),
    ("README.md", r"written into `DIR` \(default `\./<robot>`\)", lambda: init_output("`./<robot>`")),
    ("docs/probe.md", r"`<prefix>` is `(/<module>)`, or what\s+`--prefix` says", probe_prefix),
    ("docs/probe.md", r"its inputs (best effort, newest only)", input_qos_newest),
    ("docs/services.md", r"timeout = 5\.0 +# seconds \(default ([\d.]+)\)", service_timeout),
    ("docs/services.md", r"`timeout = <seconds>` \(default ([\d.]+)\)", service_timeout),
    ("docs/services.md", r"one of `true_words` \(default `([\w, ]+)`\)", true_words),
    ("docs/services.md", r"replacing the\s+default `([\w, ]+)`\.", true_words),
    ("docs/config.md", r"long lists wrapped at (\d+)\s+columns", fmt_width),
    ("docs/config.md", r"\(by default `(\w+)` beside the\s+image's topic: `(/[\w/]+)`\)", camera_info_topic),
    ("docs/config.md", r"`(plumb_bob)`, whose `d` holds\s+(\w+) coefficients, `([\w ]+)` \(a coefficient the group "
                       r"does not\s+give is 0: iCub's files give no `k3`\); with `projection fisheye` in the\s+"
                       r"group, `(equidistant)`, whose `d` holds (\w+), `([\w ]+)`", calibration_coefficients),
    ("docs/diagnostics.md", r"\(`publish = (\w+)`, the default there\)", publish_new_for_commands),
    ("docs/ros2-distros.md", r"`--distro (\w+)` is its default", default_distro_ros2),
    ("docs/benchmarks.md", r"publish (best effort), keep last (\d+) \(the sensor-data QoS, the modules' default for "
                           r"an Image\)", sensor_data_for_images),
    ("docs/benchmarks.md", r"its default `queue` \((\d+)\)", queue_only),
    ("docs/benchmarks.md", r"\(`queue`, (\d+) frames by default\)", queue_only),
    ("docs/benchmarks.md", r"\((\d+) Bottles by default: the p99", queue_only),
    ("docs/benchmarks.md", r"every bridge publishes best effort \(the modules' default for an Image\)",
     lambda: sensor_data_for_images("best effort", str(ir.SENSOR_DATA_QOS.depth))),
]

def hypothesis_profile(run) -> None:
    """The property tests' profile when none is chosen: ci, derandomized."""
    from hypothesis import settings

    from harness import properties

    run.monkeypatch.delenv(properties.PROFILE_VARIABLE, raising=False)
    # the profile the session loaded stays loaded
    run.monkeypatch.setattr(properties, "settings", SimpleNamespace(load_profile=lambda name: None))
    assert properties.load() == "ci" and settings.get_profile("ci").derandomize


#: (document, pattern, check of ``run``: the test's tmp_path, ybgc and
#: monkeypatch): the defaults of what the commands do, run
FS_CHECKS: list[tuple[str, str, Callable]] = [
    ("README.md", r"derandomized \(its `ci` profile, the default\)", hypothesis_profile),
    ("README.md", r"generate a module into `DIR` \(default `\./<module>`\), atomically, with ybgc's runtime library "
                  r"beside it", generated_into_module_folder),
    ("docs/files.md", r"the module's files in `DIR` \(default `\./<module>`\)", generated_into_module_folder),
    ("docs/runtime.md", r"By default ybgc writes the runtime\s+beside the module, in the output folder",
     generated_into_module_folder),
    ("docs/runtime.md", r"use the default to read the module\.", generated_into_module_folder),
    ("README.md", r"written to `\./<module>\.svg` by default", graph_into_module_svg),
    ("docs/files.md", r"`FILE`, default `\./<module>\.svg`", graph_into_module_svg),
    ("docs/compose.md", r"`NAME` \(default:\s+the first folder named, else the folder of the first config\)",
     composed_name),
    ("docs/compose.md", r"starts the one\s+executable with `params_file` \(default: that file\)", composed_params_file),
    ("docs/compose.md", r"it starts the\s+executable with `params_file` \(default: that file\)", composed_params_file),
]

#: the word "default" used of something else than a value ybgc chooses
NOT_A_VALUE: list[tuple[str, str]] = [
    ("README.md", r"into the venv by\s+default"),  # build_msgpkg.sh's prefix: tests/test_msgpkgs.py
    ("docs/architecture.md", r"literal values and defaults"),
    ("docs/architecture.md", r"`tests/test_docs_defaults\.py`"),  # this test
    ("docs/config.md", r"get\s+their\s+default"),
    ("docs/config.md", r"each one not given keeping its defaults"),
    ("docs/config.md", r"YARP's default of the newest Bottle only"),
    ("docs/config.md", r"the default port prefix `/<name>`"),  # runtime.md's --name, checked above
    ("docs/runtime.md", r"YARP's default,"),
    ("docs/runtime.md", r"as YARP\s+does by default"),
    ("docs/runtime.md", r"`Default` -> the type's default: 0, `\"\"`, empty list, a fixed array of N\s+defaults, "
                        r"a nested message of defaults"),
    ("docs/runtime.md", r"8 bytes by\s+default"),  # YARP's quantum
    ("docs/ros2-native.md", r"the\s+definition's\s+defaults?"),
    ("docs/graph.md", r"fields left to their default are not drawn"),
    ("docs/ros2-native.md", r"its definition's defaults"),
    ("docs/compose.md", r"with\s+its config's defaults"),
    ("docs/diagnostics.md", r"an element not given its defaults"),
    ("docs/diagnostics.md", r"the system default or unknown"),
    ("docs/probe.md", r"left to the system\s+default or unknown"),
    ("docs/probe.md", r"rmw's defaults"),
    ("docs/services.md", r"every other field keeps its default"),
    ("docs/benchmarks.md", r"as YARP does by default"),
    ("docs/benchmarks.md", r"YARP's default"),
    ("docs/benchmarks.md", r"FASTDDS_DEFAULT_PROFILES_FILE"),
    ("docs/benchmarks.md", r"Fast DDS's default"),
    ("docs/benchmarks.md", r"Strict writes \(the default of `bench/tools/producer\.cpp`"),
    ("docs/benchmarks.md", r"rcl's default of 10"),
]


def text_of(doc: str) -> str:
    return (ROOT / doc).read_text(encoding="utf-8")


def found(doc: str, pattern: str) -> re.Match:
    matches = list(re.finditer(pattern, text_of(doc), re.S))
    assert len(matches) == 1, (f"{doc} should say /{pattern}/ once, not {len(matches)} times: "
                               "read the default it says now and hold it to the code here")
    return matches[0]


@pytest.mark.parametrize("doc, pattern, check", PROSE, ids=[f"{d}:{p[:40]}" for d, p, _ in PROSE])
def test_each_default_said_in_prose_is_the_codes(doc, pattern, check):
    check(*found(doc, pattern).groups())


@pytest.mark.parametrize("doc, pattern, check", FS_CHECKS, ids=[f"{d}:{p[:40]}" for d, p, _ in FS_CHECKS])
def test_each_default_of_a_command_is_what_it_does(doc, pattern, check, tmp_path, ybgc, monkeypatch):
    found(doc, pattern)
    check(SimpleNamespace(tmp_path=tmp_path, ybgc=ybgc, monkeypatch=monkeypatch))


def test_every_default_the_documentation_says_is_held_to_the_code():
    """Each "default" of README.md and docs/*.md is in a table of defaults,
    a sentence checked above, or said of something else (NOT_A_VALUE)."""
    spans: dict[str, list[tuple[int, int]]] = {}
    for doc, table in default_tables():
        lines = text_of(doc).splitlines(keepends=True)
        start = sum(len(line) for line in lines[:table.first - 1])
        spans.setdefault(doc, []).append((start, start + sum(len(line) for line in lines[table.first - 1:table.last])))
    for doc, pattern, *_ in (*PROSE, *FS_CHECKS):
        spans.setdefault(doc, []).append(found(doc, pattern).span())
    for doc, pattern in NOT_A_VALUE:
        other = [m.span() for m in re.finditer(pattern, text_of(doc), re.S)]
        assert other, f"{doc} no longer says /{pattern}/: drop it from NOT_A_VALUE"
        spans.setdefault(doc, []).extend(other)
    loose = []
    for path in documents():
        doc, text = name_of(path), path.read_text(encoding="utf-8")
        for m in re.finditer(r"default", text, re.I):
            if not any(a <= m.start() < b for a, b in spans.get(doc, [])):
                line = text.count("\n", 0, m.start()) + 1
                loose.append(f"{doc}:{line}: ...{text[max(0, m.start() - 60):m.end() + 40]!r}...")
    assert not loose, "defaults the documentation says that no test holds to the code:\n" + "\n".join(loose)


# --------------------------------------------------------------------------
# what the documentation says of the code, beside its defaults


def test_true_words_are_compared_as_written():
    """docs/services.md: a word is true when it is one of `true_words`
    exactly, case and all; a number when it is not 0 (the Python runtime;
    the C++ runtime's own test, tests/test_services_cpp_unit.py)."""
    assert re.search(r"exactly, case and all \(`OK` and `Ok`\s+are not `ok`", text_of("docs/services.md"))
    services = pytest.importorskip("ybg.runtime.services")
    yarp = pytest.importorskip("yarp")
    reply = yarp.Bottle()
    for word in ("ok", "OK", "Ok", "done", "nope"):
        reply.addString(word)
    reply.addInt32(0)
    reply.addInt32(2)
    reply.addVocab32("ack")
    e = services.Elements(reply, 0, None, (), ir.TRUE_WORDS)
    assert [e.bool(k) for k in range(reply.size())] == [True, False, False, True, False, False, True, True]


def test_the_python_bindings_have_no_buffered_port_of_flex_images():
    """docs/runtime.md: why the Python node writes images on a plain Port."""
    said = re.search(r"the bindings\s+have a `BufferedPort` of some image types, (.*?), but none of `FlexImage`",
                     text_of("docs/runtime.md"), re.S)
    assert said, "docs/runtime.md no longer says which BufferedPorts of images the bindings have"
    yarp = pytest.importorskip("yarp")
    named = re.findall(r"`(\w+)`", said.group(1))
    assert named and all(hasattr(yarp, n) for n in named), named
    assert not any("FlexImage" in n for n in dir(yarp) if n.startswith("BufferedPort"))
    assert hasattr(yarp, "FlexImage") and not hasattr(yarp, "BufferedPortImageBgr")
