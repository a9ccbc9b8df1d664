"""A second build of ``ybg_demo_msgs`` whose ``Polygon`` has one field more:
one type name, two definitions, two type hashes (REP-2011), as a lab's own
message package rebuilt with a new field is on a robot's graph.

``variant_prefix()`` builds it once (scripts/build_msgpkg.sh, cached by its
sources; a file lock keeps the pytest-xdist workers from building it twice)
into build/variant/ of the checkout, apart from the venv's own build; and
``variant_env(env)`` is a child environment whose rclpy imports that build
instead of the venv's (PYTHONPATH and LD_LIBRARY_PATH before the venv's,
AMENT_PREFIX_PATH naming it first).
"""
from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from .env import ROOT, VENV

SOURCE = ROOT / "msgpkgs" / "ybg_demo_msgs"
BUILD = ROOT / "build" / "variant"
PREFIX = BUILD / "prefix"
#: the field the variant's Polygon has beyond the venv's
EXTRA_FIELD = "uint32 revision"
TYPE = "ybg_demo_msgs/msg/Polygon"


def _sources() -> Path:
    """The variant's sources: a copy of msgpkgs/ybg_demo_msgs with the field added."""
    src = BUILD / "src" / "ybg_demo_msgs"
    if src.exists():
        shutil.rmtree(src)
    shutil.copytree(SOURCE, src)
    msg = src / "msg" / "Polygon.msg"
    msg.write_text(msg.read_text() + EXTRA_FIELD + "\n")
    return src


def variant_prefix() -> Path:
    """The install prefix of the variant (built on first use)."""
    BUILD.mkdir(parents=True, exist_ok=True)
    with open(BUILD / ".lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        src = _sources()
        r = subprocess.run([str(ROOT / "scripts" / "build_msgpkg.sh"), "--prefix", str(PREFIX), str(src)],
                           env={**os.environ, "YBG_VENV": str(VENV)}, capture_output=True, text=True)
        if r.returncode != 0:
            pytest.fail("the variant of ybg_demo_msgs did not build (scripts/build_msgpkg.sh; "
                        f"scripts/setup.sh installs what it needs):\n{r.stderr[-3000:]}", pytrace=False)
    return PREFIX


def _site(prefix: Path) -> Path:
    found = sorted(prefix.glob("lib/python3*/site-packages"))
    if not found:
        pytest.fail(f"no Python messages under {prefix}/lib: rebuild it (rm -r {BUILD})", pytrace=False)
    return found[0]


def variant_env(env: dict) -> dict:
    """``env`` (a child's environment) with the variant's messages first."""
    prefix = variant_prefix()

    def before(key: str, value: Path) -> str:
        return os.pathsep.join([str(value)] + ([env[key]] if env.get(key) else []))

    return {**env,
            "PYTHONPATH": before("PYTHONPATH", _site(prefix)),
            "LD_LIBRARY_PATH": before("LD_LIBRARY_PATH", prefix / "lib"),
            "AMENT_PREFIX_PATH": before("AMENT_PREFIX_PATH", prefix)}
