"""The test harness itself, against real middleware: YARP 3.5, ROS 1, ROS 2."""
import dataclasses
import math
import os
import time
from pathlib import Path

import pytest

from harness import env as harness_env, ros2 as harness_ros2
from harness.env import DEFAULT_YARP, yarp_install
from harness.procs import Proc, live_processes
from harness.ros1 import RospySubscriber, YarpRosStack, ros1_msg_files
from harness.ros2 import Ros2Domain, Ros2Publisher, Ros2Subscriber, require_ros2, ros2_env
from harness.yarp import YarpProducer, YarpReader, YarpServer, require_yarp, yarp_env

pytestmark = pytest.mark.slow


def test_yarp_bottle_roundtrip(yarp_server):
    env = yarp_server.env
    sent = [
        [1, 2.5, "abc", [3, 4.0, "x"], []],
        [-7, {"int64": 2**40}, {"float32": 0.5}, float("nan"), ""],
        [0, [[1, 2], [3]], "with space", 1e-300],
    ]
    with YarpReader(env, "/test/in", source="/test/out") as reader, \
            YarpProducer(env, "/test/out") as producer:
        reader.wait_connected()
        producer.wait_outputs(1)
        for b in sent:
            producer.write(b)
        got = reader.wait_for(3)
    assert len(got) == 3
    assert got[0].data == [1, 2.5, "abc", [3, 4.0, "x"], []]
    assert got[0].types == ["int32", "float64", "string", ["int32", "float64", "string"], []]
    assert got[1].data[:3] == [-7, 2**40, 0.5] and math.isnan(got[1].data[3])
    assert got[1].data[4] == ""
    assert got[1].types == ["int32", "int64", "float32", "float64", "string"]
    assert got[2].data == [0, [[1, 2], [3]], "with space", 1e-300]
    assert all(g.stamp is None for g in got)
    assert got[0].t <= got[1].t <= got[2].t


def test_yarp_envelope_and_rate(yarp_server):
    env = yarp_server.env
    with YarpReader(env, "/rate/in", source="/rate/out") as reader, \
            YarpProducer(env, "/rate/out", bottles=[[1.0], [2.0]], rate=50, count=20,
                         envelope=True, wait_connected=True) as producer:
        producer.wait_done(timeout=10)
        got = reader.wait_for(20)
    assert [g.data for g in got] == [[1.0], [2.0]] * 10
    assert [g.stamp[0] for g in got] == list(range(20))
    # 19 periods of 20 ms by the producer's clock (its envelope times, which
    # no reader's lateness moves): a write waits for its time, so fewer only
    # by how late the first one was; more only as long as the producer was
    # kept from the CPU (2 s: a hang)
    span = got[-1].stamp[1] - got[0].stamp[1]
    assert 0.25 < span < 2.0, span
    # explicit stamp
    with YarpReader(env, "/st/in", source="/st/out") as reader, \
            YarpProducer(env, "/st/out") as producer:
        reader.wait_connected()
        producer.wait_outputs(1)
        producer.write([5], stamp=[42, 1234.5])
        (g,) = reader.wait_for(1)
    assert g.stamp == [42, 1234.5]


def test_yarp_name_server_is_loopback_and_isolated(yarp_server, tmp_path):
    with YarpProducer(yarp_server.env, "/iso/out"):
        listing = yarp_server.name_list()
    assert "/iso/out" in listing and "/root" in listing
    for line in listing.splitlines():
        if line.startswith("registration name /") and " ip " in line:
            assert " ip 127.0.0.1 " in line, line
    assert (Path(yarp_server.env["YARP_CONFIG_HOME"]) / "yarp.conf").read_text() \
        == f"127.0.0.1 {yarp_server.port} yarp\n"
    env = yarp_env(tmp_path, 12345)
    assert env["YARP_IP"] == "127.0.0.1"
    assert (tmp_path / "yarp.conf").read_text() == "127.0.0.1 12345 yarp\n"


def test_tcpros_carrier_listed(yarp, yarp_server):
    """YARP's ROS 1 carriers are there in 3.5 (the setup's build settings
    register them) and gone from 3.10 on (the separate yarp-ros plugins)."""
    out = yarp_server.yarp("connect", "--list-carriers", check=True).stdout.split()
    assert "tcp" in out
    assert ("tcpros" in out and "xmlrpc" in out) == yarp.has_ros1, out


def test_reader_reconnects_to_restarted_producer(yarp_server):
    env = yarp_server.env
    with YarpReader(env, "/rc/in", source="/rc/out", poll=0.1) as reader:
        producer = YarpProducer(env, "/rc/out")
        with producer:
            reader.wait_connected()
            producer.wait_outputs(1)
            producer.write(["first"])
            reader.wait_for(1)
            producer.kill()
            assert not producer.alive and not producer.group_alive()
            reader.wait_disconnected()
            producer.start()  # same port name, new process
            assert producer.starts == 2
            reader.wait_connected(timeout=15)
            producer.wait_outputs(1)
            producer.write(["second"])
            got = reader.wait_for(2)
    assert [g.data for g in got] == [["first"], ["second"]]


def test_rospy_receives_typed_joint_state_from_python_yarp_port(yarp_ros_server):
    stack = yarp_ros_server
    env = stack.env
    with RospySubscriber(env, "/joint_states") as sub, \
            YarpProducer(env, "/joint_states@/yarp/testnode") as producer:
        # header (seq (sec nsec) frame_id), name[], position[], velocity[], effort[]
        bottle = [[7, [12, 345], "base"], ["j1", "j2"], [0.5, -1.25], [], []]
        sub.wait_publishers(1, timeout=20)
        deadline = time.monotonic() + 20
        while not sub.messages and time.monotonic() < deadline:
            producer.write(bottle)
            time.sleep(0.1)
        (m, *_) = sub.wait_for(1, timeout=5)
    msg = m.msg
    assert msg["name"] == ["j1", "j2"]
    assert msg["position"] == [0.5, -1.25]
    assert msg["velocity"] == [] and msg["effort"] == []
    assert msg["header"]["frame_id"] == "base"
    assert msg["header"]["stamp"] == {"secs": 12, "nsecs": 345}


def test_rclpy_publisher_to_subscriber(ros2_domain):
    env = ros2_domain.env
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert 1 <= int(env["ROS_DOMAIN_ID"]) <= 100
    js = {"header": {"stamp": {"sec": 3, "nanosec": 4}, "frame_id": "f"},
          "name": ["a", "b"], "position": [1.0, 2.0], "velocity": [0.1, 0.2], "effort": []}
    with Ros2Subscriber(env, "/js") as sub, Ros2Publisher(env, "/js") as pub:
        pub.wait_matched(1, timeout=20)
        sub.wait_matched(1, timeout=20)
        pub.publish(js)
        (m,) = sub.wait_for(1, timeout=10)
    assert m.msg == js


def test_rclpy_stream_at_rate(ros2_domain):
    env = ros2_domain.env
    msgs = [{"name": ["j"], "position": [float(i)]} for i in range(10)]
    with Ros2Subscriber(env, "/rate") as sub, \
            Ros2Publisher(env, "/rate", messages=msgs, rate=100, count=10, wait_matched=True,
                          stamp_now=True) as pub:
        pub.wait_event("done", timeout=20)
        got = sub.wait_for(10, timeout=10)
    assert [g.msg["position"] for g in got] == [[float(i)] for i in range(10)]
    assert all(g.msg["header"]["stamp"]["sec"] > 0 for g in got)


def test_ros2_domains_are_distinct():
    with Ros2Domain() as a, Ros2Domain() as b:
        assert a.domain_id != b.domain_id
        assert 1 <= a.domain_id <= 100 and 1 <= b.domain_id <= 100
    assert ros2_env()["ROS_DOMAIN_ID"] == ros2_env()["ROS_DOMAIN_ID"]


def test_msg_dependencies():
    files = ros1_msg_files(["sensor_msgs/JointState", "geometry_msgs/PoseStamped"])
    assert set(files) == {"sensor_msgs/JointState", "std_msgs/Header", "geometry_msgs/PoseStamped",
                          "geometry_msgs/Pose", "geometry_msgs/Point", "geometry_msgs/Quaternion"}


def test_everything_stopped_at_the_end():
    """Servers, peers and whole process groups are gone after their context."""
    procs = []
    ports = []
    with YarpRosStack(msg_types=["sensor_msgs/JointState"]) as stack:
        procs += stack.procs()
        ports += [stack.port, stack.roscore.port]
        assert all(p.alive for p in procs)
        roscore = stack.roscore.proc
        # roscore runs rosmaster and rosout as children (in sessions of their own)
        assert len(roscore.tree()) >= 3
        with YarpReader(stack.env, "/end/in") as reader, \
                RospySubscriber(stack.env, "/end") as sub:
            procs += [reader, sub]
    with YarpServer() as server, Ros2Domain() as dom:
        with Ros2Subscriber(dom.env, "/end") as sub2, YarpProducer(server.env, "/end/out") as p:
            procs += [server.proc, sub2, p]
            ports.append(server.port)
        # a process ignoring SIGTERM is killed too
        stubborn = Proc(["/bin/sh", "-c", "trap '' TERM; sleep 60 & wait; sleep 60"],
                        name="stubborn").start()
        procs.append(stubborn)
        stubborn.stop(timeout=0.5)
    for p in procs:
        assert not p.alive, p
        assert not p.group_alive(), p
    assert not set(procs) & set(live_processes())
    # and no yarpserver / roscore / rosmaster with those ports anywhere
    for cmd in _cmdlines():
        words = cmd.split()
        if any(w.endswith(("yarpserver", "roscore", "rosmaster")) for w in words[:3]):
            assert not any(str(port) in words for port in ports), cmd


def _cmdlines():
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/cmdline", "rb") as f:
                    out.append(f.read().replace(b"\0", b" ").decode(errors="replace"))
            except OSError:
                pass
    return out


def test_missing_middleware_fails_with_install_hint(monkeypatch, tmp_path):
    nowhere = dataclasses.replace(DEFAULT_YARP, bin=tmp_path / "nowhere")
    with pytest.raises(pytest.fail.Exception, match="scripts/setup.sh"):
        require_yarp(nowhere)
    monkeypatch.setattr(harness_env, "YARP_CACHE", tmp_path / "cache")
    unbuilt = yarp_install("4.0.0")
    assert unbuilt.missing()
    with pytest.raises(pytest.fail.Exception, match=r"scripts/setup.sh --yarp 4\.0\.0"):
        require_yarp(unbuilt)
    monkeypatch.setattr(harness_ros2, "VENV_PYTHON", tmp_path / "no-python")
    with pytest.raises(pytest.fail.Exception, match="scripts/setup.sh"):
        require_ros2()


def test_update_goldens_option_defaults_to_false(update_goldens):
    assert update_goldens is False
