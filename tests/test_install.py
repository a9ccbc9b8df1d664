"""A non-editable install works: the wheel carries the grammar, the message
definitions and the templates, and `ybgc check` runs from it."""

from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import zipfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def test_wheel_install_runs_without_the_source_tree(tmp_path):
    dist = tmp_path / "dist"
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                    "-w", str(dist), str(ROOT)], check=True, capture_output=True, timeout=300)
    (wheel,) = dist.glob("ybgc-*.whl")
    names = zipfile.ZipFile(wheel).namelist()
    assert "ybg/grammar/config.lark" in names
    assert "ybg/msgs/jazzy/sensor_msgs/JointState.msg" in names
    assert "ybg/msgs/noetic/std_msgs/Header.msg" in names
    assert any(n.startswith("ybg/backends/py/templates/") and n.endswith(".j2") for n in names)
    assert any(n.startswith("ybg/backends/cpp/templates/") and n.endswith(".j2") for n in names)

    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(target),
                    str(wheel)], check=True, capture_output=True, timeout=300)
    # run from an empty folder, with the installed copy first and no .pth files
    # (-S), so the editable install of the source tree cannot be picked up
    deps = sysconfig.get_paths()["purelib"]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(target), deps]), PYTHONNOUSERSITE="1")
    code = ("import ybg, sys; from ybg.cli import main; print(ybg.__file__, file=sys.stderr); "
            "sys.exit(main(sys.argv[1:]))")
    cfg = ROOT / "examples" / "vizzy_rviz_joint_states.ini"
    r = subprocess.run([sys.executable, "-S", "-c", code, "check", str(cfg)], cwd=tmp_path,
                       capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stderr.startswith(str(target)), r.stderr
    out = tmp_path / "gen"
    r = subprocess.run([sys.executable, "-S", "-c", code, str(cfg), "--backend", "ros2", "-o", str(out)],
                       cwd=tmp_path, capture_output=True, text=True, env=env, timeout=120)
    if (ROOT / "ybg" / "backends" / "ros2" / "__init__.py").exists():
        assert r.returncode == 0, r.stderr
        assert any(out.iterdir())
