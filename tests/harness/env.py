"""Where things are and what environment a test's processes get: the
repository and the venv, the YARP installs of the test matrix and the one the
helpers use (the ``yarp`` fixture makes its version the active one), free
ports, and a clean environment for child processes.

    ROOT, EXAMPLES, LEGACY_DIR, VENV, VENV_PYTHON, SITE_PACKAGES, PEERS, YARP_CACHE, SETUP_HINT
    YarpInstall: one YARP (.version, .prefix, .bin, .python_path, .has_ros1);
    yarp_install(version) -> YarpInstall ("3.5": PyPI's, in the venv; others
    built by scripts/build_yarp.sh); MATRIX, the versions the tests run on;
    DEFAULT_YARP; active_yarp() / use_yarp(install): the one the helpers use
    cmake_prefix_path(install=None) -> "<yarp prefix>;<ycm prefix>" for -DCMAKE_PREFIX_PATH
    fail(msg)           pytest.fail, without a traceback
    python_imports(python, modules, path="") -> None or the error
    free_port() -> int, release_port(port)
    base_env(tmpdir=None, install=None) -> dict   os.environ + PATH (real YARP binaries, venv bin)
    clean_environ() -> dict   os.environ without any ROS / YARP setting of the machine
"""
from __future__ import annotations

import functools
import os
import random
import re
import socket
import subprocess
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

ROOT = Path(__file__).resolve().parents[2]
VENV = Path(os.environ.get("YBG_VENV", ROOT / ".venv"))
VENV_PYTHON = VENV / "bin" / "python"
#: the peer scripts (JSON lines over stdin/stdout): tests/peers/
PEERS = ROOT / "tests" / "peers"
EXAMPLES = ROOT / "examples"
#: the thesis' configs, in the legacy form
LEGACY_DIR = ROOT.parent / "shared" / "legacy"
LOCALHOST = "127.0.0.1"


def _site_packages() -> Path:
    found = sorted(VENV.glob("lib/python3*/site-packages"))
    return found[-1] if found else VENV / "lib" / "python3" / "site-packages"


SITE_PACKAGES = _site_packages()
#: where scripts/build_yarp.sh builds the YARP releases PyPI does not have
YARP_CACHE = Path(os.environ.get("YBG_CACHE")
                  or Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "ybgc")

SETUP_HINT = (
    "Install it with `scripts/setup.sh` (run from the repository root; the first "
    "run builds YARP 3.5 in about 6 minutes, later runs take seconds), then run "
    "the tests with `.venv/bin/python -m pytest`."
)


def _version_key(version: str) -> tuple:
    return tuple(int(x) for x in re.findall(r"\d+", version))


@dataclass(frozen=True)
class YarpInstall:
    """One YARP installation the tests run against: the PyPI 3.5 in the venv
    (``version`` "3.5") or a release built from its sources by
    ``scripts/build_yarp.sh`` into a prefix of its own."""
    version: str
    prefix: Path                  # CMake package prefix (lib/cmake/YARP)
    bin: Path                     # yarpserver, yarp, yarprun, ...
    python_path: Optional[Path]   # the bindings' folder (None: the venv's own `yarp`)
    ycm: Optional[Path]           # YCM's prefix, for CMake

    @property
    def key(self) -> tuple:
        return _version_key(self.version)

    @property
    def has_ros1(self) -> bool:
        """YARP's own ROS 1 support (tcpros, xmlrpc, yarpidl_rosmsg, `yarpserver
        --ros`): removed from YARP in 3.10."""
        return self.key < (3, 10)

    def cmake_prefix_path(self) -> str:
        return ";".join(str(p) for p in (self.prefix, self.ycm) if p is not None)

    def missing(self) -> list:
        """What is missing for this install to be usable (empty: usable)."""
        if self.python_path is not None and not (self.prefix / ".ybg-built").exists():
            return [str(self.prefix / ".ybg-built")]  # not built, or its build did not finish
        need = [self.bin / "yarpserver", self.bin / "yarp"]
        if self.python_path is not None:
            need.append(self.python_path / "yarp.py")
        return [str(p) for p in need if not p.exists()]

    def build_hint(self) -> str:
        if self.python_path is None:
            return SETUP_HINT
        return (f"Build it with `scripts/setup.sh --yarp {self.version}` (from "
                f"../shared/vendor/yarp-{self.version}.tar.xz into {self.prefix}, "
                f"12-14 minutes on 2 cores, once per machine).")


#: the YARP versions of the test matrix: PyPI's, and the two current releases
MATRIX = ("3.5", "3.12.3", "4.0.0")


def _newest(paths) -> Optional[Path]:
    found = sorted(paths, key=lambda p: _version_key(p.name))
    return found[-1] if found else None


def yarp_install(version: str = "3.5") -> YarpInstall:
    """The install of ``version`` (whether or not it is there: see
    ``YarpInstall.missing``). "3.5" is PyPI's, in the venv."""
    if version in ("3.5", "3.5.0"):
        prefix = SITE_PACKAGES / "yarp"
        return YarpInstall("3.5", prefix, prefix / "bin", None,
                           SITE_PACKAGES / "ycm_cmake_modules")
    prefix = YARP_CACHE / f"yarp-{version}"
    site = _newest(prefix.glob("lib/python3*/site-packages")) or prefix / "lib" / "python3" / "site-packages"
    ycm = _newest(p for p in YARP_CACHE.glob("ycm-*") if (p / ".ybg-built").exists())
    return YarpInstall(version, prefix, prefix / "bin", site, ycm)


DEFAULT_YARP = yarp_install("3.5")
_ACTIVE: list = [DEFAULT_YARP]


def active_yarp() -> YarpInstall:
    """The YARP install the helpers use when none is given."""
    return _ACTIVE[0]


def use_yarp(install: YarpInstall) -> None:
    """Make ``install`` the one the helpers use (the ``yarp`` fixture does)."""
    _ACTIVE[0] = install


def cmake_prefix_path(install: Optional[YarpInstall] = None) -> str:
    """Value for ``-DCMAKE_PREFIX_PATH`` to build C++ against YARP (and YCM)."""
    return (install or active_yarp()).cmake_prefix_path()


# --------------------------------------------------------------------------
# checks


def fail(msg: str):
    """Fail the test (pytest.fail, without a traceback)."""
    import pytest

    pytest.fail(msg, pytrace=False)


@functools.lru_cache(maxsize=None)
def python_imports(python: str, modules: str, path: str = "") -> Optional[str]:
    """None if ``python -c 'import <modules>'`` works (with ``path`` as
    PYTHONPATH), else the error."""
    if not Path(python).exists():
        return f"{python} does not exist"
    env = clean_environ()
    if path:
        env["PYTHONPATH"] = path
    try:
        r = subprocess.run([python, "-c", "import " + modules],
                           capture_output=True, text=True, timeout=60, env=env)
    except subprocess.TimeoutExpired:
        return f"{python} -c 'import {modules}' timed out"
    if r.returncode:
        lines = (r.stderr or r.stdout).strip().splitlines()
        return lines[-1] if lines else f"exit status {r.returncode}"
    return None


# --------------------------------------------------------------------------
# ports and environment


def _ephemeral_range() -> tuple:
    try:
        lo, hi = Path("/proc/sys/net/ipv4/ip_local_port_range").read_text().split()
        return int(lo), int(hi)
    except (OSError, ValueError):
        return 32768, 60999


def _port_free(port: int) -> bool:
    with socket.socket() as s:
        try:
            s.bind((LOCALHOST, port))
            return True
        except OSError:
            return False


#: the port ranges free_port() handed out in this process, (start, span,
#: when): a range is free of bound ports when chosen, but its server binds the
#: ports after the first only as they register, so two rigs started at once
#: (the benchmark's rigs, parallel fixtures) must not be handed overlapping
#: ranges; a range is given back by release_port(), or forgotten after
#: _HANDED_OUT_FOR seconds
_HANDED_OUT: list = []
_HANDED_OUT_FOR = 60.0
_HANDED_OUT_LOCK = threading.Lock()


def free_port(span: int = 64) -> int:
    """A TCP port on 127.0.0.1 that is free now, with the ``span`` ports after
    it free too: yarpserver hands out <port>+2, +3, ... to the ports that
    register with it. Chosen at random below the kernel's ephemeral range
    (where outgoing connections would take them) and above 20000 (clear of
    YARP's and ROS's default ports), away from the ranges this process has
    handed out already. Under pytest-xdist each worker draws from a slice of
    its own, so that two workers never hand out one range at once."""
    lo, _ = _ephemeral_range()
    bottom, top = 20000, max(20000 + 1000, lo - span - 1)
    workers = int(os.environ.get("PYTEST_XDIST_WORKER_COUNT") or 1)
    worker = os.environ.get("PYTEST_XDIST_WORKER", "")
    if workers > 1 and worker.startswith("gw") and worker[2:].isdigit():
        width = (top - bottom) // workers
        bottom += int(worker[2:]) % workers * width
        top = bottom + width
    rnd = random.Random(os.getpid() ^ time.monotonic_ns() ^ threading.get_ident())
    with _HANDED_OUT_LOCK:
        now = time.monotonic()
        _HANDED_OUT[:] = [r for r in _HANDED_OUT if now - r[2] < _HANDED_OUT_FOR]
        for _ in range(200):
            port = rnd.randrange(bottom, top)
            if any(port < start + width and start < port + span for start, width, _ in _HANDED_OUT):
                continue
            if all(_port_free(p) for p in range(port, port + span, 4)) and _port_free(port):
                if all(_port_free(p) for p in range(port, port + span)):
                    _HANDED_OUT.append((port, span, now))
                    return port
    raise RuntimeError("no free port range found")


def release_port(port: int) -> None:
    """Gives back the range free_port() handed out at ``port``."""
    with _HANDED_OUT_LOCK:
        _HANDED_OUT[:] = [r for r in _HANDED_OUT if r[0] != port]


_ENV_DROP = ("ROS_MASTER_URI", "ROS_IP", "ROS_HOSTNAME", "ROS_DOMAIN_ID",
             "ROS_LOCALHOST_ONLY", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS",
             "YARP_CONF", "YARP_CONFIG_HOME", "YARP_DATA_HOME", "YARP_CACHE_HOME",
             "YARP_IP", "YARP_NAMESPACE", "PYTHONHOME", "PYTHONPATH")


def clean_environ() -> dict:
    """os.environ without any ROS / YARP setting of the machine."""
    return {k: v for k, v in os.environ.items() if k not in _ENV_DROP}


def base_env(tmpdir: Optional[os.PathLike] = None, install: Optional[YarpInstall] = None) -> dict:
    """os.environ without any ROS / YARP settings of the machine, with PATH
    starting with the real YARP binaries (of ``install``, default the active
    one) and the venv's bin, PYTHONPATH to its Python bindings when they are
    not the venv's own, unbuffered Python output, and (with a tmpdir) ROS
    logs kept in that folder."""
    install = install or active_yarp()
    env = clean_environ()
    env["PATH"] = os.pathsep.join([str(install.bin), str(VENV / "bin"), env.get("PATH", "/usr/bin:/bin")])
    if install.python_path is not None:
        env["PYTHONPATH"] = str(install.python_path)
    env["VIRTUAL_ENV"] = str(VENV)
    env["PYTHONUNBUFFERED"] = "1"
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    if tmpdir is not None:
        ros_home = Path(tmpdir) / "ros_home"
        ros_home.mkdir(parents=True, exist_ok=True)
        env["ROS_HOME"] = str(ros_home)
        env["ROS_LOG_DIR"] = str(ros_home / "log")
    return env
