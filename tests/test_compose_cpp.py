"""``ybgc compose --backend cpp`` (docs/compose.md): several configs, one
native executable.

- The 14 configs of a whole iCub (examples/icub_robot/) and the homing of its
  left arm (examples/home_arm_trigger.ini, a config of commands), composed as
  `ybgc compose examples/icub_robot examples/home_arm_trigger.ini` (a folder
  and a file), built once (against PyPI's YARP 3.5 and the ROS 2 wheels,
  shared by the pytest-xdist workers) and run end to end in one process: a
  real YARP producer on every input port, real rclpy subscribers on every
  topic, a trajectory published into YARP, a real YARP RPC server on the
  homing port and an rclpy caller of the homing service; every stream
  bridge's values; a Trigger call answered from the RPC server's reply;
  every node on the graph, all of one DDS participant, one process;
  isolation (a producer stalled for 5 s, a ROS 2 subscriber and a YARP
  reader stalled, malformed Bottles on one bridge: the other bridges keep
  their rate within 1 %, the stalled one publishes nothing stale); `stats`
  and `quit` on ``/icub/rpc:i``, the service listed too. The checks are those
  of the ros2 backend's composed iCub (tests/harness/compose.py); one
  composed process serves them all.
- The same executable again, with a bridge unable to start (its output port
  taken: said with its config, `stats` lists it as not running, exit 1) and
  a parameter file keyed by node name (each node takes its own values).
- ``--package``: one ament_cmake package, one executable, its launch file and
  parameter file; a config of commands among the bridges, its node's
  parameters in the file with the others.
"""
from __future__ import annotations

import ast
import hashlib
import re
import shutil
import subprocess
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from harness.build import find_once_option, held, ros2_wheels_option, run_folder
from harness.compose import (ICUB, IMAGE_TOPIC, DIAGNOSTICS_PERIOD, bridge_stats, bridge_totals, check_isolation,
                             check_one_process, check_stats_and_quit, check_values, composed_stats, graph,
                             start_peers)
from harness.env import EXAMPLES, yarp_install
from harness.generated import ybgc
from harness.module import EXIT_BOUND, Module, quit_over_rpc
from harness.procs import wait_until
from harness.ros2 import Ros2Domain, ros2_environment
from harness.services import RpcServer, ServiceClient, reply, require_services
from harness.yarp import YarpProducer, YarpServer
from ybg.backends.cpp import ROS2_LINK
from ybg.compiler.pipeline import compile_path

#: the iCub's stream bridges
CONFIGS = sorted(ICUB.glob("*.ini"))
#: the homing of its left arm: a ROS 2 Trigger service answered by a YARP RPC port
HOMING = EXAMPLES / "home_arm_trigger.ini"
HOME_SERVICE = "/icub/left_arm/home"
HOME_PORT = "/icub/left_arm/homing/rpc:i"
NAME = "icub"
#: the bridges of the composed process
BRIDGES = len(CONFIGS) + 1


def generate(out: Path, *options: str) -> Path:
    """The robot's folder and the homing's file, composed (the CLI takes both)."""
    r = ybgc("compose", ICUB, HOMING, "--backend", "cpp", "--name", NAME, "-o", out, *options)
    assert r.returncode == 0, r.stdout + r.stderr
    return out


def build(tmp_path_factory) -> Path:
    """The composed iCub generated and built against YARP 3.5 and the ROS 2
    wheels, once for the run (the folder named by the digest of the
    generated files: the pytest-xdist workers share it, under a lock); the
    executable."""
    fresh = generate(tmp_path_factory.mktemp("icub_cpp") / NAME)
    digest = hashlib.sha256()
    for path in sorted(p for p in fresh.rglob("*") if p.is_file()):
        digest.update(str(path.relative_to(fresh)).encode() + b"\0" + path.read_bytes())
    root = run_folder(tmp_path_factory, f"compose_cpp_{digest.hexdigest()[:16]}")
    src, out, exe = root / "src", root / "build", root / "build" / NAME
    with held(root / ".build.lock"):
        if not exe.exists():
            shutil.rmtree(src, ignore_errors=True)
            shutil.copytree(fresh, src)
            install = yarp_install("3.5")
            cfg = subprocess.run(["cmake", "-S", str(src), "-B", str(out),
                                  f"-DCMAKE_PREFIX_PATH={install.cmake_prefix_path()}", find_once_option(),
                                  ros2_wheels_option(),
                                  "-DCMAKE_BUILD_TYPE=Tests", "-DCMAKE_CXX_FLAGS=-Werror"],
                                 capture_output=True, text=True, timeout=300)
            assert cfg.returncode == 0, cfg.stdout[-3000:] + cfg.stderr[-3000:]
            b = subprocess.run(["cmake", "--build", str(out), "-j2"], capture_output=True, text=True, timeout=900)
            assert b.returncode == 0, b.stdout[-5000:] + b.stderr[-5000:]
    return exe


@pytest.fixture(scope="module")
def icub(tmp_path_factory):
    """The composed iCub running, with a producer on every input port and a
    subscriber on every topic: the image subscriber is reliable, the left
    eye's publisher made so by a parameter of its node alone (its QoS
    override); /diagnostics twice a second from every node (the rates are
    measured from it)."""
    require_services()
    exe = build(tmp_path_factory)
    programs = {p.module: p for p in (compile_path(c).program for c in CONFIGS)}
    homing = compile_path(HOMING).program
    with Ros2Domain() as domain, YarpServer(install=yarp_install("3.5")) as server:
        env = ros2_environment(server.env, domain)
        peers = start_peers(env, programs)
        # the homing module's RPC port (it answers `home all` with one word) and a caller of the service
        arm = RpcServer(env, HOME_PORT, [reply("home all", "ok")])
        caller = ServiceClient(env, {HOME_SERVICE: "std_srvs/srv/Trigger"}, name="ybg_test_homing_caller")
        node = Module([exe, "--ros-args", "-p",
                       f"icub_left_eye:qos_overrides.{IMAGE_TOPIC}.publisher.reliability:=reliable",
                       "-p", f"diagnostic_updater.period:={DIAGNOSTICS_PERIOD}"], env=env, name="icub")
        try:
            arm.start()
            caller.start()
            t0 = time.monotonic()
            node.start()
            node.wait_log(f"{NAME}: {BRIDGES} bridges running", timeout=60)

            def feed_commands():
                """One call of the homing service through the process, answered."""
                caller.wait_service(HOME_SERVICE, timeout=60)
                got = caller.call(HOME_SERVICE)
                assert got.response is not None and got.response["message"] in ("ok", "busy"), got

            yield SimpleNamespace(env=env, server=server, node=node, exe=exe, programs=programs,
                                  commands={homing.module: homing}, feed_commands=feed_commands, arm=arm,
                                  caller=caller, started=time.monotonic() - t0, **vars(peers))
        finally:
            node.stop()
            for p in [*peers.peers, arm, caller]:
                p.stop()


@pytest.fixture(autouse=True)
def _print_logs(request):
    """The composed process's log, shown when a test fails."""
    yield
    if "icub" in request.fixturenames:
        node = request.getfixturevalue("icub").node
        print(f"---- log of {node.name}:\n{node.log_text()[-6000:]}")


@pytest.mark.timeout(900)  # the first test builds the composed module (fixture icub)
class TestComposedIcub:
    """examples/icub_robot (14 configs) and examples/home_arm_trigger.ini, one
    native process (the shared fixture)."""

    def test_every_bridge_publishes_its_values(self, icub):
        """Joint names and radians of every part on /joint_states, the four
        wrenches, the IMU's quaternion, both hands on /tf, the camera's
        image (every pixel) and a MoveIt trajectory's rows into YARP."""
        check_values(icub)

    def test_one_process_one_participant_a_node_per_bridge(self, icub):
        """Every bridge's node is on the graph with its own name, their
        /diagnostics writers of one DDS participant, in one process; every
        line a bridge says is headed by its module's name."""
        check_one_process(icub)
        log = icub.node.log_text()
        for module, program in icub.programs.items():
            assert f"{module}: publishing " in log, module
        assert re.search(r"^icub_head: connected /icub/head/state:o -> /icub_head/joints/in0:i$", log, re.M), log
        assert f"{NAME}: {BRIDGES} bridges running\n" in log
        # the bridge of commands: its node on the one participant too, its lines under its name
        nodes = [*icub.programs, *icub.commands]
        seen = graph(icub.env, nodes)
        assert "left_arm_homing" in {name for name, _ in seen["diagnostics"]}, seen
        assert len({gid[:24] for name, gid in seen["diagnostics"] if name in nodes}) == 1, seen
        assert re.search(r"^left_arm_homing: service home: serves the ROS 2 service /icub/left_arm/home ", log,
                         re.M), log[-3000:]
        print(f"{BRIDGES} bridges started in {icub.started:.2f} s")

    def test_a_trigger_call_answered_from_the_yarp_rpc_server(self, icub):
        """The homing bridge in the process: a ROS 2 Trigger call becomes
        `home all` on the YARP RPC server, whose one-word reply answers it
        (`ok`: success; any other word: a failure the caller can tell, said
        by the server, not by the bridge); counted in the process's
        `stats` under the bridge's name."""
        icub.caller.wait_service(HOME_SERVICE, timeout=60)
        before = len(icub.arm.commands)
        got = icub.caller.call(HOME_SERVICE)
        assert got.response == {"success": True, "message": "ok"}, got
        command = icub.arm.wait_commands(before + 1)[-1]
        assert (command["data"], command["types"]) == (["home", "all"], ["string", "string"])
        icub.arm.set_rules([reply("home all", "busy")])
        try:
            refused = icub.caller.call(HOME_SERVICE)
        finally:
            icub.arm.set_rules([reply("home all", "ok")])
        assert refused.response == {"success": False, "message": "busy"}, refused
        stats = composed_stats(icub.server, f"/{NAME}/rpc:i")["left_arm_homing"]
        calls = re.search(r"\(service home calls (\d+) answered (\d+) failed 0 timed_out 0 no_server 0 unfit 0\)",
                          stats)
        assert calls and int(calls[1]) == int(calls[2]) >= 2, stats

    def test_a_stall_or_malformed_bottles_delay_no_other_bridge(self, icub):
        """For 5 s: the IMU's producer, the subscriber of /joint_states and
        the trajectory's YARP reader SIGSTOPped, malformed Bottles into the
        torso: every other bridge keeps its rate within 1 %, the IMU's
        publishes nothing once its input is stale, the torso counts the
        malformed Bottles as dropped."""
        check_isolation(icub)

    def test_stats_and_quit_on_the_rpc_port(self, icub):
        """`help`, `stats` (a list per bridge) and `quit` on /icub/rpc:i:
        every bridge stops and prints its totals under its name, the process
        exits 0 (EXIT_BOUND after its `[bye]`); no bridge's own RPC port is
        open. It feeds every bridge itself (it stands alone)."""
        check_stats_and_quit(icub)

    def test_a_bridge_that_cannot_start_and_parameters_by_node_name(self, icub, tmp_path):
        """The same executable again (after `quit`), the trajectory's output
        port taken and a parameter file keyed by node name: the bridge is
        said with its config and the others run; `stats` lists it as not
        running; each node takes its own parameters (the head at 25 Hz, the
        torso's ports under another prefix); `quit`: exit 1 (EXIT_BOUND after its `[bye]`)."""
        import yaml

        if icub.node.alive:  # run alone: the composed process of the fixture goes first (its name is taken)
            assert quit_over_rpc(icub.env, icub.node, f"/{NAME}/rpc:i")[0] == 0, icub.node.log_text()[-3000:]
        taken = YarpProducer(icub.env, "/icub_left_arm_trajectory/plan:o")
        params = tmp_path / "params.yaml"
        params.write_text(yaml.safe_dump({
            "icub_head": {"ros__parameters": {"rate": 25.0}},
            "icub_torso": {"ros__parameters": {"prefix": "/torso_elsewhere"}},
        }))
        again = Module([icub.exe, "--ros-args", "--params-file", params], env=icub.env, name="icub_again")
        try:
            taken.start()
            again.start()
            log = again.wait_log(f"{NAME}: {BRIDGES - 1} bridges running; not running: icub_left_arm_trajectory")
            assert (f"{NAME}: bridge icub_left_arm_trajectory (trajectory.ini:9:1) cannot start: cannot open the "
                    "output /icub_left_arm_trajectory/plan:o; the other bridges run") in log
            stats = composed_stats(icub.server, f"/{NAME}/rpc:i")
            assert stats["icub_left_arm_trajectory"] == \
                '"not running" "cannot open the output /icub_left_arm_trajectory/plan:o"', stats
            assert bridge_stats(stats["icub_head"])["rate"][1] == "25.0", stats
            assert bridge_stats(stats["icub_left_arm"])["rate"][1] == "100.0", stats
            wait_until(lambda: icub.server.exists("/torso_elsewhere/joints/in0:i"), 10, "the torso's port")
            assert not icub.server.exists("/icub_torso/joints/in0:i")
            # the head's producer connected again by the new process, and its messages counted
            wait_until(lambda: (bridge_stats(composed_stats(icub.server, f"/{NAME}/rpc:i")["icub_head"])
                                ["published"][0] > 0), 60, "the head's messages", again)
            rc, took = quit_over_rpc(icub.env, again, f"/{NAME}/rpc:i")
            log = again.log_text()
            assert rc == 1 and took < EXIT_BOUND, (rc, took, log[-3000:])
            assert "icub_left_arm_trajectory: not started (cannot open the output " \
                   "/icub_left_arm_trajectory/plan:o)" in log
            assert bridge_totals(log, "icub_head").get("published", 0) > 0
            assert not icub.server.exists(f"/{NAME}/rpc:i") and not icub.server.exists("/torso_elsewhere/joints/in0:i")
        finally:
            again.stop()
            taken.stop()


def test_package_one_executable_launch_and_parameters(tmp_path):
    """`ybgc compose --backend cpp --package`: one ament_cmake package with one
    executable; its launch file starts it with the parameter file keyed by
    node name (no `name=`: it would rename every node of the process), which
    it installs with the launch file."""
    out = generate(tmp_path / "pkg", "--package")
    files = {str(p.relative_to(out)) for p in out.rglob("*") if p.is_file() and not p.name.startswith("ybgc_")}
    bridges = {f"bridges/{compile_path(c).program.module}.cpp" for c in [*CONFIGS, HOMING]}
    assert files == {"CMakeLists.txt", "package.xml", "icub.cpp", "icub.xml", "launch/icub.launch.py",
                     "config/icub.yaml", *bridges}, files
    assert (out / "ybgc_compose.cpp").exists() and (out / "ybgc_images.cpp").exists()
    assert (out / "ybgc_services.cpp").exists() and (out / "ybgc_services_node.cpp").exists()
    cmake = (out / "CMakeLists.txt").read_text()
    assert "install(TARGETS icub RUNTIME DESTINATION lib/${PROJECT_NAME})" in cmake
    assert "install(FILES config/icub.yaml DESTINATION share/${PROJECT_NAME}/config)" in cmake
    assert cmake.count("add_executable(") == 1 and "ament_package()" in cmake
    # every message package once
    linked = re.search(rf"^{ROS2_LINK}\(icub (.*)\)$", cmake, re.M)[1].split()
    for pkg in ("sensor_msgs", "geometry_msgs", "tf2_msgs", "trajectory_msgs", "std_srvs"):
        assert linked.count(pkg) == 1, pkg
    depends = re.findall(r"<depend>(\S+)</depend>", (out / "package.xml").read_text())
    assert {"rcl", "rosidl_runtime_c", "sensor_msgs", "trajectory_msgs", "std_srvs"} <= set(depends)
    import yaml

    params = yaml.safe_load((out / "config" / "icub.yaml").read_text())
    assert sorted(params) == sorted(compile_path(c).program.module for c in [*CONFIGS, HOMING])
    assert params["icub_head"] == {"ros__parameters": {"rate": 100.0, "timeout": 0.0, "prefix": "/icub_head",
                                                       "verbose": False, "diagnostics": True}}
    launch = ast.parse((out / "launch" / "icub.launch.py").read_text())
    consts = {t.id: ast.literal_eval(n.value) for n in launch.body if isinstance(n, ast.Assign) for t in n.targets}
    assert consts["PACKAGE"] == "icub" and consts["EXECUTABLE"] == "icub" and consts["PARAMS_FILE"] == "icub.yaml"
    assert "name=" not in (out / "launch" / "icub.launch.py").read_text().split("Node(", 1)[1].split(")")[0]
