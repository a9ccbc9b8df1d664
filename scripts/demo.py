"""The thesis' Rviz demonstration, end to end, on real middleware.

1. `ybgc check` the thesis' own config (figure 5, legacy form), and each
   example as its header says to check it (tests/harness/examples.py).
2. ROS 1 through YARP, as in the thesis: generate the C++ module from figure 5,
   build it, start roscore, `yarpserver --ros` and the type server, a YARP
   producer of Vizzy's arm angles in degrees, the module, and a rospy
   subscriber: it prints the sensor_msgs/JointState it receives, in radians.
3. ROS 2: convert figure 5 with `ybgc fmt --to named --ros2`, generate the
   rclpy node, and an rclpy subscriber prints the sensor_msgs/msg/JointState.

Everything runs on 127.0.0.1 and is stopped at the end. Run it through
`scripts/demo.sh` (after `scripts/setup.sh`).
"""

from __future__ import annotations

import math
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "tests"))

import middleware as mw  # noqa: E402  (the tests' harness for real middleware)
from harness.examples import check_commands  # noqa: E402  (each example's own check command)

FIGURE5 = ROOT.parent / "shared" / "legacy" / "thesis_figure5_rviz.ini"
ARM_PORT = "/vizzySim/left_shoulder_arm/state:o"
DEGREES = [10.0, -20.0, 30.0, 45.0, 90.0, -5.5, 0.0, 180.0]
YBGC = str(Path(sys.executable).parent / "ybgc")


def step(text: str) -> None:
    print(f"\n\033[1m== {text}\033[0m", flush=True)


def ybgc(*args: str, cwd: Path | None = None) -> None:
    print("$ ybgc " + " ".join(args), flush=True)
    r = subprocess.run([YBGC, *args], text=True, cwd=cwd)
    if r.returncode != 0:
        raise SystemExit(f"ybgc {' '.join(args)}: exit status {r.returncode}")


def show_joint_state(msg: dict, names_key: str = "name") -> None:
    header = msg["header"]
    stamp = header["stamp"]
    sec = stamp.get("secs", stamp.get("sec"))
    print(f"  header: frame_id={header['frame_id']!r} stamp={sec}"
          + (f" seq={header['seq']}" if "seq" in header else ""))
    for name, pos, deg in zip(msg[names_key], msg["position"], DEGREES):
        print(f"  {name:28s} {pos:+.6f} rad  (sent {deg:+7.2f} deg, {math.radians(deg):+.6f} rad)")
    print(f"  velocity={list(msg['velocity'])} effort={list(msg['effort'])}")


def check_all() -> None:
    step("1. check the thesis' config and the examples, each as its header says")
    ybgc("check", str(FIGURE5))
    print("(the warnings above are the thesis' own omissions: no rate, no ros_msg_name)")
    for args in check_commands():  # run from the repository's root, as the examples' headers say
        ybgc(*args, cwd=ROOT)
    print("all examples check")


def ros1_demo(work: Path) -> None:
    step("2. ROS 1 through YARP: the thesis' figure 5, as a C++ module")
    out = work / "cpp"
    ybgc(str(FIGURE5), "--backend", "cpp", "-o", str(out))
    build = out / "build"
    print("$ cmake -S ... && cmake --build ...", flush=True)
    subprocess.run(["cmake", "-S", str(out), "-B", str(build), f"-DCMAKE_PREFIX_PATH={mw.cmake_prefix_path()}",
                    "-DCMAKE_BUILD_TYPE=Release"], check=True, stdout=subprocess.DEVNULL)
    subprocess.run(["cmake", "--build", str(build), "-j2"], check=True, stdout=subprocess.DEVNULL)
    exe = build / "thesis_figure5_rviz"
    with mw.YarpRosStack(msg_types=["sensor_msgs/JointState"]) as stack:
        env = stack.env
        with mw.YarpProducer(env, ARM_PORT, rate=50.0, bottles=[DEGREES]) as producer, \
                mw.RospySubscriber(env, "/yarp/joint_states") as sub, \
                mw.Proc([str(exe)], env=env, name="thesis_figure5_rviz") as module:
            msgs = sub.wait_for(3, timeout=30)
            print(f"rospy received {len(sub.messages)} sensor_msgs/JointState; the last one:")
            show_joint_state(msgs[-1].msg)
            rc = module.stop(sig=2)
            print(f"module stopped by SIGINT: exit status {rc}")
            del producer


def ros2_demo(work: Path) -> None:
    step("3. ROS 2: the same config converted in one command, as an rclpy node")
    named = work / "figure5_ros2.ini"
    ybgc("fmt", "--to", "named", "--ros2", str(FIGURE5), "-o", str(named))
    print(named.read_text())
    out = work / "ros2"
    ybgc(str(named), "--backend", "ros2", "-o", str(out))
    (node,) = sorted(out.glob("*_node.py"))
    with mw.YarpServer() as server, mw.Ros2Domain() as domain:
        env = {**server.env, **domain.env}
        with mw.YarpProducer(env, ARM_PORT, rate=50.0, bottles=[DEGREES]), \
                mw.Ros2Subscriber(env, "/yarp/joint_states") as sub, \
                mw.Proc([sys.executable, str(node)], env=env, name=node.stem) as module:
            msgs = sub.wait_for(3, timeout=30)
            print(f"rclpy received {len(sub.messages)} sensor_msgs/msg/JointState; the last one:")
            show_joint_state(msgs[-1].msg)
            rc = module.stop(sig=2)
            print(f"node stopped by SIGINT: exit status {rc}")


def main() -> int:
    mw.require_yarp()
    t0 = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="ybgc-demo-") as tmp:
        work = Path(tmp)
        check_all()
        ros1_demo(work)
        ros2_demo(work)
    print(f"\ndone in {time.monotonic() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    finally:
        mw.stop_all()
