"""``ybgc compose`` with the Python backends (docs/compose.md): several
configs, one process.

- ``ros2``: the 14 configs of a whole iCub (examples/icub_robot/) composed
  and run end to end in one process, one rclpy context: a real YARP producer
  on every input port, real rclpy subscribers on every topic, a trajectory
  published into YARP; every bridge's values; every node on the graph, all
  of one DDS participant, one process; isolation (a producer stalled for
  5 s, a ROS 2 subscriber and a YARP reader stalled, malformed Bottles on one
  bridge: the other bridges keep their rate within 1 %, the stalled one
  publishes nothing stale); `stats` and `quit` on ``/icub/rpc:i``. One
  composed process serves every test of the class.
- ``ros2 --package``: one ament_python package, one executable, a launch
  file and the parameter file keyed by node name.
- ``py``: three YARP-output configs in one process, one of them unable to
  start (its output port taken): the others' values, `stats`, exit 1.
"""
from __future__ import annotations

import ast
import re
import time
from types import SimpleNamespace

import pytest

from harness.compose import (DEG, DIAGNOSTICS_PERIOD, ICUB, IMAGE_TOPIC, PRODUCER_HZ, bridge_stats, bridge_totals,
                             check_isolation, check_one_process, check_stats_and_quit, check_values, composed_stats,
                             run_parallel, start_peers)
from harness.env import EXAMPLES, VENV_PYTHON, yarp_install
from harness.generated import ybgc
from harness.module import EXIT_BOUND, Node, quit_over_rpc
from harness.procs import Proc, wait_until
from harness.ros2 import Ros2Domain, ros2_environment
from harness.yarp import YarpProducer, YarpReader, YarpServer, rpc
from ybg.compiler.pipeline import compile_path


# --------------------------------------------------------------------------
# the composed iCub (its peers and checks: tests/harness/compose.py, shared
# with tests/test_compose_cpp.py)


@pytest.fixture(scope="module")
def icub(tmp_path_factory):
    """The iCub composed (ybgc compose --backend ros2) and running, with a
    producer on every input port and a subscriber on every topic."""
    tmp = tmp_path_factory.mktemp("icub")
    out = tmp / "icub"
    configs = sorted(ICUB.glob("*.ini"))
    r = ybgc("compose", *configs, "--backend", "ros2", "--name", "icub", "-o", out)
    assert r.returncode == 0, r.stdout + r.stderr
    programs = {p.module: p for p in (compile_path(c).program for c in configs)}
    peers = None
    with Ros2Domain() as domain, YarpServer(install=yarp_install("3.5")) as server:
        env = ros2_environment(server.env, domain)
        try:
            t0 = time.monotonic()
            peers = start_peers(env, programs)
            # the image subscriber is reliable: the left eye's publisher made so by a
            # parameter of its node alone (its QoS override)
            # /diagnostics twice a second, every node (the rates measured from it)
            node = Node(env, out / "icub_node.py", "--ros-args", "-p",
                        f"icub_left_eye:qos_overrides.{IMAGE_TOPIC}.publisher.reliability:=reliable",
                        "-p", f"diagnostic_updater.period:={DIAGNOSTICS_PERIOD}")
            node.start()
            node.wait_log("icub: 14 bridges running", timeout=60)
            started = time.monotonic() - t0
            yield SimpleNamespace(env=env, server=server, node=node, out=out, programs=programs,
                                  started=started, **vars(peers))
        finally:
            for p in (peers.peers if peers is not None else []):
                p.stop()
            Node.started[:] = [n for n in Node.started if n.name != "icub_node"]


@pytest.fixture(autouse=True)
def _print_node_logs():
    """The logs of the composed processes a test ran, shown when it fails."""
    yield
    for node in Node.started:
        print(f"---- log of {node.name}:\n{node.log_text()[-6000:]}")


class TestComposedIcub:
    """examples/icub_robot, 14 configs, one process (the shared fixture)."""

    def test_every_bridge_publishes_its_values(self, icub):
        """Joint names and radians of every part on /joint_states, the four
        wrenches, the IMU's quaternion, both hands on /tf, the camera's
        image and a MoveIt trajectory's rows into YARP: all through the one
        process."""
        check_values(icub)

    def test_one_process_one_participant_a_node_per_bridge(self, icub):
        """Every bridge's node is on the graph with its own name; their
        /diagnostics writers all belong to one DDS participant (one GUID
        prefix); the module is one process."""
        check_one_process(icub)

    def test_a_stall_or_malformed_bottles_delay_no_other_bridge(self, icub):
        """A stalled producer, a stalled subscriber, a stalled YARP reader and
        malformed Bottles, each in one bridge, delay no other: the checks of
        tests/harness/compose.py's check_isolation (shared with the native
        module's test)."""
        check_isolation(icub)

    def test_stats_and_quit_on_the_rpc_port(self, icub):
        """`help`, `stats` (a list per bridge: its name then its own stats)
        and `quit` on /icub/rpc:i: every bridge stops, prints its totals
        under its name, the process exits 0 (EXIT_BOUND after its `[bye]`);
        no bridge's own RPC port is open. It feeds every bridge itself (it
        stands alone)."""
        check_stats_and_quit(icub)


# --------------------------------------------------------------------------
# ros2 --package: one ament_python package, one executable


def test_ros2_package_one_executable_parameters_by_node_name(tmp_path):
    """`ybgc compose --backend ros2 --package`: one ament_python package with
    one executable, the bridges' nodes a subpackage, the runtime inside; its
    launch file starts the one executable with the parameter file keyed by
    node name, and run with that file each node takes its own values."""
    import yaml

    out = tmp_path / "duo"
    configs = [ICUB / "head.ini", ICUB / "torso.ini"]
    r = ybgc("compose", *configs, "--backend", "ros2", "--name", "duo", "--package", "-o", out)
    assert r.returncode == 0, r.stdout + r.stderr
    files = {str(p.relative_to(out)) for p in out.rglob("*") if p.is_file() and "ybgc_runtime" not in p.parts}
    assert files == {"package.xml", "setup.py", "setup.cfg", "resource/duo", "launch/duo.launch.py",
                     "config/duo.yaml", "duo/__init__.py", "duo/duo_node.py", "duo/bridges/__init__.py",
                     "duo/bridges/icub_head_node.py", "duo/bridges/icub_torso_node.py"}, files
    assert (out / "duo" / "ybgc_runtime" / "compose.py").exists()
    setup = (out / "setup.py").read_text()
    assert "'duo_node = duo.duo_node:main'" in setup and setup.count("= duo.") == 1
    assert "package_name + '.bridges'" in setup and "'config/duo.yaml'" in setup
    assert "from .. import ybgc_runtime" in (out / "duo" / "bridges" / "icub_head_node.py").read_text()
    depends = re.findall(r"<exec_depend>(\S+)</exec_depend>", (out / "package.xml").read_text())
    assert {"rclpy", "diagnostic_msgs", "sensor_msgs"} <= set(depends)
    params = yaml.safe_load((out / "config" / "duo.yaml").read_text())
    assert params == {node: {"ros__parameters": {"rate": 100.0, "timeout": 0.0, "prefix": "/" + node,
                                                 "verbose": False, "diagnostics": True}}
                      for node in ("icub_head", "icub_torso")}
    launch = ast.parse((out / "launch" / "duo.launch.py").read_text())
    consts = {t.id: ast.literal_eval(n.value) for n in launch.body if isinstance(n, ast.Assign)
              for t in n.targets}
    assert consts == {"PACKAGE": "duo", "EXECUTABLE": "duo_node", "PARAMS_FILE": "duo.yaml",
                      "NODES": ("icub_head", "icub_torso")}
    assert "name=" not in (out / "launch" / "duo.launch.py").read_text().split("Node(", 1)[1].split(")")[0]
    # the executable, as `ros2 run` starts it, with a parameter file of other values
    params["icub_head"]["ros__parameters"]["rate"] = 25.0
    params["icub_torso"]["ros__parameters"]["prefix"] = "/torso_elsewhere"
    mine = tmp_path / "mine.yaml"
    mine.write_text(yaml.safe_dump(params))
    with Ros2Domain() as domain, YarpServer(install=yarp_install("3.5")) as server:
        env = ros2_environment(server.env, domain)
        node = Proc([VENV_PYTHON, "-c", "import sys; from duo.duo_node import main; sys.exit(main())",
                     "--ros-args", "--params-file", mine], env=env, cwd=out, name="duo_node")
        node.start()
        try:
            wait_until(lambda: "duo: 2 bridges running" in node.log_text(), 60, "the bridges", node)
            stats = composed_stats(server, "/duo/rpc:i")
            assert bridge_stats(stats["icub_head"])["rate"][1] == "25.0", stats
            assert bridge_stats(stats["icub_torso"])["rate"][1] == "100.0", stats
            ports = server.yarp("name", "list").stdout
            assert "/torso_elsewhere/joints/in0:i" in ports and "/icub_head/joints/in0:i" in ports, ports
            assert "[bye]" in rpc(server, "/duo/rpc:i", "quit")
            assert node.popen.wait(10) == 0, node.log_text()[-3000:]
        finally:
            node.stop()


# --------------------------------------------------------------------------
# ros2: configs of commands among the bridges


def test_ros2_commands_among_the_bridges(tmp_path):
    """Two configs of commands composed with a stream config: a ROS 2 service
    served by calling a YARP RPC port (home_arm_trigger.ini), and a YARP RPC
    port served by calling a ROS 2 service (yarp_rpc_to_ros2.ini, the port
    named like the module's own RPC port): each call answered in the one
    process, its counts in the process's `stats` and in its totals under its
    name; the commands' own `stats`/`quit` are the process's, not the port's."""
    from harness.services import RpcClient, RpcServer, ServiceClient, ServiceServer, reply, require_services

    require_services()
    out = tmp_path / "mix"
    configs = [ICUB / "head.ini", EXAMPLES / "home_arm_trigger.ini", EXAMPLES / "yarp_rpc_to_ros2.ini"]
    r = ybgc("compose", *configs, "--backend", "ros2", "--name", "mix", "-o", out)
    assert r.returncode == 0, r.stdout + r.stderr
    assert {p.name for p in (out / "bridges").iterdir()} == {"icub_head_node.py", "left_arm_homing_node.py",
                                                             "robot_gate_node.py"}
    with Ros2Domain() as domain, YarpServer(install=yarp_install("3.5")) as server:
        env = ros2_environment(server.env, domain)
        homing = RpcServer(env, "/icub/left_arm/homing/rpc:i", [reply("home", "ok")])
        robot = ServiceServer(env, {"/robot/home": {"type": "std_srvs/srv/Trigger",
                                                    "response": {"success": True, "message": "homed"}}})
        caller = ServiceClient(env, {"/icub/left_arm/home": "std_srvs/srv/Trigger"})
        gate = RpcClient(env, "/robot_gate/rpc:i")
        peers = [homing, robot, caller]
        try:
            run_parallel(*(p.start for p in peers))
            node = Node(env, out / "mix_node.py")
            node.start()
            node.wait_log("mix: 3 bridges running")
            caller.wait_service("/icub/left_arm/home")
            got = caller.call("/icub/left_arm/home")
            assert got.response == {"success": True, "message": "ok"}, got
            assert homing.wait_commands(1)[-1]["data"] == ["home", "all"]
            gate.start()
            peers.append(gate)
            gate.connect()
            answer = gate.call(["home"])
            assert answer.ok and "homed" in answer.text, answer
            stats = composed_stats(server, "/mix/rpc:i")
            assert sorted(stats) == ["icub_head", "left_arm_homing", "robot_gate"], stats
            assert stats["left_arm_homing"] == "(service home calls 1 answered 1 failed 0 timed_out 0 no_server 0 " \
                                               "unfit 0)", stats
            assert "(service home calls 1 answered 1 failed 0" in stats["robot_gate"], stats
            assert "(service track calls 0" in stats["robot_gate"], stats
            assert "quit" not in gate.call(["help"]).text  # the port's own commands, not the process's
            assert "[bye]" in rpc(server, "/mix/rpc:i", "quit")
            assert node.popen.wait(10) == 0, node.log_text()[-3000:]
            log = node.log_text()
            assert "Traceback" not in log
            assert re.search(r"^left_arm_homing: service home: calls 1, answered 1, failed 0", log, re.M), log[-2000:]
            assert re.search(r"^robot_gate: service home: calls 1, answered 1, failed 0", log, re.M), log[-2000:]
            assert re.search(r"^icub_head:   published 0 messages", log, re.M)
        finally:
            for p in peers:
                p.stop()


# --------------------------------------------------------------------------
# py: YARP bridges in one process

PY_CONFIGS = {
    "pa": "[output]\nport = /pa/out:o\nrate = 50\n\n[mux m]\nports = /src/a:o (float64 x3)\n"
          "convert = deg_to_rad\n\n[message]\nv = m\n",
    "pb": "[output]\nport = /pb/out:o\ntimeout = 30\n\n[mux m]\nports = /src/b:o\n\n[message]\nn = counter\nv = m\n",
    "pc": "[output]\nport = /pc/out:o\nrate = 20\n\n[mux m]\nports = /src/c:o (int32 x2)\n\n[message]\nv = m\n",
    "pd": "[output]\nport = /pd/out:o\n\n[mux m]\nports = /src/d:o\n\n[message]\nv = m\n",
}


def test_py_bridges_in_one_process(tmp_path):
    """Four YARP-output configs composed by the py backend: one process
    whose bridges publish their values (one at a fixed rate, one
    event-driven fed a malformed Bottle too), while the third cannot start
    (its output port is taken) and the fourth's module does not load (it
    imports a package that is not installed): each said with its config,
    listed as not running in `stats`; `quit` stops the others, each printing
    its totals, and the process exits 1 (EXIT_BOUND after its `[bye]`)."""
    for name, text in PY_CONFIGS.items():
        (tmp_path / f"{name}.ini").write_text(text)
    out = tmp_path / "trio"
    r = ybgc("compose", *(tmp_path / f"{n}.ini" for n in PY_CONFIGS), "--backend", "py", "--name", "trio",
             "-o", out)
    assert r.returncode == 0, r.stdout + r.stderr
    assert {p.name for p in (out / "bridges").iterdir()} == {"pa.py", "pb.py", "pc.py", "pd.py"}
    module = out / "bridges" / "pd.py"
    module.write_text("import ybg_missing_msgs  # a package not installed\n" + module.read_text())
    app = (out / "trio.xml").read_text()
    assert "<parameters>trio.py</parameters>" in app
    assert all(f"<from>/src/{k}:o</from>" in app and f"<to>/p{k}/m/in0:i</to>" in app for k in "abc"), app
    with YarpServer(install=yarp_install("3.5")) as server:
        env = server.env
        ra, rb = YarpReader(env, "/r/a", source="/pa/out:o"), YarpReader(env, "/r/b", source="/pb/out:o")
        taken = YarpProducer(env, "/pc/out:o")
        pa = YarpProducer(env, "/src/a:o", bottles=[[90.0, 180.0, -45.0]], rate=PRODUCER_HZ)
        pb = YarpProducer(env, "/src/b:o")
        peers = [ra, rb, taken, pa, pb]
        try:
            run_parallel(*(p.start for p in peers))
            node = Node(env, out / "trio.py")
            node.start()
            node.wait_log("trio: 2 bridges running; not running: pc, pd")
            node.wait_log("trio: bridge pd (pd.ini:2:1) cannot start: cannot load its module bridges/pd.py "
                          "(ModuleNotFoundError: No module named 'ybg_missing_msgs'); the other bridges run")
            log = node.wait_log("trio: bridge pc (pc.ini:2:1) cannot start: cannot open the output /pc/out:o; "
                                "the other bridges run")
            (a, *_) = ra.wait_for(3)
            assert a.data == [90.0 * DEG + 0.0, 180.0 * DEG + 0.0, -45.0 * DEG + 0.0], a.data
            pb.wait_outputs(1)
            rb.wait_connected()
            pb.write([1, 2.5, -3])
            pb.write(["not a number"])
            pb.write([4, 5.5, 6])
            b = rb.wait_for(2)
            assert [x.data for x in b] == [[0, 1, 2.5, -3], [1, 4, 5.5, 6]], [x.data for x in b]
            stats = composed_stats(server, "/trio/rpc:i")
            assert stats["pc"] == '"not running" "cannot open the output /pc/out:o"', stats
            assert stats["pd"].startswith('"not running" "cannot load its module bridges/pd.py'), stats
            assert bridge_stats(stats["pb"])["inputs"] == {"/src/b:o": (3, 1, 0, 0, 0)}, stats
            assert bridge_stats(stats["pa"])["rate"][1] == "50.0"
            assert not server.exists("/pa/rpc:i") and not server.exists("/pb/rpc:i")
            rc, took = quit_over_rpc(env, node, "/trio/rpc:i")
            log = node.log_text()
            assert rc == 1 and took < EXIT_BOUND, (rc, took, log[-3000:])
            assert "Traceback" not in log
            assert bridge_totals(log, "pb") == {"/src/b:o": (3, 1, 0, 0), "published": 2}, log[-2000:]
            assert bridge_totals(log, "pa")["published"] > 0
            assert "pc: not started (cannot open the output /pc/out:o)" in log
            assert "pd: not started (cannot load its module" in log
            assert not server.exists("/trio/rpc:i") and not server.exists("/pa/out:o")
        finally:
            for p in peers:
                p.stop()
