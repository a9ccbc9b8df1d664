"""ROS 2 for the tests: a domain id of a test's own (never shared with
another process of this machine), localhost-only discovery, and rclpy peers
(tests/peers/rclpy_peer.py, ros2_qos_subscriber.py) run by the venv's Python.

    require_ros2()      pytest.fail with how to install
    ros2_env(domain_id=None) -> dict    ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST,
                        ROS_DOMAIN_ID (default: one reserved for this test run)
    Ros2Domain()        context manager reserving its own domain id: .domain_id, .env
    ros2_environment(env, domain) -> dict   ``env`` in that domain
    yarp_and_ros2(ros2_domain)   with: a YARP 3.5 name server and the domain, one ``.env``
    Ros2Subscriber(env, topic, msg_type="sensor_msgs/msg/JointState")
        .messages: list of Message(t, msg as nested dicts), .wait_for(n),
        .wait_publishers(n) / .wait_matched(n)
    QosSubscriber(env, topic, msg_type, qos=None)   with a chosen QoS; also
        .publisher_qos (what the matched publishers offer), .wait_after(t)
    subscriber_for(env, program)   a QosSubscriber of a program's ROS 2 output
    Ros2Publisher(env, topic, msg_type=..., messages=None, rate=None, count=None,
                  wait_matched=False, stamp_now=False)
        .publish(dict), .wait_matched(n), .sent
    statuses(msg)       the statuses of a diagnostic_msgs/DiagnosticArray
    wait_incompatible(peer, policy)   rclpy's incompatible-QoS warning in a peer's log
"""
from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
import threading
import time
from pathlib import Path
from types import SimpleNamespace
from typing import Optional

from harness.env import SETUP_HINT, VENV_PYTHON, base_env, fail, python_imports, yarp_install
from harness.procs import Peer, Subscriber, TmpDir
from harness.yarp import YarpServer

def require_ros2() -> None:
    """Fail the test unless the ROS 2 rclpy wheels are installed in the venv."""
    err = python_imports(str(VENV_PYTHON),
                         "rclpy, sensor_msgs.msg, std_msgs.msg, geometry_msgs.msg")
    if err:
        fail(f"ROS 2 (rclpy wheels) not usable in {VENV_PYTHON}: {err}. {SETUP_HINT}")


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
        self._tmp = TmpDir("ybg-ros2-")
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


def ros2_environment(env: dict, domain) -> dict:
    """``env`` with the ROS 2 domain's variables and its ROS logs' folder."""
    return {**env, **domain.ros_env, "ROS_HOME": domain.env["ROS_HOME"], "ROS_LOG_DIR": domain.env["ROS_LOG_DIR"]}


@contextlib.contextmanager
def yarp_and_ros2(ros2_domain):
    """A YARP name server (PyPI's YARP 3.5: the node's ROS 2 side does not
    depend on the YARP version, which test_backend_ros2 runs on every one)
    and a ROS 2 domain, in one environment (``.env``)."""
    with YarpServer(install=yarp_install("3.5")) as server:
        yield SimpleNamespace(env=ros2_environment(server.env, ros2_domain), yarp=server, ros2=ros2_domain)


# --------------------------------------------------------------------------
# peers


class Ros2Subscriber(Subscriber):
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


class QosSubscriber(Peer):
    """An rclpy subscriber with a chosen QoS (tests/peers/ros2_qos_subscriber.py)."""

    script = "ros2_qos_subscriber.py"

    def __init__(self, env, topic, msg_type, qos=None):
        """``qos``: a ybg.compiler.ir.QoS (default: the default QoS)."""
        from ybg.compiler.ir import QoS

        qos = qos or QoS()
        super().__init__(env, {"topic": topic, "type": msg_type, "reliability": qos.reliability,
                               "durability": qos.durability, "depth": 100},
                         name=f"ros2_sub{topic.replace('/', '_')}")
        self.messages: list = []
        self.publishers = 0
        self.publisher_qos: list = []

    def _on_event(self, ev):
        if ev["ev"] == "msg":
            self.messages.append(SimpleNamespace(t=ev["t"], msg=ev["msg"]))
        elif ev["ev"] == "matched":
            self.publishers = ev["n"]
            self.publisher_qos = ev.get("qos", [])

    def wait_for(self, n, timeout=60.0):
        self.wait(lambda: len(self.messages) >= n, timeout, f"{n} messages")
        with self._cond:
            return list(self.messages)

    def wait_after(self, t, timeout=60.0, pred=lambda m: True):
        """The first message received after time ``t`` that satisfies ``pred``."""
        def find():
            for m in self.messages:
                if m.t > t and pred(m):
                    return m
            return None
        return self.wait(find, timeout, f"a message after {t}")

    def wait_publishers(self, n=1, timeout=60.0):
        self.wait(lambda: self.publishers >= n, timeout, f"{n} publishers")

    def clear(self):
        with self._cond:
            self.messages.clear()


def subscriber_for(env, program) -> QosSubscriber:
    """A subscriber of ``program``'s ROS 2 output, with the QoS it offers."""
    out = program.output
    pkg, name = out.msg_type.split("/")
    return QosSubscriber(env, out.name, f"{pkg}/msg/{name}", out.qos)


def ros2_type(msg_type: str) -> str:
    """"pkg/Name" as ROS 2 names it: "pkg/msg/Name"."""
    pkg, name = msg_type.split("/")
    return f"{pkg}/msg/{name}"


def wait_matched(node, sub, program):
    """Both sides of the topic matched: a message published now is delivered."""
    sub.wait_publishers(1)
    node.wait_log(f"{program.output.name}: 1 subscriber\n")


def statuses(msg) -> dict:
    """{name: (level, message, {key: value}, hardware_id)} of one DiagnosticArray."""
    out = {}
    for s in msg["status"]:
        level = s["level"][0] if isinstance(s["level"], list) else s["level"]
        out[s["name"]] = (level, s["message"], {kv["key"]: kv["value"] for kv in s["values"]},
                          s["hardware_id"])
    return out


def wait_incompatible(peer, policy, found="publisher discovered", verb="offering", timeout=60.0):
    """rclpy's warning in a peer's log: the node's publisher (subscription)
    was discovered and refused for ``policy``."""
    end = time.monotonic() + timeout
    text = f"New {found} on topic"
    tail = f"{verb} incompatible QoS. No messages will be "
    last = f"Last incompatible policy: {policy}"
    while not all(t in peer.log_text() for t in (text, tail, last)):
        assert time.monotonic() < end, f"no incompatible {policy} in:\n{peer.log_text()[-2000:]}"
        time.sleep(0.05)
