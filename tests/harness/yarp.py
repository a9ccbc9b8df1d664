"""YARP for the tests: the real ``yarpserver`` on 127.0.0.1 and a free port,
with its configuration in a temporary folder, and the peers that write and
read YARP ports (tests/peers/yarp_producer.py, yarp_reader.py).

    require_yarp(install=None)   pytest.fail with how to install
    yarp_env(tmpdir, port, ip="127.0.0.1") -> dict   YARP_CONFIG/DATA/CACHE_HOME=tmpdir,
                                        YARP_IP=ip, writes <tmpdir>/yarp.conf "<ip> <port> yarp"
    YarpServer(ros=False, ros_master_uri=None, install=None)
        .port, .install, .env (full environment for child processes), .tmpdir,
        .yarp(*args) -> CompletedProcess of the real `yarp` CLI,
        .exists(port_name) -> bool, .wait_port(name, timeout)
    YarpProducer(env, port, bottles=None, rate=None, count=None, envelope=False,
                 wait_connected=False, connect_to=None)
        .write(data, stamp=None), .output_count(), .wait_outputs(n), .sent,
        .kill(), .stop(), .start() (restart after kill/stop)
    YarpReader(env, port, source=None, carrier="", poll=0.2)
        .bottles: list of Received(t, data, types, stamp, text),
        .wait_for(n, timeout) -> list, .wait_connected(), .clear()
        With a source it reconnects source -> port by itself (polling connect).
    rpc(server, port, *commands) -> what the real `yarp rpc` prints
    yarp_ports(server), registered(server, port)   what the name server knows

Bottle values in Python (see tests/peers/bottle_codec.py): int -> int32 (int64 if
large), float -> float64, str -> string, list -> nested list; force a type with
{"int64": n}, {"float32": x}, {"vocab": "abcd"}. A received Bottle gives ``data``
(plain lists) and ``types`` (same shape, wire type of every leaf: "int32",
"int64", "float64", "string", "vocab", ...).

Example::

    from harness.yarp import YarpProducer, YarpReader

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

import os
import re
import subprocess
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

from harness.env import (LOCALHOST, VENV_PYTHON, YarpInstall, active_yarp, base_env, fail, free_port,
                         python_imports, release_port)
from harness.procs import Peer, Proc, TmpDir, wait_until

def require_yarp(install: Optional[YarpInstall] = None) -> None:
    """Fail the test (never skip) unless YARP (the active install: PyPI's 3.5
    unless the ``yarp`` fixture chose another) is installed."""
    install = install or active_yarp()
    missing = [str(VENV_PYTHON)] if not VENV_PYTHON.exists() else []
    missing += install.missing()
    if missing:
        fail(f"YARP {install.version} is not installed: missing {', '.join(missing)}. "
             f"{install.build_hint()}")
    err = python_imports(str(VENV_PYTHON), "yarp", str(install.python_path or ""))
    if err:
        fail(f"`import yarp` of YARP {install.version} fails in {VENV_PYTHON}: {err}. "
             f"{install.build_hint()}")


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
        self._tmp = TmpDir("ybg-yarp-", self._tmp_arg)
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
                wait_until(lambda: self.exists("/root"), self.timeout,
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
        wait_until(lambda: self.exists(port_name), timeout, f"port {port_name}")

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


def rpc(server, port: str, *commands: str) -> str:
    """What the real `yarp rpc PORT` prints for ``commands`` typed in it.
    `yarp rpc` that could not connect ("Cannot make connection": on a busy
    machine its connection can time out) sent nothing: it is run again, up
    to 5 times; what the module answers is never retried."""
    for _ in range(5):
        r = subprocess.run([str(server.install.bin / "yarp"), "rpc", port],
                           input="".join(c + "\n" for c in commands),
                           env=server.env, capture_output=True, text=True, timeout=30)
        text = r.stdout + r.stderr
        if "Cannot make connection" not in text:
            return text
        time.sleep(0.5)
    return text


def yarp_ports(server) -> set[str]:
    """The ports registered with the name server."""
    out = server.yarp("name", "list").stdout
    return set(re.findall(r"registration name (\S+)", out))


def registered(server, port: str) -> bool:
    r = server.yarp("name", "query", port)
    return r.returncode == 0 and "registration name" in r.stdout and port in r.stdout


# --------------------------------------------------------------------------
# peers


@dataclass
class Received:
    """A Bottle received by a YarpReader."""
    t: float                 # receive time, time.time()
    data: list               # the Bottle as Python lists
    types: list              # same shape, the wire type of every leaf
    stamp: Optional[list]    # envelope [seq, time] or None
    text: str                # Bottle.toString()


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
    picked up. With ``head``, it keeps the first ``head`` values of each
    Bottle and not its text (large Bottles counted, not read)."""

    script = "yarp_reader.py"

    def __init__(self, env: dict, port: str, source: Optional[str] = None,
                 carrier: str = "", poll: float = 0.2, head: Optional[int] = None):
        super().__init__(env, {"port": port, "source": source, "carrier": carrier, "poll": poll, "head": head},
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
