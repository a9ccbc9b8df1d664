"""Real middleware for the tests: YARP (PyPI's 3.5, and 3.12.3 and 4.0.0 built
from their sources), ROS 1 (Debian) and ROS 2 (rclpy).

Nothing here is mocked. Every helper is a context manager that starts real
processes, each in its own process group, and on exit stops them (SIGTERM,
then SIGKILL of the whole group), so nothing is left running; an ``atexit``
hook stops anything a crashed test left behind. Everything runs on 127.0.0.1,
with its own free ports and temporary YARP / ROS folders.

Install the middleware with ``scripts/setup.sh``; a test that needs missing
middleware fails (``require_yarp()`` and friends), it is never skipped.

Paths and checks
    ROOT, VENV, VENV_PYTHON, SITE_PACKAGES, YARP_PREFIX, YARP_BIN, YCM_PREFIX
    YarpInstall: one YARP (.version, .prefix, .bin, .python_path, .has_ros1);
    yarp_install(version) -> YarpInstall ("3.5": PyPI's, in the venv; others
    built by scripts/build_yarp.sh); MATRIX, the versions the tests run on;
    active_yarp() / use_yarp(install): the one the helpers use by default
    (the ``yarp`` fixture sets it); YARP_PREFIX, YARP_BIN, YCM_PREFIX are its
    cmake_prefix_path(install=None) -> "<yarp prefix>;<ycm prefix>" for -DCMAKE_PREFIX_PATH
    require_yarp(install=None), require_ros1(), require_ros2()   pytest.fail with how to install
    free_port() -> int
    run_folder(tmp_path_factory, name) -> Path   a folder every pytest-xdist worker of the run sees
    held(path)          with: an exclusive lock on a file across processes (build once per run)
    base_env(tmpdir=None) -> dict   os.environ + PATH (real YARP binaries, venv bin)

Servers
    yarp_env(tmpdir, port, ip="127.0.0.1") -> dict   YARP_CONFIG/DATA/CACHE_HOME=tmpdir,
                                        YARP_IP=ip, writes <tmpdir>/yarp.conf "<ip> <port> yarp"
    YarpServer(ros=False, ros_master_uri=None, install=None)
        .port, .install, .env (full environment for child processes), .tmpdir,
        .yarp(*args) -> CompletedProcess of the real `yarp` CLI,
        .exists(port_name) -> bool, .wait_port(name, timeout)
    RosCore()           Debian `roscore -p <free port>`: .port, .uri, .ros_env, .env
    TypeServer(yarp_server, msg_types=["sensor_msgs/JointState"])
                        `yarpidl_rosmsg --name /typ@/yarpidl` run from a folder
                        holding the .msg files (and their dependencies);
                        msg_types=None: every type in /usr/share/*/msg
    YarpRosStack(msg_types=None)   RosCore + YarpServer(ros=True) + TypeServer,
                        in that order: .env (YARP + ROS_MASTER_URI/ROS_IP), .port,
                        .uri, .roscore, .yarp_server, .type_server, .exists(name)
    ros2_env(domain_id=None) -> dict    ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST,
                        ROS_DOMAIN_ID (default: one reserved for this test run)
    Ros2Domain()        context manager reserving its own domain id: .domain_id, .env

Peers (scripts in tests/peers/, JSON lines over stdin/stdout)
    YarpProducer(env, port, bottles=None, rate=None, count=None, envelope=False,
                 wait_connected=False, connect_to=None)
        .write(data, stamp=None), .output_count(), .wait_outputs(n), .sent,
        .kill(), .stop(), .start() (restart after kill/stop)
    YarpReader(env, port, source=None, carrier="", poll=0.2)
        .bottles: list of Received(t, data, types, stamp, text),
        .wait_for(n, timeout) -> list, .wait_connected(), .clear()
        With a source it reconnects source -> port by itself (polling connect).
    RospySubscriber(env, topic, msg_type="sensor_msgs/JointState")  (/usr/bin/python3)
    Ros2Subscriber(env, topic, msg_type="sensor_msgs/msg/JointState")
        .messages: list of Message(t, msg as nested dicts), .wait_for(n),
        .wait_publishers(n) / .wait_matched(n)
    Ros2Publisher(env, topic, msg_type=..., messages=None, rate=None, count=None,
                  wait_matched=False, stamp_now=False)
        .publish(dict), .wait_matched(n), .sent
    Proc(argv, env=None, cwd=None, name=None)   any other process (e.g. a
        generated module), in a process group of its own, stdout+stderr to
        .log_path: .start(), .stop(timeout=3, sig=SIGTERM) -> exit status,
        .kill(), .wait_exit(timeout), .alive, .group_alive(), .log_text(),
        .returncode. stop() also kills descendants that left the group.
    Peer.wait(pred, timeout), .wait_event(name), .events: the raw peer events.
    stop_all(), live_processes(), tmp_root() (one folder per run, removed at exit;
    kept with YBG_KEEP_TMP=1)

Bottle values in Python (see tests/peers/bottle_codec.py): int -> int32 (int64 if
large), float -> float64, str -> string, list -> nested list; force a type with
{"int64": n}, {"float32": x}, {"vocab": "abcd"}. A received Bottle gives ``data``
(plain lists) and ``types`` (same shape, wire type of every leaf: "int32",
"int64", "float64", "string", "vocab", ...).

Example::

    from middleware import YarpServer, YarpProducer, YarpReader

    def test_roundtrip(yarp_server):             # fixture from conftest.py
        env = yarp_server.env
        with YarpReader(env, "/test/in", source="/test/out") as reader, \\
             YarpProducer(env, "/test/out") as producer:
            reader.wait_connected()
            producer.write([1, 2.5, "a", [3, 4]])
            (got,) = reader.wait_for(1)
            assert got.data == [1, 2.5, "a", [3, 4]]
            assert got.types == ["int32", "float64", "string", ["int32", "int32"]]
"""
from __future__ import annotations

import atexit
import fcntl
import functools
import json
import os
import re
import shutil
import signal
import socket
import subprocess
import tempfile
import threading
import time
import xmlrpc.client
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Optional

ROOT = Path(__file__).resolve().parents[1]
VENV = Path(os.environ.get("YBG_VENV", ROOT / ".venv"))
VENV_PYTHON = VENV / "bin" / "python"
PEERS = Path(__file__).resolve().parent / "peers"
ROS1_PYTHON = "/usr/bin/python3"
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


def __getattr__(name):  # YARP_PREFIX, YARP_BIN, YCM_PREFIX: of the active install
    install = active_yarp()
    if name == "YARP_PREFIX":
        return install.prefix
    if name == "YARP_BIN":
        return install.bin
    if name == "YCM_PREFIX":
        return install.ycm
    raise AttributeError(name)


def cmake_prefix_path(install: Optional[YarpInstall] = None) -> str:
    """Value for ``-DCMAKE_PREFIX_PATH`` to build C++ against YARP (and YCM)."""
    return (install or active_yarp()).cmake_prefix_path()


# --------------------------------------------------------------------------
# checks


def _fail(msg: str):
    import pytest

    pytest.fail(msg, pytrace=False)


@functools.lru_cache(maxsize=None)
def _python_imports(python: str, modules: str, path: str = "") -> Optional[str]:
    """None if ``python -c 'import <modules>'`` works (with ``path`` as
    PYTHONPATH), else the error."""
    if not Path(python).exists():
        return f"{python} does not exist"
    env = _clean_environ()
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


def require_yarp(install: Optional[YarpInstall] = None) -> None:
    """Fail the test (never skip) unless YARP (the active install: PyPI's 3.5
    unless the ``yarp`` fixture chose another) is installed."""
    install = install or active_yarp()
    missing = [str(VENV_PYTHON)] if not VENV_PYTHON.exists() else []
    missing += install.missing()
    if missing:
        _fail(f"YARP {install.version} is not installed: missing {', '.join(missing)}. "
              f"{install.build_hint()}")
    err = _python_imports(str(VENV_PYTHON), "yarp", str(install.python_path or ""))
    if err:
        _fail(f"`import yarp` of YARP {install.version} fails in {VENV_PYTHON}: {err}. "
              f"{install.build_hint()}")


def require_ros1() -> None:
    """Fail the test unless Debian's ROS 1 (roscore, rospy, message packages) is there."""
    require_yarp()
    missing = [p for p in ("/usr/bin/roscore", "/usr/share/sensor_msgs/msg/JointState.msg",
                           "/usr/share/std_msgs/msg/Header.msg", ROS1_PYTHON)
               if not Path(p).exists()]
    if missing:
        _fail(f"ROS 1 is not installed: missing {', '.join(missing)} (Debian packages "
              f"ros-core python3-rospy python3-sensor-msgs ros-sensor-msgs ros-std-msgs). "
              f"{SETUP_HINT}")
    err = _python_imports(ROS1_PYTHON, "rospy, roslib.message, sensor_msgs.msg")
    if err:
        _fail(f"rospy does not import in {ROS1_PYTHON}: {err}. {SETUP_HINT}")
    install = active_yarp()
    if not install.has_ros1:
        _fail(f"YARP {install.version} has no ROS 1 support (removed in YARP 3.10): "
              f"a ROS 1 test runs on YARP 3.5 only")
    if not (install.bin / "yarpidl_rosmsg").exists():
        _fail(f"yarpidl_rosmsg is missing from {install.bin}. {SETUP_HINT}")


def require_ros2() -> None:
    """Fail the test unless the ROS 2 rclpy wheels are installed in the venv."""
    err = _python_imports(str(VENV_PYTHON),
                          "rclpy, sensor_msgs.msg, std_msgs.msg, geometry_msgs.msg")
    if err:
        _fail(f"ROS 2 (rclpy wheels) not usable in {VENV_PYTHON}: {err}. {SETUP_HINT}")


# --------------------------------------------------------------------------
# environment


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
    import random

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


def run_folder(tmp_path_factory, name: str) -> Path:
    """A folder of this test run that every pytest-xdist worker sees (the
    run's base folder, of which each worker's is a subfolder; without
    xdist, the session's), for what is built once per run."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent
    folder = base / name
    folder.mkdir(parents=True, exist_ok=True)
    return folder


class held:
    """``with held(path):`` an exclusive lock on the file ``path`` (created),
    across processes: the pytest-xdist workers building one thing take
    turns, and the later ones find it built."""

    def __init__(self, path: Path):
        self.path = path

    def __enter__(self):
        self.fd = os.open(self.path, os.O_CREAT | os.O_RDWR, 0o644)
        fcntl.flock(self.fd, fcntl.LOCK_EX)
        return self

    def __exit__(self, *exc):
        fcntl.flock(self.fd, fcntl.LOCK_UN)
        os.close(self.fd)


def release_port(port: int) -> None:
    """Gives back the range free_port() handed out at ``port``."""
    with _HANDED_OUT_LOCK:
        _HANDED_OUT[:] = [r for r in _HANDED_OUT if r[0] != port]


_ENV_DROP = ("ROS_MASTER_URI", "ROS_IP", "ROS_HOSTNAME", "ROS_DOMAIN_ID",
             "ROS_LOCALHOST_ONLY", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS",
             "YARP_CONF", "YARP_CONFIG_HOME", "YARP_DATA_HOME", "YARP_CACHE_HOME",
             "YARP_IP", "YARP_NAMESPACE", "PYTHONHOME", "PYTHONPATH")


def _clean_environ() -> dict:
    env = {k: v for k, v in os.environ.items() if k not in _ENV_DROP}
    return env


def base_env(tmpdir: Optional[os.PathLike] = None, install: Optional[YarpInstall] = None) -> dict:
    """os.environ without any ROS / YARP settings of the machine, with PATH
    starting with the real YARP binaries (of ``install``, default the active
    one) and the venv's bin, PYTHONPATH to its Python bindings when they are
    not the venv's own, unbuffered Python output, and (with a tmpdir) ROS
    logs kept in that folder."""
    install = install or active_yarp()
    env = _clean_environ()
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


def yarp_env(tmpdir: os.PathLike, port: int, ip: str = LOCALHOST) -> dict:
    """The YARP variables (only those) for a name server on <ip>:<port>
    (default 127.0.0.1), with all YARP configuration in ``tmpdir`` (writes
    <tmpdir>/yarp.conf); ports register on ``ip`` (YARP_IP)."""
    tmp = Path(tmpdir)
    tmp.mkdir(parents=True, exist_ok=True)
    (tmp / "yarp.conf").write_text(f"{ip} {port} yarp\n")
    return {
        "YARP_CONFIG_HOME": str(tmp),
        "YARP_DATA_HOME": str(tmp),
        "YARP_CACHE_HOME": str(tmp),
        "YARP_IP": ip,
    }


# ROS 2 domain ids: one per test run, reserved with a lock file so that two
# runs at the same time on this machine never share one.
_DOMAIN_LOCKS: dict = {}
_DOMAIN_LOCK = threading.Lock()
_RUN_DOMAIN: list = []


def reserve_domain_id() -> int:
    """Reserve a ROS 2 domain id in 1..100 that no other process holds
    (lock file under the temp dir, released when this process ends or by
    ``release_domain_id``). The search starts at a value derived from the pid."""
    with _DOMAIN_LOCK:
        start = os.getpid() % 100
        for i in range(100):
            did = (start + i) % 100 + 1
            if did in _DOMAIN_LOCKS:
                continue
            path = Path(tempfile.gettempdir()) / f"ybg-ros2-domain-{did}.lock"
            fd = os.open(path, os.O_CREAT | os.O_RDWR, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                continue
            _DOMAIN_LOCKS[did] = fd
            return did
    raise RuntimeError("all ROS 2 domain ids 1..100 are in use")


def release_domain_id(did: int) -> None:
    with _DOMAIN_LOCK:
        fd = _DOMAIN_LOCKS.pop(did, None)
        if fd is not None:
            os.close(fd)


def ros2_env(domain_id: Optional[int] = None) -> dict:
    """ROS 2 variables (only those): localhost-only discovery and a domain id
    (default: one reserved for this whole test run)."""
    if domain_id is None:
        with _DOMAIN_LOCK:
            have = _RUN_DOMAIN[0] if _RUN_DOMAIN else None
        if have is None:
            have = reserve_domain_id()
            _RUN_DOMAIN.append(have)
        domain_id = have
    return {
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "ROS_DOMAIN_ID": str(domain_id),
        "RMW_IMPLEMENTATION": "rmw_fastrtps_cpp",
    }


# --------------------------------------------------------------------------
# processes

_SETPRIV = shutil.which("setpriv")
_LIVE: "set[Proc]" = set()
_LIVE_LOCK = threading.Lock()


def _proc_table() -> dict:
    """{pid: (state, ppid, pgrp, starttime)} of every process."""
    table = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        rest = stat[stat.rfind(")") + 2:].split()
        # rest[0] state, rest[1] ppid, rest[2] pgrp, rest[19] starttime
        try:
            table[int(d)] = (rest[0], int(rest[1]), int(rest[2]), int(rest[19]))
        except (IndexError, ValueError):
            continue
    return table


def _group_members(pgid: int) -> list:
    """Pids of the live (non-zombie) processes in process group ``pgid``."""
    return [pid for pid, (st, _, pg, _) in _proc_table().items()
            if pg == pgid and st not in ("Z", "X")]


def _tree(root: int, pgid: Optional[int]) -> set:
    """{(pid, starttime)} of the live processes in group ``pgid`` and of all
    descendants of ``root`` and of those group members (some programs, e.g.
    roslaunch, put their children in sessions of their own)."""
    table = _proc_table()
    children: dict = {}
    for pid, (_, ppid, _, _) in table.items():
        children.setdefault(ppid, []).append(pid)
    todo = [root] + [pid for pid, v in table.items() if pgid is not None and v[2] == pgid]
    seen = set()
    while todo:
        pid = todo.pop()
        if pid in seen or pid not in table:
            continue
        seen.add(pid)
        todo.extend(children.get(pid, []))
    return {(pid, table[pid][3]) for pid in seen if table[pid][0] not in ("Z", "X")}


def _still_running(known: set) -> set:
    table = _proc_table()
    return {(pid, st) for pid, st in known
            if pid in table and table[pid][3] == st and table[pid][0] not in ("Z", "X")}


class Proc:
    """A process started in its own process group (session), output to a log
    file (or, with ``pipe_stdout``, stdout to a pipe and stderr to the log).
    Context manager: started on enter, stopped (whole group) on exit."""

    def __init__(self, argv: Iterable, env: Optional[dict] = None, cwd=None,
                 name: Optional[str] = None, log_dir=None, pipe_stdout: bool = False,
                 pipe_stdin: bool = False, die_with_parent: bool = False,
                 gate_output: bool = False):
        self.argv = [str(a) for a in argv]
        self.env = dict(env) if env is not None else base_env()
        self.cwd = str(cwd) if cwd is not None else None
        self.name = name or Path(self.argv[0]).name
        self.log_dir = Path(log_dir) if log_dir else tmp_root()
        base = re.sub(r"[^A-Za-z0-9_.-]", "_", self.name)
        self.log_path = self.log_dir / f"{base}.log"
        k = 1
        while self.log_path.exists():
            k += 1
            self.log_path = self.log_dir / f"{base}.{k}.log"
        self.pipe_stdout = pipe_stdout
        self.pipe_stdin = pipe_stdin
        self.die_with_parent = die_with_parent
        self.gate_output = gate_output and not pipe_stdout
        self._gate: Optional[_OutputGate] = None
        self.popen: Optional[subprocess.Popen] = None
        self.pgid: Optional[int] = None
        self._known: set = set()
        self.starts = 0

    # -- lifecycle
    def start(self) -> "Proc":
        if self.alive:
            return self
        self.starts += 1
        log = open(self.log_path, "ab")
        log.write(f"==== start {self.starts}: {' '.join(self.argv)}\n".encode())
        log.flush()
        argv = self.argv
        # With die_with_parent the process gets SIGKILL if the test process
        # itself is killed (no atexit then). The kernel ties this to the thread
        # that starts it, so only from the main thread.
        if self.die_with_parent and _SETPRIV and threading.current_thread() is threading.main_thread():
            argv = [_SETPRIV, "--pdeathsig", "KILL", "--"] + argv
        stdout = subprocess.PIPE if self.pipe_stdout else log
        if self.gate_output:
            self._gate = _OutputGate(self.log_path)
            stdout = self._gate.write_fd
        try:
            self.popen = subprocess.Popen(
                argv, env=self.env, cwd=self.cwd,
                stdin=subprocess.PIPE if self.pipe_stdin else subprocess.DEVNULL,
                stdout=stdout, stderr=log, start_new_session=True)
        finally:
            log.close()
            if self._gate is not None:
                self._gate.started()
        self.pgid = self.popen.pid
        self._known = set()
        with _LIVE_LOCK:
            _LIVE.add(self)
        return self

    @property
    def pid(self) -> Optional[int]:
        return self.popen.pid if self.popen else None

    @property
    def alive(self) -> bool:
        return self.popen is not None and self.popen.poll() is None

    @property
    def returncode(self) -> Optional[int]:
        return self.popen.poll() if self.popen else None

    def tree(self) -> set:
        """{(pid, starttime)} of the live processes it started: its process
        group and every descendant (also those in sessions of their own),
        plus any seen at an earlier stop()."""
        if self.pgid is None:
            return set()
        self._known |= _tree(self.pgid, self.pgid)
        return _still_running(self._known)

    def group_alive(self) -> bool:
        """True while any process of its tree (group + descendants) runs."""
        return bool(self.tree())

    def _signal_group(self, sig) -> None:
        if self.pgid is None:
            return
        try:
            os.killpg(self.pgid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    def _kill_tree(self) -> None:
        for pid, _ in _still_running(self._known):
            try:
                os.kill(pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass

    def stop(self, timeout: float = 3.0, sig=signal.SIGTERM) -> Optional[int]:
        """Send ``sig`` to the whole group, wait up to ``timeout`` s for the
        process and everything it started to end, then SIGKILL whatever is
        left (group and descendants). Returns the exit status."""
        if self.popen is None:
            return None
        self.release_output()  # a held stdout would keep it from exiting
        self.tree()  # remember the descendants before they get orphaned
        if self.popen.poll() is None:
            self._signal_group(sig)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.popen.poll()
            if not self.tree():
                break
            time.sleep(0.02)
        end = time.monotonic() + 5
        while True:
            self.popen.poll()
            if not self.tree():
                break
            self._signal_group(signal.SIGKILL)
            self._kill_tree()
            if time.monotonic() > end:
                break
            time.sleep(0.02)
        try:
            self.popen.wait(5)
        except subprocess.TimeoutExpired:
            pass
        self._close_pipes()
        if self._gate is not None:
            self._gate.finish()
        with _LIVE_LOCK:
            _LIVE.discard(self)
        return self.popen.returncode

    def kill(self) -> Optional[int]:
        """SIGKILL the whole group at once (a crash, as seen by its peers)."""
        if self.popen is None:
            return None
        self.tree()
        self._signal_group(signal.SIGKILL)
        self._kill_tree()
        return self.stop(timeout=2.0)

    def _close_pipes(self) -> None:
        for f in (self.popen.stdin, self.popen.stdout):
            if f is not None:
                try:
                    f.close()
                except OSError:
                    pass

    # -- a held stdout (gate_output=True)
    def hold_output(self) -> None:
        """Stop copying the process's stdout to its log: once the small pipe
        (one page) is full, every thread of the process that writes on
        stdout blocks in write(2), the others run on. A test uses it to
        hold up exactly the threads that print (e.g. a module's --verbose
        values, printed by the thread that builds each message)."""
        if self._gate is None:
            raise RuntimeError(f"{self.name}: started without gate_output=True")
        self._gate.hold()

    def release_output(self) -> None:
        """Copy stdout to the log again (the blocked writers go on)."""
        if self._gate is not None:
            self._gate.release()

    def output_blocked(self) -> list:
        """The threads of the process asleep in a write(2)/writev(2) on its
        stdout (fd 1): those a held stdout holds up. [] when none."""
        if self.popen is None or self.popen.poll() is not None:
            return []
        out = []
        task = Path(f"/proc/{self.popen.pid}/task")
        try:
            tids = os.listdir(task)
        except OSError:
            return []
        for tid in tids:
            try:
                fields = (task / tid / "syscall").read_text().split()
            except OSError:
                continue
            # "<nr> <arg0> ...", or "running"; x86_64: write 1, writev 20
            if len(fields) > 1 and fields[0] in ("1", "20") and int(fields[1], 16) == 1:
                out.append(int(tid))
        return out

    def wait_output_blocked(self, timeout: float = 30.0) -> list:
        """Wait until a thread is held up writing on the held stdout."""
        return _wait_until(lambda: self.output_blocked(), timeout,
                           f"a thread of {self.name} blocked on its held stdout", self,
                           interval=0.01)

    def wait_exit(self, timeout: Optional[float] = None) -> int:
        """Wait for the process itself to end; returns its exit status."""
        return self.popen.wait(timeout)

    def log_text(self) -> str:
        try:
            return self.log_path.read_text(errors="replace")
        except OSError:
            return ""

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()

    def __repr__(self):
        return f"<Proc {self.name} pid={self.pid}>"


class _OutputGate:
    """A process's stdout: a one-page pipe that a thread copies to the log
    file, unless held (see Proc.hold_output)."""

    PIPE_SIZE = 4096

    def __init__(self, log_path: Path):
        self.log_path = log_path
        self.read_fd, self.write_fd = os.pipe()
        try:
            fcntl.fcntl(self.write_fd, getattr(fcntl, "F_SETPIPE_SZ", 1031), self.PIPE_SIZE)
        except OSError:
            pass
        self._open = threading.Event()
        self._open.set()
        self._thread = threading.Thread(target=self._pump, daemon=True, name=f"gate {log_path.name}")

    def started(self) -> None:
        os.close(self.write_fd)  # the child holds it now; EOF when it (and its children) exit
        self.write_fd = -1
        self._thread.start()

    def _pump(self) -> None:
        with open(self.log_path, "ab", buffering=0) as log:
            while True:
                self._open.wait()
                try:
                    data = os.read(self.read_fd, 65536)
                except OSError:
                    break
                if not data:
                    break
                log.write(data)

    def hold(self) -> None:
        self._open.clear()

    def release(self) -> None:
        self._open.set()

    def finish(self) -> None:
        self.release()
        self._thread.join(5)
        if not self._thread.is_alive():
            try:
                os.close(self.read_fd)
            except OSError:
                pass


def stop_all() -> None:
    """Stop every process these helpers started that is still running."""
    with _LIVE_LOCK:
        procs = list(_LIVE)
    for p in procs:
        try:
            p.stop(timeout=1.0)
        except Exception:
            pass


def live_processes() -> list:
    """The Procs started by these helpers and not stopped yet."""
    with _LIVE_LOCK:
        return [p for p in _LIVE if p.alive or p.group_alive()]


_TMP_ROOT: list = []


def tmp_root() -> Path:
    """One temporary folder per test run holding every helper's files and logs;
    removed at exit (kept when YBG_KEEP_TMP is set)."""
    with _LIVE_LOCK:
        if not _TMP_ROOT:
            _TMP_ROOT.append(Path(tempfile.mkdtemp(prefix="ybg-tests-")))
        return _TMP_ROOT[0]


def _at_exit() -> None:
    stop_all()
    if _TMP_ROOT and not os.environ.get("YBG_KEEP_TMP"):
        shutil.rmtree(_TMP_ROOT[0], ignore_errors=True)


atexit.register(_at_exit)


def _wait_until(pred: Callable[[], Any], timeout: float, what: str, proc: Optional[Proc] = None,
                interval: float = 0.05):
    end = time.monotonic() + timeout
    while True:
        v = pred()
        if v:
            return v
        if proc is not None and proc.popen is not None and proc.popen.poll() is not None:
            raise RuntimeError(f"{proc.name} exited (status {proc.popen.returncode}) while "
                               f"waiting for {what}; log:\n{proc.log_text()[-3000:]}")
        if time.monotonic() > end:
            tail = f"; log of {proc.name}:\n{proc.log_text()[-3000:]}" if proc else ""
            raise TimeoutError(f"timed out after {timeout} s waiting for {what}{tail}")
        time.sleep(interval)


class _TmpDir:
    """A folder under tmp_root() (or the given one, never removed here)."""

    def __init__(self, prefix: str, tmpdir=None):
        self.own = tmpdir is None
        self.path = Path(tmpdir) if tmpdir else Path(tempfile.mkdtemp(prefix=prefix, dir=tmp_root()))
        self.path.mkdir(parents=True, exist_ok=True)

    def remove(self):
        pass  # kept until the end of the run, so that logs can be read after stop()


# --------------------------------------------------------------------------
# servers


class YarpServer:
    """The real ``yarpserver`` on 127.0.0.1:<free port>, with ``--read`` (and
    ``--ros`` when asked; then ``ros_master_uri`` must point to a running
    roscore). ``.env`` is the full environment for any YARP process that must
    use this server."""

    def __init__(self, ros: bool = False, ros_master_uri: Optional[str] = None,
                 port: Optional[int] = None, tmpdir=None, timeout: float = 20.0,
                 install: Optional[YarpInstall] = None):
        self.install = install
        self.ros = ros
        self.ros_master_uri = ros_master_uri
        self.port = port
        self._tmp_arg = tmpdir
        self.timeout = timeout
        self.proc: Optional[Proc] = None
        self.env: dict = {}

    def start(self) -> "YarpServer":
        if self.install is None:
            self.install = active_yarp()
        require_yarp(self.install)
        if self.ros and not self.ros_master_uri:
            raise ValueError("YarpServer(ros=True) needs ros_master_uri (start a RosCore first)")
        self._tmp = _TmpDir("ybg-yarp-", self._tmp_arg)
        self.tmpdir = self._tmp.path
        # a port chosen here may be taken by another process before the
        # server binds it: then the server exits at once, and another port
        # is tried (a port the caller gave is tried once)
        chosen = self.port is None
        for attempt in range(3 if chosen else 1):
            if chosen:
                self.port = free_port()
            env = base_env(self.tmpdir, self.install)
            env.update(yarp_env(self.tmpdir / "yarp", self.port))
            if self.ros_master_uri:
                env["ROS_MASTER_URI"] = self.ros_master_uri
                env["ROS_IP"] = LOCALHOST
            self.env = env
            argv = [self.install.bin / "yarpserver", "--ip", LOCALHOST, "--socket", self.port, "--read"]
            if self.ros:
                argv.append("--ros")
            self.proc = Proc(argv, env=env, name="yarpserver", log_dir=self.tmpdir,
                             die_with_parent=True).start()
            try:
                _wait_until(lambda: self.exists("/root"), self.timeout,
                            f"yarpserver on port {self.port}", self.proc)
                return self
            except RuntimeError:  # it exited: its port was taken
                self.proc.stop()
                if chosen:
                    release_port(self.port)
                if not chosen or attempt == 2:
                    self.stop()
                    raise
            except BaseException:
                self.stop()
                raise
        return self

    def yarp(self, *args, timeout: float = 20.0, check: bool = False) -> subprocess.CompletedProcess:
        """Run the real ``yarp`` command line tool against this server."""
        return subprocess.run([str(self.install.bin / "yarp"), *map(str, args)], env=self.env,
                              capture_output=True, text=True, timeout=timeout, check=check)

    def exists(self, port_name: str) -> bool:
        try:
            return self.yarp("exists", port_name, timeout=10).returncode == 0
        except subprocess.TimeoutExpired:
            return False

    def wait_port(self, port_name: str, timeout: float = 10.0) -> None:
        """Wait until ``port_name`` is registered and answers."""
        _wait_until(lambda: self.exists(port_name), timeout, f"port {port_name}")

    def name_list(self) -> str:
        return self.yarp("name", "list").stdout

    def stop(self) -> None:
        if self.proc is not None:
            self.proc.stop()
            if self.port is not None:
                release_port(self.port)
        if getattr(self, "_tmp", None) is not None:
            self._tmp.remove()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


class RosCore:
    """Debian's ``roscore -p <free port>`` on 127.0.0.1. ``.ros_env`` holds
    ROS_MASTER_URI / ROS_IP; ``.env`` is a full environment with them."""

    def __init__(self, port: Optional[int] = None, tmpdir=None, timeout: float = 30.0):
        self.port = port
        self._tmp_arg = tmpdir
        self.timeout = timeout
        self.proc: Optional[Proc] = None

    @property
    def uri(self) -> str:
        return f"http://{LOCALHOST}:{self.port}"

    def _master_ok(self) -> bool:
        try:
            proxy = xmlrpc.client.ServerProxy(self.uri)
            socket.setdefaulttimeout(2)
            try:
                code, _, _ = proxy.getSystemState("/ybg_test")
            finally:
                socket.setdefaulttimeout(None)
            return code == 1
        except (OSError, xmlrpc.client.Error):
            return False

    def start(self) -> "RosCore":
        require_ros1()
        self._tmp = _TmpDir("ybg-ros-", self._tmp_arg)
        self.tmpdir = self._tmp.path
        if self.port is None:
            self.port = free_port()
        self.ros_env = {"ROS_MASTER_URI": self.uri, "ROS_IP": LOCALHOST}
        self.env = base_env(self.tmpdir)
        self.env.update(self.ros_env)
        self.proc = Proc(["/usr/bin/roscore", "-p", self.port], env=self.env, name="roscore",
                         log_dir=self.tmpdir, die_with_parent=True).start()
        try:
            _wait_until(self._master_ok, self.timeout, f"roscore on port {self.port}", self.proc,
                        interval=0.1)
        except BaseException:
            self.stop()
            raise
        return self

    def stop(self) -> None:
        if self.proc is not None:
            # roslaunch shuts its children down on SIGINT
            self.proc.stop(timeout=5.0, sig=signal.SIGINT)
        if getattr(self, "_tmp", None) is not None:
            self._tmp.remove()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


_ROS1_BUILTINS = {"bool", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64",
                  "uint64", "float32", "float64", "string", "time", "duration", "byte", "char"}
ROS1_MSG_ROOT = Path("/usr/share")


def ros1_msg_files(msg_types: Iterable[str], root: Path = ROS1_MSG_ROOT) -> dict:
    """{"pkg/Name": path} for the given ROS 1 types and every type they use."""
    todo = list(msg_types)
    found: dict = {}
    while todo:
        t = todo.pop()
        if t in found:
            continue
        pkg, name = t.split("/")
        path = root / pkg / "msg" / f"{name}.msg"
        if not path.exists():
            raise FileNotFoundError(f"no ROS 1 message definition {path} for {t}")
        found[t] = path
        for line in path.read_text().splitlines():
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            parts = line.split()
            if len(parts) < 2 or "=" in line.split(None, 1)[1].split()[0] or "=" in parts[1]:
                continue  # constant
            ftype = re.sub(r"\[.*\]$", "", parts[0])
            if ftype in _ROS1_BUILTINS:
                continue
            if ftype == "Header":
                ftype = "std_msgs/Header"
            elif "/" not in ftype:
                ftype = f"{pkg}/{ftype}"
            todo.append(ftype)
    return found


def all_ros1_msg_types(root: Path = ROS1_MSG_ROOT) -> list:
    """Every "pkg/Name" with a definition under /usr/share/<pkg>/msg/."""
    return sorted(f"{p.parent.parent.name}/{p.stem}" for p in root.glob("*/msg/*.msg"))


class TypeServer:
    """YARP's ROS type server ``yarpidl_rosmsg --name /typ@/yarpidl``, started
    from a folder holding copies of the .msg files of ``msg_types`` and of
    their dependencies (from Debian's /usr/share/<pkg>/msg)."""

    NAME = "/typ@/yarpidl"

    def __init__(self, yarp_server: YarpServer,
                 msg_types: Optional[Iterable[str]] = ("sensor_msgs/JointState",),
                 timeout: float = 20.0):
        self.yarp_server = yarp_server
        self.msg_types = list(msg_types) if msg_types is not None else all_ros1_msg_types()
        self.timeout = timeout
        self.proc: Optional[Proc] = None

    def start(self) -> "TypeServer":
        require_ros1()
        self._tmp = _TmpDir("ybg-typ-")
        self.msg_dir = self._tmp.path / "msgs"
        for t, path in ros1_msg_files(self.msg_types).items():
            pkg, name = t.split("/")
            dst = self.msg_dir / pkg
            dst.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(path, dst / f"{name}.msg")
        self.proc = Proc([self.yarp_server.install.bin / "yarpidl_rosmsg", "--name", self.NAME],
                         env=self.yarp_server.env, cwd=self.msg_dir, name="yarpidl_rosmsg",
                         log_dir=self._tmp.path, die_with_parent=True).start()
        try:
            _wait_until(lambda: self.yarp_server.exists(self.NAME), self.timeout,
                        f"type server {self.NAME}", self.proc, interval=0.1)
        except BaseException:
            self.stop()
            raise
        return self

    def stop(self) -> None:
        if self.proc is not None:
            self.proc.stop()
        if getattr(self, "_tmp", None) is not None:
            self._tmp.remove()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


class YarpRosStack:
    """Everything YARP's ROS 1 support needs, started in the verified order:
    RosCore, YarpServer(ros=True) and the TypeServer (by default with every
    message type Debian provides). ``.env`` = the YARP server's environment,
    which carries ROS_MASTER_URI / ROS_IP too (use it for YARP and rospy
    processes alike); also ``.port``, ``.uri``, ``.roscore``, ``.yarp_server``,
    ``.type_server``, ``.exists(name)``, ``.yarp(*args)``."""

    def __init__(self, msg_types: Optional[Iterable[str]] = None):
        self.msg_types = msg_types
        self.roscore: Optional[RosCore] = None
        self.yarp_server: Optional[YarpServer] = None
        self.type_server: Optional[TypeServer] = None

    def start(self) -> "YarpRosStack":
        require_ros1()
        try:
            self.roscore = RosCore().start()
            self.yarp_server = YarpServer(ros=True, ros_master_uri=self.roscore.uri).start()
            self.type_server = TypeServer(self.yarp_server, self.msg_types).start()
        except BaseException:
            self.stop()
            raise
        self.env = self.yarp_server.env
        self.port = self.yarp_server.port
        self.uri = self.roscore.uri
        return self

    def exists(self, port_name: str) -> bool:
        return self.yarp_server.exists(port_name)

    def yarp(self, *args, **kw) -> subprocess.CompletedProcess:
        return self.yarp_server.yarp(*args, **kw)

    def wait_port(self, port_name: str, timeout: float = 10.0) -> None:
        self.yarp_server.wait_port(port_name, timeout)

    def procs(self) -> list:
        return [x.proc for x in (self.type_server, self.yarp_server, self.roscore)
                if x is not None and x.proc is not None]

    def stop(self) -> None:
        for x in (self.type_server, self.yarp_server, self.roscore):
            if x is not None:
                x.stop()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


class Ros2Domain:
    """A ROS 2 domain id reserved for the life of the context (1..100, never
    shared with another process of this machine). ``.env`` is a full
    environment for ROS 2 processes (venv PATH, ROS logs in a temp folder)."""

    def __init__(self, domain_id: Optional[int] = None):
        self._fixed = domain_id
        self.domain_id: Optional[int] = domain_id

    def start(self) -> "Ros2Domain":
        require_ros2()
        if self._fixed is None:
            self.domain_id = reserve_domain_id()
        self._tmp = _TmpDir("ybg-ros2-")
        self.tmpdir = self._tmp.path
        self.ros_env = ros2_env(self.domain_id)
        self.env = base_env(self.tmpdir)
        self.env.update(self.ros_env)
        return self

    def stop(self) -> None:
        if self._fixed is None and self.domain_id is not None:
            release_domain_id(self.domain_id)
        if getattr(self, "_tmp", None) is not None:
            self._tmp.remove()

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()


# --------------------------------------------------------------------------
# peers


class Peer(Proc):
    """A peer script of tests/peers/: config as one JSON argument, JSON events
    on stdout (collected in ``.events`` by a thread), JSON commands on stdin."""

    script = ""
    python = str(VENV_PYTHON)
    ready_timeout = 30.0

    def __init__(self, env: dict, config: dict, name: Optional[str] = None):
        self.config = config
        super().__init__([self.python, PEERS / self.script, json.dumps(config)], env=env,
                         cwd=PEERS, name=name or Path(self.script).stem,
                         pipe_stdout=True, pipe_stdin=True)
        self.events: list = []
        self._mark = 0  # index in .events where the current run starts
        self.noise: list = []
        self._cond = threading.Condition()
        self._reader: Optional[threading.Thread] = None

    def start(self) -> "Peer":
        if self.alive:
            return self
        super().start()
        self._mark = len(self.events)
        out = self.popen.stdout
        self._reader = threading.Thread(target=self._pump, args=(out,), daemon=True)
        self._reader.start()
        self.wait_event("ready", timeout=self.ready_timeout, since=self._mark)
        return self

    def _pump(self, out) -> None:
        for raw in iter(out.readline, b""):
            line = raw.decode(errors="replace").strip()
            if not line:
                continue
            try:
                ev = json.loads(line)
            except ValueError:
                ev = None
            with self._cond:
                if isinstance(ev, dict) and "ev" in ev:
                    self.events.append(ev)
                    self._on_event(ev)
                else:
                    self.noise.append(line)
                self._cond.notify_all()
        with self._cond:
            self._cond.notify_all()

    def _on_event(self, ev: dict) -> None:  # called with the lock held
        pass

    def send(self, **cmd) -> None:
        if not self.alive:
            raise RuntimeError(f"{self.name} is not running; log:\n{self.log_text()[-2000:]}")
        self.popen.stdin.write((json.dumps(cmd) + "\n").encode())
        self.popen.stdin.flush()

    def wait(self, pred: Callable[[], Any], timeout: float = 60.0, what: str = "a condition"):
        """Wait until ``pred()`` (called with the event lock held) is true; return it."""
        end = time.monotonic() + timeout
        with self._cond:
            while True:
                v = pred()
                if v:
                    return v
                if self.popen is not None and self.popen.poll() is not None:
                    raise RuntimeError(f"{self.name} exited (status {self.popen.returncode}) "
                                       f"while waiting for {what}; log:\n{self.log_text()[-3000:]}")
                left = end - time.monotonic()
                if left <= 0:
                    recent = "\n".join(json.dumps(e) for e in self.events[-10:])
                    raise TimeoutError(f"{self.name}: timed out after {timeout} s waiting for "
                                       f"{what}; last events:\n{recent}\n"
                                       f"log:\n{self.log_text()[-3000:]}")
                self._cond.wait(min(left, 0.1))

    def wait_event(self, ev: str, pred: Callable[[dict], bool] = lambda e: True,
                   timeout: float = 60.0, since: int = 0) -> dict:
        def find():
            for e in self.events[since:]:
                if e["ev"] == ev and pred(e):
                    return e
            return None
        return self.wait(find, timeout, f"event {ev!r}")

    def last_event(self, ev: str) -> Optional[dict]:
        with self._cond:
            for e in reversed(self.events):
                if e["ev"] == ev:
                    return e
        return None

    def stop(self, timeout: float = 3.0, sig=signal.SIGTERM):
        rc = super().stop(timeout, sig)
        if self._reader is not None:
            self._reader.join(2)
        return rc

    def __exit__(self, *exc):
        self.stop()


@dataclass
class Received:
    """A Bottle received by a YarpReader."""
    t: float                 # receive time, time.time()
    data: list               # the Bottle as Python lists
    types: list              # same shape, the wire type of every leaf
    stamp: Optional[list]    # envelope [seq, time] or None
    text: str                # Bottle.toString()


@dataclass
class Message:
    """A ROS message received by a subscriber peer."""
    t: float                 # receive time, time.time()
    msg: dict                # nested dicts of the fields


class YarpProducer(Peer):
    """Writes Bottles on a YARP port (BufferedPortBottle, strict writes).
    With ``rate`` (Hz) and ``bottles`` it writes them in turn, ``count`` times
    or until stopped; ``envelope=True`` stamps each write (seq, time.time()).
    Restart after ``kill()``/``stop()`` with ``start()``."""

    script = "yarp_producer.py"

    def __init__(self, env: dict, port: str, bottles: Optional[list] = None,
                 rate: Optional[float] = None, count: Optional[int] = None,
                 envelope: bool = False, wait_connected: bool = False,
                 connect_to: Optional[list] = None, carrier: str = ""):
        super().__init__(env, {"port": port, "bottles": bottles, "rate": rate, "count": count,
                               "envelope": envelope, "wait_connected": wait_connected,
                               "connect_to": connect_to, "carrier": carrier},
                         name=f"producer{port.replace('/', '_')}")
        self.port = port

    @property
    def sent(self) -> list:
        """The "sent" events (n, t) of the current run."""
        with self._cond:
            return [e for e in self.events[self._mark:] if e["ev"] == "sent"]

    def write(self, data: list, stamp: Optional[list] = None, timeout: float = 60.0) -> dict:
        """Write one Bottle (``stamp`` = [seq, time] sets the envelope); returns
        the "sent" event once written."""
        n0 = len(self.sent)
        self.send(cmd="write", data=data, stamp=stamp)
        return self.wait(lambda: len(self.sent) > n0 and self.sent[n0], timeout, "write")

    def burst(self, bottles: list, timeout: float = 60.0) -> dict:
        """Write ``bottles`` back to back, as fast as the connections take
        them (strict); returns once the last one is delivered (a reader's
        port holds it: YARP's tcp carrier acknowledges each message)."""
        mark = len(self.events)
        self.send(cmd="burst", bottles=bottles)
        return self.wait_event("burst", timeout=timeout, since=mark)

    def output_count(self, timeout: float = 60.0) -> int:
        mark = len(self.events)
        self.send(cmd="outputs")
        return self.wait_event("outputs", timeout=timeout, since=mark)["n"]

    def wait_outputs(self, n: int = 1, timeout: float = 60.0) -> int:
        """Wait until at least ``n`` connections go out of the port."""
        end = time.monotonic() + timeout
        while True:
            k = self.output_count()
            if k >= n:
                return k
            if time.monotonic() > end:
                raise TimeoutError(f"{self.port}: {k} output connections, wanted {n}")
            time.sleep(0.05)

    def wait_done(self, timeout: float = 30.0) -> dict:
        return self.wait_event("done", timeout=timeout, since=self._mark)


class YarpReader(Peer):
    """Records every Bottle arriving on a YARP port (strict, nothing dropped).
    With ``source`` it keeps ``source -> port`` connected by itself (checks
    every ``poll`` s and connects again), so a late or restarted source is
    picked up."""

    script = "yarp_reader.py"

    def __init__(self, env: dict, port: str, source: Optional[str] = None,
                 carrier: str = "", poll: float = 0.2):
        super().__init__(env, {"port": port, "source": source, "carrier": carrier, "poll": poll},
                         name=f"reader{port.replace('/', '_')}")
        self.port = port
        self.source = source
        self.bottles: list = []
        self.connected = False

    def _on_event(self, ev: dict) -> None:
        if ev["ev"] == "bottle":
            self.bottles.append(Received(ev["t"], ev["data"], ev["types"], ev.get("stamp"),
                                         ev.get("text", "")))
        elif ev["ev"] == "connected":
            self.connected = True
        elif ev["ev"] == "disconnected":
            self.connected = False

    def wait_for(self, n: int, timeout: float = 60.0) -> list:
        """Wait until ``n`` Bottles in all have arrived; returns them all."""
        self.wait(lambda: len(self.bottles) >= n, timeout, f"{n} bottles on {self.port}")
        with self._cond:
            return list(self.bottles)

    def wait_connected(self, timeout: float = 60.0) -> None:
        self.wait(lambda: self.connected, timeout, f"connection {self.source} -> {self.port}")

    def wait_disconnected(self, timeout: float = 60.0) -> None:
        self.wait(lambda: not self.connected, timeout, f"{self.source} to go away")

    def clear(self) -> None:
        with self._cond:
            self.bottles.clear()


class _Subscriber(Peer):
    def __init__(self, env, config, name):
        super().__init__(env, config, name=name)
        self.messages: list = []
        self.publishers = 0

    def _on_event(self, ev: dict) -> None:
        if ev["ev"] == "msg":
            self.messages.append(Message(ev["t"], ev["msg"]))
        elif ev["ev"] in ("publishers", "matched"):
            self.publishers = ev["n"]

    def wait_for(self, n: int, timeout: float = 60.0) -> list:
        """Wait until ``n`` messages in all have arrived; returns them all."""
        self.wait(lambda: len(self.messages) >= n, timeout, f"{n} messages")
        with self._cond:
            return list(self.messages)

    def wait_publishers(self, n: int = 1, timeout: float = 60.0) -> None:
        self.wait(lambda: self.publishers >= n, timeout, f"{n} publishers")

    wait_matched = wait_publishers

    def clear(self) -> None:
        with self._cond:
            self.messages.clear()


class RospySubscriber(_Subscriber):
    """A rospy subscriber (Debian's /usr/bin/python3). ``env`` must carry
    ROS_MASTER_URI / ROS_IP (e.g. ``yarp_ros_server.env``). Messages are
    nested dicts; times are {"secs", "nsecs"}."""

    script = "rospy_subscriber.py"
    python = ROS1_PYTHON

    def __init__(self, env: dict, topic: str, msg_type: str = "sensor_msgs/JointState",
                 node: str = "ybg_test_listener"):
        super().__init__(env, {"topic": topic, "type": msg_type, "node": node},
                         name=f"rospy_sub{topic.replace('/', '_')}")


class Ros2Subscriber(_Subscriber):
    """An rclpy subscriber (venv python). ``env`` must carry the ROS 2
    variables (e.g. ``ros2_domain.env``). Times are {"sec", "nanosec"}."""

    script = "rclpy_peer.py"

    def __init__(self, env: dict, topic: str, msg_type: str = "sensor_msgs/msg/JointState",
                 node: str = "ybg_test_sub", depth: int = 100):
        super().__init__(env, {"mode": "sub", "topic": topic, "type": msg_type, "node": node,
                               "depth": depth},
                         name=f"rclpy_sub{topic.replace('/', '_')}")


class Ros2Publisher(Peer):
    """An rclpy publisher (venv python). Publishes on command (``publish``)
    or, with ``rate`` and ``messages``, in turn at that rate (``count`` times);
    ``stamp_now`` sets header.stamp to the current time."""

    script = "rclpy_peer.py"

    def __init__(self, env: dict, topic: str, msg_type: str = "sensor_msgs/msg/JointState",
                 messages: Optional[list] = None, rate: Optional[float] = None,
                 count: Optional[int] = None, wait_matched: bool = False,
                 stamp_now: bool = False, node: str = "ybg_test_pub", depth: int = 100):
        super().__init__(env, {"mode": "pub", "topic": topic, "type": msg_type, "node": node,
                               "depth": depth, "messages": messages, "rate": rate,
                               "count": count, "wait_matched": wait_matched,
                               "stamp_now": stamp_now},
                         name=f"rclpy_pub{topic.replace('/', '_')}")
        self.matched = 0

    def _on_event(self, ev: dict) -> None:
        if ev["ev"] == "matched":
            self.matched = ev["n"]

    @property
    def sent(self) -> list:
        with self._cond:
            return [e for e in self.events[self._mark:] if e["ev"] == "sent"]

    def publish(self, msg: dict, timeout: float = 60.0) -> dict:
        n0 = len(self.sent)
        self.send(cmd="publish", msg=msg)
        return self.wait(lambda: len(self.sent) > n0 and self.sent[n0], timeout, "publish")

    def wait_matched(self, n: int = 1, timeout: float = 60.0) -> None:
        self.wait(lambda: self.matched >= n, timeout, f"{n} matched subscribers")
