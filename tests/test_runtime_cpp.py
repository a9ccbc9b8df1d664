"""The C++ runtime library's unit tests (tests/runtime/test_runtime.cpp),
built against the oldest and the newest YARP of the matrix and run with no
name server: the
runtime's logic (values printed, converters, output Bottles, checks of input
Bottles, whose float32 rule differs between YARP 3 and 4) as plain code. Its
ROS 2 side (tests/runtime/ros2/test_ros2_runtime.cpp) likewise, built
against the ROS 2 wheels, with no ROS 2 graph.

Beyond it, for a module generated for another runtime version: its build
stops with a message that says what to do."""

from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

import ybg
from harness.build import find_once_option
from harness.generated import ybgc
from harness.env import VENV
from harness.ros2 import require_ros2
from ybg.backends.runtime import CPP_DIR

ROOT = Path(__file__).resolve().parent.parent
SOURCE = Path(__file__).resolve().parent / "runtime"


def cmake_build(src: Path, build: Path, install, target: str | None = None,
                options: tuple = ()) -> subprocess.CompletedProcess:
    r = subprocess.run(["cmake", "-S", str(src), "-B", str(build),
                        f"-DCMAKE_PREFIX_PATH={install.cmake_prefix_path()}", find_once_option(), *options],
                       capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        return r
    cmd = ["cmake", "--build", str(build), "-j2"] + (["--target", target] if target else [])
    return subprocess.run(cmd, capture_output=True, text=True, timeout=900)


# on YARP 3.5 and 4.0.0, one of each major version (its float32 rule);
# 3.12.3 is the version tests' (docs/yarp-versions.md)
@pytest.mark.yarp_ends
def test_runtime_unit_tests(yarp, tmp_path):
    built = cmake_build(SOURCE, tmp_path / "build", yarp)
    assert built.returncode == 0, built.stdout[-4000:] + built.stderr[-4000:]
    run = subprocess.run([str(tmp_path / "build" / "test_runtime")], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stdout + run.stderr
    checks, = [line for line in run.stdout.splitlines() if " checks, " in line]
    assert checks.startswith(tuple(f"{n} checks, 0 failed" for n in range(60, 1000))), checks
    assert f"(YARP {yarp.version}" in checks or yarp.version == "3.5", checks


@pytest.mark.yarp_min((4, 0))
def test_ros2_runtime_unit_tests(yarp, tmp_path):
    """The helpers a module's ROS 2 message builder calls (they depend on
    no YARP release: built against the newest)."""
    require_ros2()
    built = cmake_build(SOURCE / "ros2", tmp_path / "build", yarp, options=(f"-DYBGC_ROS2_PYTHON_ENV={VENV}",))
    assert built.returncode == 0, built.stdout[-4000:] + built.stderr[-4000:]
    run = subprocess.run([str(tmp_path / "build" / "test_ros2_runtime"), str(tmp_path)], capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0, run.stdout + run.stderr
    checks, = [line for line in run.stdout.splitlines() if " checks, " in line]
    assert checks.startswith(tuple(f"{n} checks, 0 failed" for n in range(90, 1000))), checks


# the check is the runtime's own (a preprocessor test): any YARP shows it
@pytest.mark.yarp_min((4, 0))
def test_module_build_refuses_a_runtime_of_another_version(yarp, tmp_path):
    out = tmp_path / "module"
    r = ybgc(ROOT / "examples" / "yarp_to_yarp_end_effector.ini", "--backend", "cpp", "-o", out)
    assert r.returncode == 0, r.stderr
    header = out / "ybgc_runtime.hpp"
    header.write_text(header.read_text().replace(f'#define YBGC_RUNTIME_VERSION "{ybg.__version__}"',
                                                 '#define YBGC_RUNTIME_VERSION "0.1.9"'))
    built = cmake_build(out, out / "build", yarp)
    assert built.returncode != 0
    assert (f"this module was generated for ybgc's runtime library {ybg.__version__}: generate it again"
            in built.stdout + built.stderr), built.stdout[-3000:]
    assert (CPP_DIR / "ybgc_runtime.hpp").read_text().count("YBGC_RUNTIME_VERSION") >= 1
