"""Message packages built from their definitions with rosidl and ament_cmake
from the ROS 2 wheels (scripts/build_msgpkg.sh): tf2_msgs and ybg_demo_msgs,
built into the venv by the setup, used by real rclpy processes (Python), their
C and C++ structs compiled; a user's own package built into a prefix of its
own, used the same way, found by ``ybgc check`` through AMENT_PREFIX_PATH,
cached until its sources change."""
from __future__ import annotations

import glob
import os
import shutil
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from harness.env import VENV_PYTHON, base_env
from harness.generated import ybgc
from harness.ros2 import QosSubscriber

ROOT = Path(__file__).resolve().parents[1]
BUILD = ROOT / "scripts" / "build_msgpkg.sh"
VENV = Path(VENV_PYTHON).parent.parent
PYVER = "%d.%d" % sys.version_info[:2]


@pytest.fixture
def ros2(ros2_domain):
    env = dict(ros2_domain.env)
    env.update(ros2_domain.ros_env)
    return env


def publisher(env, type_name: str, topic: str, build: str) -> subprocess.Popen:
    """A Python process publishing ``build`` (an expression of ``M``, the
    message class) on ``topic`` at 20 Hz until stopped."""
    pkg, name = type_name.split("/")
    code = textwrap.dedent(f"""\
        import time, rclpy
        from {pkg}.msg import {name} as M
        import geometry_msgs.msg as g
        rclpy.init()
        node = rclpy.create_node("ybg_test_msgpkg_pub")
        pub = node.create_publisher(M, {topic!r}, 10)
        msg = {build}
        while True:
            pub.publish(msg)
            time.sleep(0.05)
        """)
    return subprocess.Popen([str(VENV_PYTHON), "-c", code], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, start_new_session=True)


def received(env, type_name, topic, build) -> dict:
    """The first message an rclpy subscriber receives from ``publisher``."""
    pkg, name = type_name.split("/")
    sub = QosSubscriber(env, topic, f"{pkg}/msg/{name}").start()
    pub = publisher(env, type_name, topic, build)
    try:
        return sub.wait_for(1)[0].msg
    finally:
        pub.kill()
        pub.wait()
        sub.stop()


TF = ("M(transforms=[g.TransformStamped(child_frame_id='r_hand', "
      "transform=g.Transform(translation=g.Vector3(x=0.1, y=-0.25, z=1.5), "
      "rotation=g.Quaternion(x=0.0, y=0.0, z=0.7071067811865476, w=0.7071067811865476))), "
      "g.TransformStamped(child_frame_id='l_hand')])")


def test_tf2_msgs_built_by_the_setup(ros2):
    share = VENV / "share" / "tf2_msgs"
    for name in ("TFMessage.msg", "TF2Error.msg"):  # the definitions, verbatim
        assert (share / "msg" / name).read_text() == (ROOT / "msgpkgs" / "tf2_msgs" / "msg" / name).read_text()
    msg = received(ros2, "tf2_msgs/TFMessage", "/tf", TF)
    first, second = msg["transforms"]
    assert first["child_frame_id"] == "r_hand" and second["child_frame_id"] == "l_hand"
    assert first["transform"]["translation"] == {"x": 0.1, "y": -0.25, "z": 1.5}
    assert first["transform"]["rotation"] == {"x": 0.0, "y": 0.0, "z": 0.7071067811865476,
                                              "w": 0.7071067811865476}


def test_c_and_cpp_structs_compile(tmp_path):
    """The headers a C or C++ module uses (<venv>/include/<pkg>/, libraries in <venv>/lib)."""
    src = tmp_path / "use.cpp"
    src.write_text(textwrap.dedent("""\
        #include <tf2_msgs/msg/tf_message.hpp>
        #include <tf2_msgs/msg/tf_message.h>
        #include <ybg_demo_msgs/msg/motors_inertial.hpp>
        int main() {
          tf2_msgs::msg::TFMessage tf;
          tf.transforms.resize(1);
          tf.transforms[0].child_frame_id = "r_hand";
          ybg_demo_msgs::msg::MotorsInertial mi;
          mi.motors = {0.5, 1.0};
          return tf.transforms.size() == 1 && mi.motors.size() == 2 ? 0 : 1;
        }
        """))
    includes = [f"-I{d}" for d in sorted(glob.glob(str(VENV / "include" / "*")))]
    r = subprocess.run(["g++", "-std=c++17", "-fsyntax-only", *includes, str(src)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr[-3000:]
    for pkg in ("tf2_msgs", "ybg_demo_msgs"):
        for kind in ("rosidl_generator_c", "rosidl_typesupport_c", "rosidl_typesupport_cpp",
                     "rosidl_typesupport_fastrtps_cpp", "rosidl_typesupport_introspection_cpp"):
            assert (VENV / "lib" / f"lib{pkg}__{kind}.so").is_file()


USER_PACKAGE = {
    "package.xml": """\
        <?xml version="1.0"?>
        <package format="3">
          <name>my_robot_msgs</name>
          <version>1.0.0</version>
          <description>A robot's own messages</description>
          <maintainer email="someone@example.com">someone</maintainer>
          <license>MIT</license>
          <buildtool_depend>ament_cmake</buildtool_depend>
          <buildtool_depend>rosidl_default_generators</buildtool_depend>
          <depend>geometry_msgs</depend>
          <exec_depend>rosidl_default_runtime</exec_depend>
          <member_of_group>rosidl_interface_packages</member_of_group>
          <export><build_type>ament_cmake</build_type></export>
        </package>
        """,
    "CMakeLists.txt": """\
        cmake_minimum_required(VERSION 3.8)
        project(my_robot_msgs)
        find_package(ament_cmake REQUIRED)
        find_package(rosidl_default_generators REQUIRED)
        find_package(geometry_msgs REQUIRED)
        rosidl_generate_interfaces(${PROJECT_NAME} "msg/Grasp.msg" DEPENDENCIES geometry_msgs)
        ament_export_dependencies(rosidl_default_runtime)
        ament_package()
        """,
    "msg/Grasp.msg": """\
        geometry_msgs/Pose pose
        float64[] fingers
        """,
}


def build(pkg: Path, prefix: Path) -> subprocess.CompletedProcess:
    env = dict(base_env(), YBG_VENV=str(VENV))
    r = subprocess.run(["bash", str(BUILD), "--prefix", str(prefix), str(pkg)], env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stderr[-4000:]
    return r


def test_a_users_own_message_package(tmp_path, ros2):
    pkg = tmp_path / "src" / "my_robot_msgs"
    for name, text in USER_PACKAGE.items():
        (pkg / name).parent.mkdir(parents=True, exist_ok=True)
        (pkg / name).write_text(textwrap.dedent(text))
    prefix = tmp_path / "install"
    assert "building" in build(pkg, prefix).stderr
    # as a user sets them for a prefix other than the venv (the venv's python
    # adds the wheels' own library folders to LD_LIBRARY_PATH when it starts)
    env = dict(ros2, PYTHONPATH=str(prefix / "lib" / f"python{PYVER}" / "site-packages"),
               LD_LIBRARY_PATH=str(prefix / "lib"))
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    msg = received(env, "my_robot_msgs/Grasp", "/grasp",
                   "M(pose=g.Pose(position=g.Point(x=0.3, y=-0.1, z=0.8)), fingers=[0.25, 1.0, -0.5])")
    assert msg["pose"]["position"] == {"x": 0.3, "y": -0.1, "z": 0.8}
    assert msg["fingers"] == [0.25, 1.0, -0.5]

    # ybgc finds the installed definitions as it finds a ROS 2 install's
    cfg = tmp_path / "grasp.ini"
    cfg.write_text("[output]\ntopic = /grasp\ntype = my_robot_msgs/Grasp\n\n"
                   "[mux hand]\nports = /hand:o (float64 x3)\n\n[message]\nfingers = hand\n")
    r = ybgc("check", cfg)
    assert "W503" in r.stderr  # not found without it: not checked
    r = subprocess.run([str(Path(VENV_PYTHON).parent / "ybgc"), "check", str(cfg)], capture_output=True,
                       text=True, timeout=60, env=dict(os.environ, AMENT_PREFIX_PATH=str(prefix)))
    assert r.returncode == 0 and r.stderr == "", r.stderr

    # cached: unchanged sources are not rebuilt; a changed definition is
    t0 = time.monotonic()
    assert "up to date" in build(pkg, prefix).stderr
    assert time.monotonic() - t0 < 30
    (pkg / "msg" / "Grasp.msg").write_text("geometry_msgs/Pose pose\nfloat64[] fingers\nstring side\n")
    assert "building" in build(pkg, prefix).stderr
    r = subprocess.run([str(VENV_PYTHON), "-c", "from my_robot_msgs.msg import Grasp; print(Grasp(side='left').side)"],
                       env=env, capture_output=True, text=True, timeout=60)
    assert r.stdout.strip() == "left", r.stderr


def test_a_package_that_does_not_build_is_a_clear_error(tmp_path):
    pkg = tmp_path / "broken_msgs"
    for name, text in USER_PACKAGE.items():
        (pkg / name).parent.mkdir(parents=True, exist_ok=True)
        (pkg / name).write_text(textwrap.dedent(text).replace("my_robot_msgs", "broken_msgs"))
    (pkg / "msg" / "Grasp.msg").write_text("no_such_msgs/Thing thing\n")
    env = dict(base_env(), YBG_VENV=str(VENV))
    r = subprocess.run(["bash", str(BUILD), "--prefix", str(tmp_path / "install"), str(pkg)], env=env,
                       capture_output=True, text=True, timeout=600)
    assert r.returncode != 0
    assert "error: broken_msgs did not build (full log: " in r.stderr
    assert "no_such_msgs" in r.stderr
    shutil.rmtree(r.stderr.rsplit("full log: ", 1)[1].split(")")[0].rsplit("/", 1)[0], ignore_errors=True)
