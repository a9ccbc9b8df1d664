"""A robot's network on one machine: four hosts made of Linux network
namespaces, for the multi-host tests (tests/test_network.py) and the fault
figures (bench/network_faults.py). See docs/network.md.

    hub namespace:  bridge br0, one port per host (p0..p3)
    host "names":      10.213.0.1   the YARP name server
    host "producers":  10.213.0.2   the robot's ports (YARP producers)
    host "module":     10.213.0.3   the generated module
    host "consumers":  10.213.0.4   a YARP reader, an rclpy subscriber

Each host is a namespace of its own (loopback up, one veth to the hub, a
route for multicast so that DDS discovery crosses the bridge). The addresses
exist only inside these namespaces; every namespace is named after this
process (``ybg<pid>n<k>-<host>``, a fresh rig per test), so two runs at
once never share one, and all are deleted by ``Rig.stop()`` (the fixtures'
finalizer) or, after a crash, by the ``atexit`` hook. Cutting a host off (``Rig.cut``) sets its port on
the bridge down, as a pulled cable: the host keeps its address and routes,
its packets go nowhere until ``Rig.restore``.

Processes run inside a host with ``ip netns exec`` (``Rig.place`` prefixes
any ``harness.procs.Proc`` or peer before it starts; the pid stays that of the
command, so stopping and killing work as on loopback).

Needs root (``ip netns add``); otherwise ``RigUnavailable`` says so and how
to run the tests.
"""
from __future__ import annotations

import atexit
import os
import shutil
import subprocess
import threading
import time
from pathlib import Path
from typing import Optional

from harness import procs
from harness.env import YarpInstall, base_env
from harness.procs import Proc, wait_until
from harness.ros2 import ros2_env
from harness.yarp import yarp_env

SUBNET = "10.213.0"
HOSTS = ("names", "producers", "module", "consumers")
#: the name server's port inside its host (nothing else listens there)
NAME_SERVER_PORT = 10000

_LIVE: "set[Rig]" = set()
_MADE = 0
_LIVE_LOCK = threading.Lock()


class RigUnavailable(RuntimeError):
    """Network namespaces cannot be made here (not root, no ``ip``)."""


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess:
    r = subprocess.run(["ip", *args], capture_output=True, text=True, timeout=20)
    if check and r.returncode != 0:
        raise RuntimeError(f"ip {' '.join(args)}: {r.stderr.strip()}")
    return r


def why_unavailable() -> Optional[str]:
    """Why the rig cannot be made on this machine, or None."""
    how = ("run the network tests as root on Linux (CI does), e.g. "
           "`sudo -E .venv/bin/python -m pytest -q tests/test_network.py`")
    if shutil.which("ip") is None:
        return f"the multi-host tests need the `ip` command (iproute2): install it and {how}"
    if os.geteuid() != 0:
        return f"the multi-host tests make Linux network namespaces, which needs root: {how}"
    return None


class Rig:
    """Four hosts joined by a bridge (context manager: made on enter,
    removed on exit). ``ip(host)``, ``env(host)`` (a YARP environment that
    registers on that host's address), ``place(host, proc)``, ``run(host,
    argv)``, ``cut(host)`` / ``restore(host)``, ``name_server`` once
    ``start_name_server()`` ran."""

    def __init__(self, install: YarpInstall, tag: Optional[str] = None):
        global _MADE
        _MADE += 1
        self.install = install
        self.tag = tag or f"ybg{os.getpid()}n{_MADE}"
        self.hub = f"{self.tag}-hub"
        self.made: list[str] = []
        self.name_server: Optional[Proc] = None
        self.tmpdir = Path(procs.tmp_root()) / f"rig-{self.tag}"

    # -- the network
    def ns(self, host: str) -> str:
        return f"{self.tag}-{host}"

    def ip(self, host: str) -> str:
        return f"{SUBNET}.{HOSTS.index(host) + 1}"

    def _port(self, host: str) -> str:
        return f"p{HOSTS.index(host)}"

    def start(self) -> "Rig":
        why = why_unavailable()
        if why:
            raise RigUnavailable(why)
        with _LIVE_LOCK:
            _LIVE.add(self)
        try:
            self._add_ns(self.hub)
            _ip("-n", self.hub, "link", "add", "br0", "type", "bridge", "mcast_snooping", "0")
            _ip("-n", self.hub, "link", "set", "br0", "up")
            for host in HOSTS:
                ns, dev = self.ns(host), "eth0"
                self._add_ns(ns)
                _ip("link", "add", dev, "netns", ns, "type", "veth",
                    "peer", "name", self._port(host), "netns", self.hub)
                _ip("-n", ns, "link", "set", "lo", "up")
                _ip("-n", ns, "addr", "add", f"{self.ip(host)}/24", "dev", dev)
                _ip("-n", ns, "link", "set", dev, "up", "multicast", "on")
                _ip("-n", ns, "route", "add", "224.0.0.0/4", "dev", dev)
                _ip("-n", self.hub, "link", "set", self._port(host), "master", "br0", "up")
        except RuntimeError as e:
            self.stop()
            if "Operation not permitted" in str(e):
                raise RigUnavailable(f"{e}: {why_unavailable() or 'needs root'}") from e
            raise
        self.tmpdir.mkdir(parents=True, exist_ok=True)
        return self

    def _add_ns(self, name: str) -> None:
        _ip("netns", "add", name)
        self.made.append(name)

    def stop(self) -> None:
        """Stop the name server and delete every namespace of the rig."""
        if self.name_server is not None:
            self.name_server.stop()
        for name in reversed(self.made):
            _ip("netns", "del", name, check=False)
        self.made.clear()
        with _LIVE_LOCK:
            _LIVE.discard(self)

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()

    def cut(self, host: str) -> None:
        """The host's cable pulled: its port on the bridge down."""
        _ip("-n", self.hub, "link", "set", self._port(host), "down")

    def restore(self, host: str) -> None:
        _ip("-n", self.hub, "link", "set", self._port(host), "up")

    # -- processes
    def wrap(self, host: str, argv) -> list[str]:
        return ["ip", "netns", "exec", self.ns(host), *map(str, argv)]

    def place(self, host: str, proc: Proc) -> Proc:
        """``proc`` (not started yet) to run inside ``host``."""
        assert not proc.alive, f"{proc.name} already runs"
        proc.argv = self.wrap(host, proc.argv)
        return proc

    def run(self, host: str, argv, env: Optional[dict] = None,
            timeout: float = 20.0) -> subprocess.CompletedProcess:
        return subprocess.run(self.wrap(host, argv), env=env, capture_output=True, text=True,
                              timeout=timeout)

    # -- YARP
    def env(self, host: str) -> dict:
        """The environment of a YARP (or ROS 2) process on ``host``: the
        rig's name server in yarp.conf, ports registered with the host's
        address (YARP_IP), DDS discovery across the subnet."""
        env = base_env(self.tmpdir, self.install)
        env.update(yarp_env(self.tmpdir / "yarp", NAME_SERVER_PORT,
                            ip=self.ip("names")))
        env["YARP_IP"] = self.ip(host)
        env.update(ros2_env(1))
        env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "SUBNET"
        # over the network only: Fast DDS would otherwise carry data through
        # shared memory (/dev/shm is the same for every namespace)
        env["FASTDDS_BUILTIN_TRANSPORTS"] = "UDPv4"
        return env

    def yarp(self, *args, host: str = "names", timeout: float = 20.0) -> subprocess.CompletedProcess:
        """The real ``yarp`` command run on ``host``."""
        return self.run(host, [self.install.bin / "yarp", *args], env=self.env(host), timeout=timeout)

    def rpc(self, port: str, *commands: str, host: str = "names", timeout: float = 30.0) -> str:
        """What `yarp rpc PORT`, run on ``host``, prints for ``commands``."""
        r = subprocess.run(self.wrap(host, [self.install.bin / "yarp", "rpc", port]),
                           input="".join(c + "\n" for c in commands), env=self.env(host), capture_output=True,
                           text=True, timeout=timeout)
        return r.stdout + r.stderr

    def exists(self, port: str, host: str = "names") -> bool:
        try:
            return self.yarp("exists", port, host=host, timeout=10).returncode == 0
        except subprocess.TimeoutExpired:
            return False

    def registered(self, port: str) -> Optional[str]:
        """The address ``port`` is registered with (None: not registered)."""
        out = self.yarp("name", "query", port).stdout
        if "registration name" not in out or port not in out:
            return None
        words = out.split()
        return words[words.index("ip") + 1] if "ip" in words else ""

    def contact(self, port: str) -> Optional[tuple[str, int]]:
        """(address, port number) the name server gives ``port`` (None: not registered)."""
        words = self.yarp("name", "query", port).stdout.split()
        if "registration" not in words or "ip" not in words or "port" not in words:
            return None
        return words[words.index("ip") + 1], int(words[words.index("port") + 1])

    def wait_port(self, port: str, timeout: float = 30.0, host: str = "names") -> None:
        wait_until(lambda: self.exists(port, host), timeout, f"port {port} on the rig")

    def start_name_server(self, keep: bool = False) -> Proc:
        """``yarpserver`` on the names host (started again if it was stopped).
        ``keep``: its registrations kept in a database on disk (``--portdb``,
        ``--subdb``), so that started again it still knows every port; its
        address then comes from yarp.conf (``--ip`` or ``--socket`` would
        reset the database)."""
        if self.name_server is None:
            argv = [self.install.bin / "yarpserver", "--ip", self.ip("names"),
                    "--socket", NAME_SERVER_PORT, "--read"]
            if keep:
                argv = [self.install.bin / "yarpserver", "--read",
                        "--portdb", self.tmpdir / "ports.db", "--subdb", self.tmpdir / "subs.db"]
            self.name_server = self.place("names", Proc(
                argv, env=self.env("names"), name="yarpserver", log_dir=self.tmpdir,
                die_with_parent=True))
        # started again at once after a kill, it can find its port still
        # held (the killed process not yet reaped on a busy machine, or its
        # connections in TIME_WAIT): it says so and exits 1; tried again
        # while that lasts (10 s at most)
        end = time.monotonic() + 10.0
        while True:
            self.name_server.start()
            try:
                wait_until(lambda: self.exists("/root"), 30, "the rig's yarpserver", self.name_server)
                return self.name_server
            except RuntimeError:
                if time.monotonic() > end or "Aborting" not in self.name_server.log_text()[-300:]:
                    raise
                time.sleep(0.25)


def stop_all() -> None:
    """Remove every rig of this process (the atexit hook), once the
    processes the tests started are stopped."""
    procs.stop_all()
    with _LIVE_LOCK:
        rigs = list(_LIVE)
    for rig in rigs:
        try:
            rig.stop()
        except Exception:
            pass


atexit.register(stop_all)


def rss_kb(pid: int) -> int:
    """The resident memory of process ``pid``, in kB (0 once it is gone)."""
    try:
        for line in Path(f"/proc/{pid}/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return int(line.split()[1])
    except OSError:
        pass
    return 0

