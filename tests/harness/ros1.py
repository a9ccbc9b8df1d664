"""ROS 1 for the tests: Debian's ``roscore``, YARP's ROS support (a
``yarpserver --ros`` and its type server, in YARP before 3.10) and rospy
peers (Debian's /usr/bin/python3).

    require_ros1()      pytest.fail with how to install
    RosCore()           Debian `roscore -p <free port>`: .port, .uri, .ros_env, .env
    TypeServer(yarp_server, msg_types=["sensor_msgs/JointState"])
                        `yarpidl_rosmsg --name /typ@/yarpidl` run from a folder
                        holding the .msg files (and their dependencies);
                        msg_types=None: every type in /usr/share/*/msg
    YarpRosStack(msg_types=None)   RosCore + YarpServer(ros=True) + TypeServer,
                        in that order: .env (YARP + ROS_MASTER_URI/ROS_IP), .port,
                        .uri, .roscore, .yarp_server, .type_server, .exists(name)
    RospySubscriber(env, topic, msg_type="sensor_msgs/JointState")
    rospy_publisher(env, topic, msg_type, fields, rate=20) -> Proc
    ros_master_nodes(stack, topic) -> (publishers, subscribers)
    ros1_type_known(msg_type) -> bool   Debian has its definition
"""
from __future__ import annotations

import json
import re
import shutil
import signal
import socket
import subprocess
import xmlrpc.client
from pathlib import Path
from typing import Iterable, Optional

from harness.env import LOCALHOST, SETUP_HINT, active_yarp, base_env, fail, free_port, python_imports
from harness.procs import Proc, Subscriber, TmpDir, wait_until
from harness.yarp import YarpServer, require_yarp

#: the Python of Debian's ROS 1 (rospy)
ROS1_PYTHON = "/usr/bin/python3"


def require_ros1() -> None:
    """Fail the test unless Debian's ROS 1 (roscore, rospy, message packages) is there."""
    require_yarp()
    missing = [p for p in ("/usr/bin/roscore", "/usr/share/sensor_msgs/msg/JointState.msg",
                           "/usr/share/std_msgs/msg/Header.msg", ROS1_PYTHON)
               if not Path(p).exists()]
    if missing:
        fail(f"ROS 1 is not installed: missing {', '.join(missing)} (Debian packages "
             f"ros-core python3-rospy python3-sensor-msgs ros-sensor-msgs ros-std-msgs). "
             f"{SETUP_HINT}")
    err = python_imports(ROS1_PYTHON, "rospy, roslib.message, sensor_msgs.msg")
    if err:
        fail(f"rospy does not import in {ROS1_PYTHON}: {err}. {SETUP_HINT}")
    install = active_yarp()
    if not install.has_ros1:
        fail(f"YARP {install.version} has no ROS 1 support (removed in YARP 3.10): "
             f"a ROS 1 test runs on YARP 3.5 only")
    if not (install.bin / "yarpidl_rosmsg").exists():
        fail(f"yarpidl_rosmsg is missing from {install.bin}. {SETUP_HINT}")


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
        self._tmp = TmpDir("ybg-ros-", self._tmp_arg)
        self.tmpdir = self._tmp.path
        if self.port is None:
            self.port = free_port()
        self.ros_env = {"ROS_MASTER_URI": self.uri, "ROS_IP": LOCALHOST}
        self.env = base_env(self.tmpdir)
        self.env.update(self.ros_env)
        self.proc = Proc(["/usr/bin/roscore", "-p", self.port], env=self.env, name="roscore",
                         log_dir=self.tmpdir, die_with_parent=True).start()
        try:
            wait_until(self._master_ok, self.timeout, f"roscore on port {self.port}", self.proc,
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
        self._tmp = TmpDir("ybg-typ-")
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
            wait_until(lambda: self.yarp_server.exists(self.NAME), self.timeout,
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


class RospySubscriber(Subscriber):
    """A rospy subscriber (Debian's /usr/bin/python3). ``env`` must carry
    ROS_MASTER_URI / ROS_IP (e.g. ``yarp_ros_server.env``). Messages are
    nested dicts; times are {"secs", "nsecs"}."""

    script = "rospy_subscriber.py"
    python = ROS1_PYTHON

    def __init__(self, env: dict, topic: str, msg_type: str = "sensor_msgs/JointState",
                 node: str = "ybg_test_listener"):
        super().__init__(env, {"topic": topic, "type": msg_type, "node": node},
                         name=f"rospy_sub{topic.replace('/', '_')}")


def ros1_type_known(msg_type: Optional[str]) -> bool:
    """Has Debian a definition of this ROS 1 type (a rospy subscriber can read it)?"""
    if not msg_type or "/" not in msg_type:
        return False
    pkg, name = msg_type.split("/")
    return (ROS1_MSG_ROOT / pkg / "msg" / f"{name}.msg").exists()


def ros_master_nodes(stack, topic: str) -> tuple[list, list]:
    """(publishers, subscribers) of ``topic`` that the ROS master knows."""
    code, _, (pubs, subs, _) = xmlrpc.client.ServerProxy(stack.uri).getSystemState("/ybg_test")
    assert code == 1
    find = lambda rows: next((nodes for name, nodes in rows if name == topic), [])  # noqa: E731
    return find(pubs), find(subs)


ROSPY_PUBLISHER = r"""
import json, sys, time
import rospy, roslib.message
cfg = json.loads(sys.argv[1])
cls = roslib.message.get_message_class(cfg["type"])
rospy.init_node("ybg_test_pub", anonymous=True, disable_signals=True)
pub = rospy.Publisher(cfg["topic"], cls, queue_size=10)
if cfg["type"] == "geometry_msgs/PointStamped":
    from std_msgs.msg import Header
    from geometry_msgs.msg import Point
    msg = cls(header=Header(frame_id=cfg["fields"]["header"]["frame_id"]),
              point=Point(**cfg["fields"]["point"]))
else:
    msg = cls(**cfg["fields"])
while True:
    pub.publish(msg)
    time.sleep(1.0 / cfg["rate"])
"""


def rospy_publisher(env: dict, topic: str, msg_type: str, fields: dict, rate: float = 20) -> Proc:
    """A rospy publisher of one message, ``rate`` times a second (not started)."""
    return Proc([ROS1_PYTHON, "-c", ROSPY_PUBLISHER,
                 json.dumps({"topic": topic, "type": msg_type, "fields": fields, "rate": rate})],
                env=env, name=f"rospy_pub{topic.replace('/', '_')}")
