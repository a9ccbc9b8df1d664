"""ROS 2 Jazzy, the distro labs run, as the second ROS 2 of the matrix: the
project's wheels are Kilted's (.venv), Jazzy's are in .venv-jazzy
(scripts/setup.sh). docs/ros2-distros.md.

One graph for the whole file, on YARP 4.0.0 (whose Python bindings the Jazzy
node imports) and one ROS 2 domain, fed by the same two YARP producers
(harness.programs.DIFF_TF: tf2_msgs/TFMessage, two transforms from two muxes
with geometry converters):

- the native module built against Kilted's wheels, on ``/diff/tf_kilted``,
  read by a Kilted subscriber (the reference) and a Jazzy one;
- the same module built against Jazzy's wheels, on ``/diff/tf_jazzy``, read
  by a Jazzy subscriber and a Kilted one;
- the rclpy node run by the Jazzy venv's Python, on ``/diff/tf_node``, read by
  a Jazzy subscriber.

Every subscriber receives every message, the same bit for bit as the Kilted
reference: Kilted and Jazzy interoperate on Fast DDS both ways. Then the
other direction of a bridge: a Jazzy publisher to the ROS 2 input of the
Kilted-built native module and of the Kilted rclpy node
(harness.programs.QOS_READER), into a YARP port. ``ybgc probe``
checks the endpoints of either distro as its own (their type hashes, their
QoS) before a module runs. And what mixes the two distros in one process: a
Jazzy Python, or a Jazzy-built module, started with the library path a
Kilted Python sets (tests/harness/jazzy.py).
"""
from __future__ import annotations

import dataclasses
import json
import random
import signal
import subprocess
from pathlib import Path
from types import SimpleNamespace

import pytest

from harness.build import Builds
from harness.differential import float_bits
from harness.env import VENV, VENV_PYTHON, clean_environ
from harness.jazzy import (JAZZY_PYTHON, JAZZY_VENV, NODE_YARP, JazzyPublisher, JazzySubscriber,
                           jazzy_env, kilted_inherited, require_jazzy)
from harness.launchers import write_node
from harness.module import EXIT_BOUND, Module
from harness.programs import DIFF_TF, QOS_READER, diff_tf_program, text_program
from harness.ros2 import Ros2Domain, Ros2Subscriber, ros2_environment
from harness.yarp import YarpProducer, YarpReader, YarpServer

TF = "tf2_msgs/msg/TFMessage"
ROUNDS = 5


def on_topic(program, suffix: str):
    """``program`` renamed (module and topic) with ``suffix``."""
    return dataclasses.replace(program, module=f"{program.module}_{suffix}",
                               output=dataclasses.replace(program.output,
                                                          name=f"{program.output.name}_{suffix}"))


def built(tmp_path_factory, ros2_env, *programs) -> list:
    """The native modules of ``programs`` built in one CMake project against
    YARP 4.0.0 and the ROS 2 wheels of ``ros2_env``."""
    builds = Builds(tmp_path_factory.mktemp(f"native_{ros2_env.name}"), NODE_YARP, ros2_env=ros2_env)
    for program in programs:
        builds.add(program.module, program)
    return [builds.exe(program.module) for program in programs]


def reader_program(backend: str):
    """harness.programs.QOS_READER: the ROS 2 topic /qos/goal, a
    geometry_msgs/Point, into the YARP port /qos_reader/out:o."""
    return text_program(QOS_READER, "qos_reader.ini", backend)


@pytest.fixture(scope="module")
def graph(tmp_path_factory):
    require_jazzy()
    base = diff_tf_program()
    programs = {s: on_topic(base, s) for s in ("kilted", "jazzy", "node")}
    kilted_prog, jazzy_prog, node_prog = programs.values()
    kilted_exe, reader_exe = built(tmp_path_factory, VENV, kilted_prog, reader_program("cpp"))
    jazzy_exe, = built(tmp_path_factory, JAZZY_VENV, jazzy_prog)
    node_path = write_node(node_prog, tmp_path_factory.mktemp("jazzy_node"))
    with YarpServer(install=NODE_YARP) as server, Ros2Domain() as domain:
        env = ros2_environment(server.env, domain)
        jenv = jazzy_env(env)
        native = {"kilted": Module([kilted_exe], env=env, name=kilted_prog.module),
                  "jazzy": Module([jazzy_exe], env=jenv, name=jazzy_prog.module)}
        node = Module([JAZZY_PYTHON, node_path], env=jenv, name=node_prog.module)
        topic = {k: p.output.name for k, p in programs.items()}
        # (publisher's distro, subscriber's distro): the subscriber
        subs = {("kilted", "kilted"): Ros2Subscriber(env, topic["kilted"], TF, node="kilted_of_kilted"),
                ("kilted", "jazzy"): JazzySubscriber(env, topic["kilted"], TF, node="jazzy_of_kilted"),
                ("jazzy", "jazzy"): JazzySubscriber(env, topic["jazzy"], TF, node="jazzy_of_jazzy"),
                ("jazzy", "kilted"): Ros2Subscriber(env, topic["jazzy"], TF, node="kilted_of_jazzy"),
                ("node", "jazzy"): JazzySubscriber(env, topic["node"], TF, node="jazzy_of_node")}
        producers = {i.name: YarpProducer(env, i.name) for m in base.muxes for i in m.inputs}
        procs = [*native.values(), node, *subs.values(), *producers.values()]
        try:
            for p in procs:
                p.start()
            node.wait_log("event-driven")
            for producer in producers.values():
                producer.wait_outputs(3)
            for s in subs.values():
                s.wait_publishers(1)
            yield SimpleNamespace(env=env, native=native, node=node, subs=subs, producers=producers,
                                  reader_exe=reader_exe)
        finally:
            for p in reversed(procs):
                p.stop()


HAND = [0.25, -1.5, 3.0, 10.0, 20.0, -30.0]        # x y z, roll pitch yaw in degrees
TOOL = [0.5, 4.0, -6.0, 0.0, 0.0, 1.0, 0.75]        # x y z (clamped, halved), axis, angle


def write_round(graph, k: int, stamp: float) -> None:
    """One Bottle to each port, with an envelope: one message of each publisher."""
    graph.producers["/diff/hand:o"].write([v + k for v in HAND], stamp=[k, stamp])
    graph.producers["/diff/tool:o"].write(TOOL, stamp=[k, stamp + 0.5])


def until_through(send, peers) -> None:
    """A message published before a subscription has matched its publisher
    is lost (volatile QoS): ``send()`` every half second until each of
    ``peers`` (subscribers, YARP readers) has one (at most 30 s), then
    forget those. A later copy of it, sent for a peer still waiting, may
    still reach one after that: the test leaves it out by its values."""
    pending = list(peers)
    for _ in range(60):
        send()
        for p in list(pending):
            try:
                p.wait_for(1, timeout=0.5)
                pending.remove(p)
            except TimeoutError:
                pass
        if not pending:
            break
    assert not pending, f"nothing reached {[p.name for p in pending]} in 30 s"
    for p in peers:
        p.clear()


def test_kilted_and_jazzy_publishers_and_subscribers_exchange_the_same_messages(graph):
    warm_up = {"sec": 1700000000, "nanosec": 0}

    def rounds(s) -> list:  # the rounds' messages: a late warm-up's left out
        return [m for m in s.messages if m.msg["transforms"][0]["header"]["stamp"] != warm_up]
    until_through(lambda: write_round(graph, 0, 1.7e9), graph.subs.values())
    rng = random.Random(29)
    stamps = [1.7e9 + rng.uniform(0, 1e6) for _ in range(ROUNDS)]
    for k, stamp in enumerate(stamps):
        write_round(graph, k + 1, stamp)
        for s in graph.subs.values():
            s.wait(lambda: len(rounds(s)) >= k + 1, 60, f"{k + 1} messages")
    got = {route: [float_bits(m.msg) for m in rounds(s)] for route, s in graph.subs.items()}
    reference = got[("kilted", "kilted")]
    assert len(reference) == ROUNDS
    for route, msgs in got.items():
        assert msgs == reference, f"{route[0]} publisher -> {route[1]} subscriber"
    # and they are the messages the config makes of the Bottles
    for k, (msg, stamp) in enumerate(zip((m.msg for m in rounds(graph.subs[("kilted", "jazzy")])), stamps)):
        hand, tool = msg["transforms"]
        assert (hand["child_frame_id"], tool["child_frame_id"]) == ("r_hand", "r_tool")
        t = hand["transform"]["translation"]
        assert [t["x"], t["y"], t["z"]] == [v + k + 1 for v in HAND[:3]]
        assert tool["transform"]["translation"] == {"x": 0.25, "y": 0.0, "z": -1.0}
        assert hand["header"]["stamp"]["sec"] == int(stamp)


def venv_libraries(pid: int) -> set[str]:
    """The venvs (.venv, .venv-jazzy) whose libraries process ``pid`` has loaded."""
    maps = Path(f"/proc/{pid}/maps").read_text()
    venvs = (VENV, JAZZY_VENV)
    return {v.name for line in maps.splitlines() for v in venvs if f"{v}/" in line.split()[-1]}


def test_each_native_build_loads_the_libraries_of_its_distro(graph):
    # the module's RPATH names the wheels it was built against; the Jazzy
    # one runs in the Jazzy venv's environment (jazzy_env), as the node does
    assert venv_libraries(graph.native["kilted"].pid) == {VENV.name}
    assert venv_libraries(graph.native["jazzy"].pid) == {JAZZY_VENV.name}
    assert venv_libraries(graph.node.pid) == {JAZZY_VENV.name}


def test_a_jazzy_build_started_with_the_kilted_library_path_mixes_the_two(graph):
    # what a process started by a Kilted Python inherits (its LD_LIBRARY_PATH,
    # tests/harness/jazzy.py) wins over the RPATH for the type supports that
    # rosidl loads by name: the Jazzy module then runs with Kilted's libraries
    # of geometry_msgs in it. Run a module in its own distro's environment.
    probe = Module([graph.native["jazzy"].argv[0], "--prefix", "/jazzy_probe"],
                   env=kilted_inherited(graph.env), name="jazzy_probe")
    with probe:
        probe.wait_log("publishing tf2_msgs/msg/TFMessage")
        assert venv_libraries(probe.pid) == {VENV.name, JAZZY_VENV.name}


@pytest.mark.parametrize("backend", ["cpp", "ros2"])
def test_a_jazzy_publisher_feeds_a_kilted_module(graph, tmp_path, backend):
    # the other direction of a bridge: a ROS 2 topic of Jazzy into a YARP
    # port through the native module built against Kilted, and through the
    # rclpy node on Kilted
    program = reader_program(backend)
    argv = [graph.reader_exe] if backend == "cpp" else [VENV_PYTHON, write_node(program, tmp_path)]
    module = Module(argv, env=graph.env, name=f"{program.module}_{backend}")
    reader = YarpReader(graph.env, "/jazzy_test/in", source=program.output.name)
    publisher = JazzyPublisher(graph.env, program.muxes[0].inputs[0].name, msg_type="geometry_msgs/msg/Point",
                               node="jazzy_point")

    def rounds() -> list:  # the points' Bottles: a late warm-up's (x = -1) left out
        return [b.data for b in reader.bottles if b.data[0] != -1.0]
    with module, reader, publisher:
        reader.wait_connected()
        publisher.wait_matched(1)
        until_through(lambda: publisher.publish({"x": -1.0, "y": 0.0, "z": 0.0}), [reader])
        points = [{"x": 0.1 * k, "y": -2.0 ** k, "z": 1e-300 * k} for k in range(1, ROUNDS + 1)]
        for k, p in enumerate(points):  # each read before the next (the input keeps the newest)
            publisher.publish(p)
            got = reader.wait(lambda: len(rounds()) >= k + 1 and rounds(), 60, f"{k + 1} points")
    assert got == [[p["x"], p["y"], p["z"]] for p in points]


def test_a_jazzy_python_with_the_kilted_library_path_cannot_import_rclpy(tmp_path):
    # what jazzy_env is for: a Python of ROS 2 wheels re-executes itself once
    # with its wheels' libraries on LD_LIBRARY_PATH, and marks that done; a
    # Jazzy Python started by a Kilted one inherits both, and fails
    require_jazzy()
    code = "import rclpy; rclpy.init(); rclpy.create_node('probe'); print('ok')"
    inherited = subprocess.run([str(JAZZY_PYTHON), "-c", code], capture_output=True, text=True,
                               env=kilted_inherited(clean_environ()), timeout=60)
    assert inherited.returncode != 0 and "libfastrtps.so.2.14" in inherited.stderr, inherited.stderr[-2000:]
    own = subprocess.run([str(JAZZY_PYTHON), "-c", code], capture_output=True, text=True,
                         env={**jazzy_env(kilted_inherited(clean_environ())), "ROS_HOME": str(tmp_path)},
                         timeout=60)
    assert own.returncode == 0 and own.stdout.strip() == "ok", own.stderr[-2000:]


@pytest.mark.parametrize("distro,topic", [("kilted", "/diff/tf_jazzy"), ("jazzy", "/diff/tf_kilted")])
def test_the_probe_checks_the_other_distros_endpoints_as_its_own(graph, tmp_path, distro, topic):
    # ybgc probe (Kilted's rclpy), before a module of ``distro`` joins the
    # topic that publishers and subscribers of both distros are on: each
    # endpoint seen, its type hash that of the definition checked (no E374),
    # its QoS compatible; the endpoints' hashes are read (a definition of one
    # field more: E374 for each of them)
    config = tmp_path / "probe_tf.ini"
    config.write_text(DIFF_TF.replace("name = diff_tf", "name = probe_tf")
                      .replace("topic = /diff/tf\n", f"topic = {topic}\n"), encoding="utf-8")
    other = tmp_path / "msgs" / "tf2_msgs"
    other.mkdir(parents=True)
    (other / "TFMessage.msg").write_text("geometry_msgs/TransformStamped[] transforms\nuint8 more\n")

    def probe(wait, *options):
        r = subprocess.run([str(VENV / "bin" / "ybgc"), "probe", str(config), "--distro", distro, "-v",
                            "--format", "json", "--wait", str(wait), *options], env=graph.env,
                           capture_output=True, text=True, timeout=60)
        return r.returncode, {d["code"]: d["message"] for d in json.loads(r.stdout or "[]")
                              if d["code"] != "N670" or topic in d["message"]}, r.stderr

    rc, found, err = probe(4)  # discovery of every endpoint, node names too, on a busy machine
    assert rc == 0 and set(found) == {"N670", "W570"}, (found, err)  # W570: the producers are quiet
    for endpoint in ({"/diff/tf_jazzy": "/diff_tf_jazzy", "/diff/tf_kilted": "/diff_tf_kilted"}[topic],
                     "/kilted_of_", "/jazzy_of_"):
        assert endpoint in found["N670"], found["N670"]
    rc, found, err = probe(2, "--msg-path", str(tmp_path / "msgs"))
    assert rc == 1 and "E374" in found, (found, err)


def test_each_native_module_stops_on_sigint(graph):
    # with 0 within 2 s, whichever ROS 2 it was built for
    for module in graph.native.values():
        rc, elapsed = module.interrupt(signal.SIGINT)
        assert rc == 0 and elapsed < EXIT_BOUND, module.log_text()[-2000:]
        assert "Traceback" not in module.log_text()
