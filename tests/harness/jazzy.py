"""ROS 2 Jazzy, the second ROS 2 of the tests' matrix: the PyPI wheels of
Jazzy (``ros-jazzy-*``, which pin the Jazzy builds of the ``ros-*`` names)
in a virtual environment of their own, ``.venv-jazzy`` (scripts/setup.sh),
beside the Kilted wheels of ``.venv``.

    JAZZY_VENV, JAZZY_PYTHON, JAZZY_HINT
    require_jazzy(node_yarp=True)   pytest.fail with how to install it, unless the venv has
                        Jazzy's rclpy (and YARP 4.0.0 is built for the node)
    jazzy_env(env) -> dict   ``env`` for a process of the Jazzy venv
    kilted_inherited(env) -> dict   ``env`` as a process a Kilted Python starts has it
    JazzySubscriber, JazzyPublisher   the rclpy peers run by the Jazzy venv's Python
    NODE_YARP           the YARP whose Python bindings the Jazzy node loads (4.0.0)

A Python of a venv of ROS 2 wheels re-executes itself once with the wheels'
libraries on ``LD_LIBRARY_PATH`` (their ``ros_wheels_bootstrapper``) and
marks it done in ``_ROS_WHEELS_BOOTSTRAP_COMPLETE``. Every process the tests
start inherits both from the Kilted Python that runs them: a Jazzy Python
started with them keeps Kilted's libraries and fails to import rclpy
(``libfastrtps.so.2.14: cannot open shared object file``). ``jazzy_env``
takes them out, so that the Jazzy venv sets its own.
"""
from __future__ import annotations

import os
import subprocess
from pathlib import Path

from harness.env import ROOT, VENV, clean_environ, fail, yarp_install
from harness.ros2 import Ros2Publisher, Ros2Subscriber

JAZZY_VENV = Path(os.environ.get("YBG_JAZZY_VENV", ROOT / ".venv-jazzy"))
JAZZY_PYTHON = JAZZY_VENV / "bin" / "python"
JAZZY_HINT = ("Install it with `scripts/setup.sh` (run from the repository root: it sets up "
              f"{JAZZY_VENV} with ROS 2 Jazzy's wheels beside .venv, about 1.5 minutes the first time), "
              "then run the tests with `.venv/bin/python -m pytest`.")
#: Jazzy's rclpy (Kilted's is 9.x)
JAZZY_RCLPY = "7."
#: the YARP whose Python bindings the Jazzy node imports: a release the
#: setup builds for the project's Python (PyPI's 3.5 is built into .venv only)
NODE_YARP = yarp_install("4.0.0")

_BOOTSTRAP = "_ROS_WHEELS_BOOTSTRAP_COMPLETE"


def require_jazzy(node_yarp: bool = True) -> None:
    """Fail the test unless the Jazzy venv imports Jazzy's rclpy and the
    message packages the tests use (tf2_msgs built by the setup), and (with
    ``node_yarp``) YARP 4.0.0 is built for its node."""
    probe = ("import rclpy, sensor_msgs.msg, std_msgs.msg, geometry_msgs.msg, tf2_msgs.msg\n"
             "from importlib.metadata import version\nprint(version('ros-rclpy'))")
    if not JAZZY_PYTHON.exists():
        err = f"{JAZZY_PYTHON} does not exist"
    else:
        r = subprocess.run([str(JAZZY_PYTHON), "-c", probe], env=jazzy_env(clean_environ()),
                           capture_output=True, text=True, timeout=60)
        lines = (r.stderr or r.stdout).strip().splitlines() or [f"exit status {r.returncode}"]
        got = r.stdout.strip()
        if r.returncode:
            err = lines[-1]
        elif not got.startswith(JAZZY_RCLPY):
            err = f"its rclpy is {got}, not Jazzy's {JAZZY_RCLPY}x"
        else:
            err = None
    if err:
        fail(f"ROS 2 Jazzy not usable in {JAZZY_VENV}: {err}. {JAZZY_HINT}")
    missing = NODE_YARP.missing() if node_yarp else []
    if missing:
        fail(f"YARP {NODE_YARP.version} (the Jazzy node's YARP bindings) is not built: {missing[0]}. "
             + NODE_YARP.build_hint())


def jazzy_env(env: dict) -> dict:
    """``env`` for a process of the Jazzy venv: without the Kilted venv's
    libraries on LD_LIBRARY_PATH and its bootstrap mark, with the Jazzy
    venv's bin instead of the Kilted one's on PATH."""
    out = {k: v for k, v in env.items() if k != _BOOTSTRAP}
    kilted = str(VENV)
    libs = [p for p in env.get("LD_LIBRARY_PATH", "").split(os.pathsep)
            if p and not p.startswith(kilted)]
    if libs:
        out["LD_LIBRARY_PATH"] = os.pathsep.join(libs)
    else:
        out.pop("LD_LIBRARY_PATH", None)
    out["PATH"] = os.pathsep.join(str(JAZZY_VENV / "bin") if p == str(VENV / "bin") else p
                                  for p in env.get("PATH", "").split(os.pathsep))
    out["VIRTUAL_ENV"] = str(JAZZY_VENV)
    return out


def kilted_inherited(env: dict) -> dict:
    """``env`` as a process started by a Kilted Python has it: the Kilted
    venv's libraries on LD_LIBRARY_PATH and its bootstrap mark (what
    ``jazzy_env`` takes out)."""
    site = next(VENV.glob("lib/python3*/site-packages"))
    libs = [str(VENV / "lib"), *sorted(str(p) for p in site.glob("ros_*.libs"))]
    return {**env, "LD_LIBRARY_PATH": os.pathsep.join(libs), _BOOTSTRAP: "1"}


class JazzySubscriber(Ros2Subscriber):
    """An rclpy subscriber of Jazzy; ``env`` as for Ros2Subscriber (made a
    Jazzy one here)."""

    python = str(JAZZY_PYTHON)

    def __init__(self, env: dict, topic: str, msg_type: str = "sensor_msgs/msg/JointState",
                 node: str = "ybg_jazzy_sub", depth: int = 100):
        super().__init__(jazzy_env(env), topic, msg_type, node=node, depth=depth)


class JazzyPublisher(Ros2Publisher):
    """An rclpy publisher of Jazzy (Ros2Publisher's options)."""

    python = str(JAZZY_PYTHON)

    def __init__(self, env: dict, topic: str, **options):
        super().__init__(jazzy_env(env), topic, **options)
