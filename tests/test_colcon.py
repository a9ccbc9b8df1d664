"""colcon and a user's own messages, end to end: the original tool's tutorial
config (shared/legacy/tutorial_example_yarp_ros.ini) converted for ROS 2
with ``ybgc fmt --to named --ros2``, generated as an ament_python package
into a colcon workspace, built by ``colcon build``, its installed entry point
run from the workspace's setup.bash between real YARP producers and a real
rclpy subscriber of ``ybg_demo_msgs/MotorsInertial`` (the tutorial's message,
built from its definition with rosidl from the ROS 2 wheels by the setup);
and the same config as the native C++ module in a ROS 2 package (``--backend
cpp --package``), an ament_cmake package built by colcon."""
from __future__ import annotations

import importlib.util
import json
import math
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from harness.env import VENV_PYTHON, yarp_install
from harness.generated import ybgc
from harness.module import Node, stop_clean, totals
from harness.procs import Proc
from harness.ros2 import QosSubscriber, yarp_and_ros2
from harness.yarp import YarpProducer

ROOT = Path(__file__).resolve().parents[1]
TUTORIAL = ROOT.parent / "shared" / "legacy" / "tutorial_example_yarp_ros.ini"
PACKAGE = "tutorial_example_yarp_ros"
COLCON = Path(VENV_PYTHON).parent / "colcon"


@pytest.fixture
def mw(ros2_domain):
    with yarp_and_ros2(ros2_domain) as both:
        yield both


class EntryPoint(Node):
    """The package's installed executable, run as ``ros2 run`` would, in the
    environment of the workspace's install/setup.bash."""

    def __init__(self, env, workspace: Path, executable: str, *args: str):
        self.path = workspace / "install" / PACKAGE / "lib" / PACKAGE / executable
        Proc.__init__(self, ["bash", "-c", 'source "$1/install/setup.bash" && exec "$2" "${@:3}"',
                             "bash", workspace, self.path, *args], env=env, name=executable)


def tutorial_config(tmp_path, msg_package="ybg_demo_msgs") -> Path:
    """The tutorial config converted for ROS 2 by ``ybgc fmt --to named --ros2``
    (its message in ``msg_package``)."""
    named = tmp_path / "tutorial.ini"
    r = ybgc("fmt", "--to", "named", "--ros2", "--msg-path", ROOT / "msgpkgs", TUTORIAL, "-o", named)
    assert r.returncode == 0, r.stderr
    text = named.read_text()
    assert "type = ybg_demo_msgs/MotorsInertial" in text and "via = ros2" in text
    assert "inertial = mux2" in text and "motors = mux1" in text
    named.write_text(text.replace("ybg_demo_msgs/", msg_package + "/"))
    return named


def colcon_build(env, ws: Path, *args) -> str:
    r = subprocess.run([str(COLCON), "build", *args], cwd=ws, env=env, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert f"Finished <<< {PACKAGE}" in r.stdout
    assert (ws / "install" / PACKAGE / "share" / PACKAGE / "package.xml").is_file()
    return r.stdout


def workspace_env(env, ws: Path) -> dict:
    """``env`` after ``source install/setup.bash`` of the workspace."""
    r = subprocess.run(["bash", "-c", 'source "$1/install/setup.bash" && env -0', "bash", ws],
                       env=env, capture_output=True, timeout=60)
    assert r.returncode == 0, r.stderr
    return dict(item.split("=", 1) for item in r.stdout.decode().split("\0") if "=" in item)


def run_tutorial(mw, ws: Path, msg_type: str, sub_env=None) -> None:
    """Producers -> the installed entry point -> an rclpy subscriber of
    ``msg_type``: the tutorial's message, exact."""
    sub = QosSubscriber(sub_env or mw.env, "/motors_inertial_port", msg_type).start()
    head = YarpProducer(mw.env, "/dummy_head/state:o").start()
    inertial = YarpProducer(mw.env, "/inertial").start()
    # (never stale within the test: its totals count stale periods, 0)
    node = EntryPoint(mw.env, ws, f"{PACKAGE}_node", "--ros-args", "-p", "timeout:=30.0").start()
    try:
        node.wait_log("publishing")
        head.wait_outputs(1)
        inertial.wait_outputs(1)
        # matched before the Bottles, which are written once
        sub.wait_publishers(1)
        node.wait_log("/motors_inertial_port: 1 subscriber\n")
        degrees = [10.0, -20.5, 90.0]
        imu = [0.5, -1.25, 9.81, 1, 2, 3, 0.125, 0.0, -0.5, 30.0, 45.0, 60.0]
        head.write(degrees)
        inertial.write(imu)
        want = {"inertial": [float(x) for x in imu], "motors": [d * math.pi / 180.0 for d in degrees]}

        def exact(m):
            got = m.msg
            return (sorted(got) == ["inertial", "motors"]
                    and len(got["inertial"]) == 12 and got["inertial"] == want["inertial"]
                    and len(got["motors"]) == 3
                    and all(abs(a - b) <= 1e-12 for a, b in zip(got["motors"], want["motors"])))
        sub.wait(lambda: any(exact(m) for m in sub.messages), 60, "the tutorial's message")
        log = stop_clean(node)
        assert totals(log)["/dummy_head/state:o"] == (1, 0, 0)
        assert totals(log)["published"] >= 1
    finally:
        for p in (node, head, inertial, sub):
            p.stop()
        shutil.rmtree(ws / "build", ignore_errors=True)


def test_tutorial_package_built_by_colcon(mw, tmp_path):
    """The node's package alone in the workspace; ybg_demo_msgs from the setup."""
    named = tutorial_config(tmp_path)
    ws = tmp_path / "ws"
    r = ybgc(named, "--backend", "ros2", "--package", "--msg-path", ROOT / "msgpkgs", "-o", ws / "src" / PACKAGE)
    assert r.returncode == 0, r.stderr
    assert "<exec_depend>ybg_demo_msgs</exec_depend>" in (ws / "src" / PACKAGE / "package.xml").read_text()
    colcon_build(mw.env, ws)
    run_tutorial(mw, ws, "ybg_demo_msgs/msg/MotorsInertial")


@pytest.mark.timeout(900)  # a message package built by CMake and rosidl, then the node's
def test_message_package_and_node_in_one_workspace(mw, tmp_path):
    """A user's own message package beside the node's in one workspace, both
    built by one ``colcon build`` with the wheels' rosidl (the message package
    first, as the node's package depends on it); the subscriber uses the
    workspace's environment too."""
    ws = tmp_path / "ws"
    msgs = ws / "src" / "my_robot_msgs"
    shutil.copytree(ROOT / "msgpkgs" / "ybg_demo_msgs", msgs)
    for name in ("package.xml", "CMakeLists.txt"):
        (msgs / name).write_text((msgs / name).read_text().replace("ybg_demo_msgs", "my_robot_msgs"))
    named = tutorial_config(tmp_path, "my_robot_msgs")
    r = ybgc(named, "--backend", "ros2", "--package", "--msg-path", ws / "src", "-o", ws / "src" / PACKAGE)
    assert r.returncode == 0, r.stderr
    # with the wheels, ament finds rosidl's type supports through AMENT_PREFIX_PATH
    env = dict(mw.env, AMENT_PREFIX_PATH=str(Path(VENV_PYTHON).parent.parent))
    out = colcon_build(env, ws, "--cmake-args", f"-DCMAKE_PROJECT_INCLUDE={ROOT / 'scripts' / 'msgpkg_wheels.cmake'}",
                       "-DBUILD_TESTING=OFF", f"-DPython3_EXECUTABLE={VENV_PYTHON}")
    assert out.index("Finished <<< my_robot_msgs") < out.index(f"Starting >>> {PACKAGE}")
    run_tutorial(mw, ws, "my_robot_msgs/msg/MotorsInertial", workspace_env(mw.env, ws))


@pytest.mark.timeout(900)  # a C++ build
def test_native_module_package_built_by_colcon(mw, tmp_path):
    """The tutorial as the native C++ module in a ROS 2 package (``--backend
    cpp --package``): colcon builds it as an ament_cmake package (YARP and
    the ROS 2 wheels given through its cmake-args), the ament index finds it as ``ros2
    run`` does, its executable is in ``lib/<package>``, and run from the
    workspace's setup.bash it publishes the tutorial's message; its launch
    file's parameters, given as launch_ros gives them, set its rate."""
    named = tutorial_config(tmp_path)
    ws = tmp_path / "ws"
    src = ws / "src" / PACKAGE
    r = ybgc(named, "--backend", "cpp", "--package", "--msg-path", ROOT / "msgpkgs", "-o", src)
    assert r.returncode == 0, r.stderr
    xml = (src / "package.xml").read_text()
    assert "<depend>ybg_demo_msgs</depend>" in xml and "<build_type>ament_cmake</build_type>" in xml
    yarp = yarp_install("3.5")
    venv = Path(VENV_PYTHON).parent.parent
    # ament_cmake from the wheels (found through the venv, with its Python), as in a sourced ROS 2
    env = dict(mw.env, AMENT_PREFIX_PATH=str(venv))
    colcon_build(env, ws, "--cmake-args", f"-DCMAKE_PREFIX_PATH={yarp.cmake_prefix_path()};{venv}",
                 f"-DYBGC_ROS2_PYTHON_ENV={venv}", f"-DPython3_EXECUTABLE={VENV_PYTHON}", "-DBUILD_TESTING=OFF")
    env = workspace_env(mw.env, ws)
    assert str(ws / "install" / PACKAGE) in env["AMENT_PREFIX_PATH"].split(":")
    found = subprocess.run([VENV_PYTHON, "-c", "from ament_index_python.packages import get_package_prefix as p; "
                            f"print(p('{PACKAGE}'))"], env=env, capture_output=True, text=True, timeout=60)
    assert found.returncode == 0 and Path(found.stdout.strip()) == ws / "install" / PACKAGE, found
    sub = QosSubscriber(mw.env, "/motors_inertial_port", "ybg_demo_msgs/msg/MotorsInertial").start()
    head = YarpProducer(mw.env, "/dummy_head/state:o").start()
    inertial = YarpProducer(mw.env, "/inertial").start()
    module = EntryPoint(mw.env, ws, PACKAGE).start()
    try:
        module.wait_log("publishing")
        head.wait_outputs(1)
        inertial.wait_outputs(1)
        sub.wait_publishers(1)
        degrees = [10.0, -20.5, 90.0]
        imu = [0.5, -1.25, 9.81, 1, 2, 3, 0.125, 0.0, -0.5, 30.0, 45.0, 60.0]
        want = {"inertial": [float(x) for x in imu], "motors": [d * math.pi / 180.0 for d in degrees]}

        def exact(m):
            got = m.msg
            return (sorted(got) == ["inertial", "motors"] and got["inertial"] == want["inertial"]
                    and len(got["motors"]) == 3
                    and all(abs(a - b) <= 1e-12 for a, b in zip(got["motors"], want["motors"])))
        # the native module says no subscriber match: the Bottles again until the message arrives
        end = time.monotonic() + 60
        while not any(exact(m) for m in sub.messages):
            assert time.monotonic() < end, sub.messages[-3:]
            head.write(degrees)
            inertial.write(imu)
            time.sleep(0.3)
        log = stop_clean(module)
        assert totals(log)["/dummy_head/state:o"][0] >= 1 and totals(log)["published"] >= 1

        # its launch file (installed where `ros2 launch` looks) starts it as
        # launch_ros does: the node's name remapped, the parameters in a file under /**
        path = ws / "install" / PACKAGE / "share" / PACKAGE / "launch" / f"{PACKAGE}.launch.py"
        spec = importlib.util.spec_from_file_location("launch_file", path)
        launch = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(launch)
        assert (launch.PACKAGE, launch.EXECUTABLE, launch.NODE_NAME) == (PACKAGE, PACKAGE, PACKAGE)
        params = tmp_path / "params.yaml"
        params.write_text(json.dumps({"/**": {"ros__parameters": dict(launch.PARAMETERS, rate=25.0)}}))
        module = EntryPoint(mw.env, ws, PACKAGE, "--ros-args", "-r", f"__node:={launch.NODE_NAME}",
                            "--params-file", str(params)).start()
        module.wait_log(", 25 Hz")
        stop_clean(module)
    finally:
        for p in (module, head, inertial, sub):
            p.stop()
        shutil.rmtree(ws / "build", ignore_errors=True)


def test_native_packages_of_any_module(tmp_path):
    """`--backend cpp --package` of a module of YARP ports alone is a package
    too (a robot's colcon workspace holds its YARP modules), with no ROS 2
    dependency and no launch file (it takes no ROS arguments); a module named
    as no ROS package can be is packaged under the ROS package name of its
    name (its CMake project named so, as ament_package() wants), its
    executable keeping the module's name."""
    yarp_only = ROOT / "examples" / "yarp_to_yarp_end_effector.ini"
    r = ybgc(yarp_only, "--backend", "cpp", "--package", "-o", tmp_path / "a")
    assert r.returncode == 0, r.stdout + r.stderr
    xml = (tmp_path / "a" / "package.xml").read_text()
    assert "<depend>" not in xml and "<build_type>ament_cmake</build_type>" in xml
    assert not (tmp_path / "a" / "launch").exists()
    cmake = (tmp_path / "a" / "CMakeLists.txt").read_text()
    assert "ament_package()" in cmake and "launch" not in cmake.split("find_package(ament_cmake")[1]

    text = (ROOT / "examples" / "vizzy_rviz_joint_states.ini").read_text()
    assert "[module]" not in text  # named after its file
    cfg = tmp_path / "Vizzy.ini"
    cfg.write_text("[module]\nname = VizzyArm\n\n" + text)
    r = ybgc(cfg, "--backend", "cpp", "--package", "-o", tmp_path / "b")
    assert r.returncode == 0, r.stdout + r.stderr
    assert "<name>vizzyarm</name>" in (tmp_path / "b" / "package.xml").read_text()
    cmake = (tmp_path / "b" / "CMakeLists.txt").read_text()
    assert "project(vizzyarm LANGUAGES CXX)" in cmake
    assert "install(TARGETS VizzyArm RUNTIME DESTINATION lib/${PROJECT_NAME})" in cmake
    launch = (tmp_path / "b" / "launch" / "VizzyArm.launch.py").read_text()
    assert "PACKAGE = 'vizzyarm'" in launch and "EXECUTABLE = 'VizzyArm'" in launch
