"""The README's quick start, run as written.

Its config (the ``ini`` block that names ``vizzy.ini``) and its commands
(the ``sh`` blocks) are read from README.md's "Quick start" section, not
copied here, and run by bash, one script, in a fresh folder laid out as the
repository's folder is for them (``vizzy.ini``, and links to ``.venv`` and
``examples/``), in the environment of a new shell of a user who ran
scripts/setup.sh: a plain PATH and HOME, nothing of this test session's
environment (the quick start's own first command activates the venv).
Everything it builds is built as written: the native ROS 2 module against
the ROS 2 wheels, the ROS 1 module; each built binary then answers
``--help`` (it links and loads), and so does the rclpy node written last.
"""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from harness.env import VENV, yarp_install
from harness.markdown import README, commands, fenced, section
from harness.ros2 import require_ros2
from harness.yarp import require_yarp

ROOT = Path(__file__).resolve().parents[1]

#: what the quick start must keep showing: a pattern of each command that
#: the test runs (a command the README drops fails the test, not skips it)
REQUIRED = {
    "activate": r"^source \.venv/bin/activate\b",
    "check": r"^ybgc check vizzy\.ini\b",
    "cpp": r"^ybgc vizzy\.ini --backend cpp\b",
    "native configure": r"^cmake -S vizzy -B vizzy/build\b",
    "native build": r"\bcmake --build vizzy/build\b",
    "ros2": r"^ybgc vizzy\.ini --backend ros2\s*(#|$)",
    "ros2 package": r"^ybgc vizzy\.ini --backend ros2 --package\b",
    "ros2 single file": r"^ybgc vizzy\.ini --backend ros2 --single-file\b",
    "ros1 cpp": r"^ybgc examples/rviz_joint_states_ros1\.ini --backend cpp -o rviz\b",
    "ros1 build": r"^cmake -S rviz -B rviz/build\b.*\bcmake --build rviz/build\b",
    "ir": r"^ybgc ir vizzy\.ini\b",
}


def quick_start() -> tuple[str, str, list[str]]:
    """The quick start's config (file name, text) and commands, from README.md."""
    blocks = fenced(section(README.read_text(encoding="utf-8"), "Quick start"))
    configs = [body for lang, body in blocks if lang == "ini"]
    assert len(configs) == 1, f"the quick start should hold one ini block, not {len(configs)}"
    named = re.match(r"#\s*(\S+\.ini)\b", configs[0])
    assert named, "the quick start's config should start with a comment naming its file"
    cmds = [c for lang, body in blocks if lang == "sh" for c in commands(body)]
    return named.group(1), configs[0], cmds


def user_environment(home: Path) -> dict:
    """A new login shell's environment on the setup's machine: no venv, no
    ROS, nothing this test session set."""
    return {"HOME": str(home), "PATH": "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin",
            "LANG": "C.UTF-8", "USER": os.environ.get("USER", "root"), "TERM": "dumb"}


def script(cmds: list[str], steps: Path) -> str:
    """A bash script that runs ``cmds`` in order, in one shell (so that what
    one sets, the next has), each one's output in ``steps/<i>.out`` and
    ``.err``, stopping at the first that fails."""
    lines = ["set -eo pipefail"]
    for i, cmd in enumerate(cmds):
        lines.append(f"echo {i} > {steps}/current")
        lines.append(f"{{ {cmd}\n}} > {steps}/{i}.out 2> {steps}/{i}.err")
    lines.append(f"echo done > {steps}/current")
    return "\n".join(lines) + "\n"


def step_output(steps: Path, i: int) -> tuple[str, str]:
    return ((steps / f"{i}.out").read_text(errors="replace"), (steps / f"{i}.err").read_text(errors="replace"))


def test_quick_start_parsed():
    """The quick start holds the config and every command the test below
    runs, and the examples those commands name exist."""
    name, config, cmds = quick_start()
    assert name == "vizzy.ini"
    assert "[output]" in config and "[message]" in config
    for what, pattern in REQUIRED.items():
        assert any(re.search(pattern, c, re.S) for c in cmds), f"the quick start has no {what} command ({pattern})"
    examples = {m for c in cmds for m in re.findall(r"\bexamples/[\w./-]+\.ini\b", c)}
    assert examples, cmds
    for path in examples:
        assert (ROOT / path).is_file(), f"the quick start names {path}, which does not exist"


@pytest.mark.slow
@pytest.mark.timeout(900)  # two C++ builds, on 2 cores shared with the rest of the suite
def test_quick_start_runs_as_written(tmp_path):
    """Every command of the quick start, in order, in one bash, exits 0; the
    modules it generates and builds are there and start."""
    yarp = yarp_install("3.5")
    require_yarp(yarp)
    require_ros2()
    name, config, cmds = quick_start()
    work = tmp_path / "repo"
    work.mkdir()
    (work / name).write_text(config, encoding="utf-8")
    (work / ".venv").symlink_to(VENV)
    (work / "examples").symlink_to(ROOT / "examples")
    home = tmp_path / "home"
    home.mkdir()
    steps = tmp_path / "steps"
    steps.mkdir()
    env = user_environment(home)

    start = time.monotonic()
    r = subprocess.run(["nice", "-n", "5", "bash", "-c", script(cmds, steps)], cwd=work, env=env,
                       capture_output=True, text=True, timeout=880)
    took = time.monotonic() - start
    current = (steps / "current").read_text().strip()
    if r.returncode != 0 or current != "done":
        i = int(current)
        out, err = step_output(steps, i)
        pytest.fail(f"the quick start's command {i + 1} of {len(cmds)} failed (exit {r.returncode}):\n"
                    f"  {cmds[i]}\nstdout:\n{out[-3000:]}\nstderr:\n{err[-3000:]}{r.stderr[-1000:]}",
                    pytrace=False)
    print(f"the quick start ran in {took:.0f} s")

    def index(what: str) -> int:
        return next(i for i, c in enumerate(cmds) if re.search(REQUIRED[what], c, re.S))

    out, err = step_output(steps, index("check"))
    assert "error" not in (out + err), out + err
    program = json.loads(step_output(steps, index("ir"))[0])
    assert program["module"] == "vizzy" and program["output"]["kind"] == "ros2", program["output"]

    # built as written: the native ROS 2 module against the wheels, the ROS 1 module
    cache = (work / "vizzy" / "build" / "CMakeCache.txt").read_text()
    wheels = re.search(r"^YBGC_ROS2_PYTHON_ENV:PATH=(.*)$", cache, re.M)
    assert wheels and wheels.group(1) and Path(wheels.group(1)).resolve() == VENV.resolve(), \
        "the native module was not built against the setup's ROS 2 wheels"
    run_env = dict(env, PATH=f"{VENV / 'bin'}:{env['PATH']}")
    for exe, says in ((work / "vizzy" / "build" / "vizzy", "on the ROS 2 topic /vizzy/joint_states"),
                      (work / "rviz" / "build" / "rviz_joint_states", "on the ROS 1 topic /yarp/joint_states")):
        assert os.access(exe, os.X_OK), f"{exe.relative_to(work)} was not built"
        h = subprocess.run([exe, "--help"], env=run_env, capture_output=True, text=True, timeout=60)
        assert h.returncode == 0 and says in h.stdout, (exe, h.returncode, h.stdout, h.stderr)
    # the rclpy node the last ros2 command wrote (--single-file: the runtime inlined)
    node = work / "vizzy" / "vizzy_node.py"
    assert "inlined (--single-file)" in node.read_text()
    h = subprocess.run([VENV / "bin" / "python", node, "--help"], env=run_env, capture_output=True, text=True,
                       timeout=60)
    assert h.returncode == 0 and "ROS 2 node vizzy" in h.stdout, (h.returncode, h.stdout, h.stderr)
    shutil.rmtree(work / "vizzy" / "build", ignore_errors=True)
    shutil.rmtree(work / "rviz" / "build", ignore_errors=True)
