"""ROS 2 QoS the ROS way: the node honours ``qos_overrides./<topic>.publisher.<policy>``
parameters (as rclcpp and rclpy nodes do) on top of the config's QoS, seen
from the subscriber's side: a TRANSIENT_LOCAL subscriber that joins late gets
the last message only when the override makes the publisher transient_local;
a RELIABLE subscriber does not match a publisher overridden to best effort
while a BEST_EFFORT one does; ``.subscription.`` overrides the QoS of a topic
the node reads, as its mux's own QoS does; a bad value is an error, not a
traceback."""
from __future__ import annotations

import pytest

from harness.generated import generate
from harness.module import Node, stop_clean
from harness.programs import QOS_CONFIG as CONFIG, QOS_READER as READER, QOS_VALUE as VALUE
from harness.ros2 import QosSubscriber, Ros2Publisher, statuses, wait_incompatible, yarp_and_ros2
from harness.yarp import YarpProducer
from ybg.compiler.ir import QoS


@pytest.fixture
def mw(ros2_domain):
    with yarp_and_ros2(ros2_domain) as both:
        yield both


NODE = "qos_bridge"
TOPIC = "/qos/point"
OUTPUT = f"{NODE}: output {TOPIC}"


def start(mw, tmp_path, *overrides):
    """The node with ``overrides`` (``policy:=value`` of its publisher), its
    producer connected, and a /diagnostics subscriber (the node's totals)."""
    folder = generate(tmp_path, CONFIG, NODE, "ros2")
    args = []
    for o in overrides:
        args += ["-p", f"qos_overrides.{TOPIC}.publisher.{o}"]
    diag = QosSubscriber(mw.env, "/diagnostics", "diagnostic_msgs/msg/DiagnosticArray").start()
    producer = YarpProducer(mw.env, "/qos/p:o").start()
    node = Node(mw.env, folder / f"{NODE}_node.py", *(["--ros-args", *args] if args else [])).start()
    node.wait_log("publishing")
    producer.wait_outputs(1)
    return node, producer, diag


def published(diag) -> int:
    """The node's count of published messages, from the newest /diagnostics."""
    diag.wait_for(1)
    return int(statuses(diag.messages[-1].msg)[OUTPUT][2]["published"])


def publish_one(producer, diag):
    """One Bottle in, one message out (event-driven), before any subscriber joins."""
    producer.write([VALUE["x"], VALUE["y"], VALUE["z"]])
    diag.wait(lambda: diag.messages and published(diag) == 1, 60, "one message published")


@pytest.mark.parametrize("override", [True, False], ids=["transient_local", "config"])
def test_late_transient_local_subscriber(mw, tmp_path, override):
    node, producer, diag = start(mw, tmp_path, *(["durability:=transient_local"] if override else []))
    late = None
    try:
        publish_one(producer, diag)
        late = QosSubscriber(mw.env, TOPIC, "geometry_msgs/msg/Point",
                             QoS(reliability="reliable", durability="transient_local")).start()
        if override:
            assert late.wait_for(1)[0].msg == VALUE  # the message published before it joined
            late.wait_publishers(1)
            assert late.publisher_qos[0]["durability"] == "transient_local"
        else:
            # the config's volatile publisher: a transient_local subscriber is
            # incompatible with it, and the message before it joined is gone
            wait_incompatible(late, "DURABILITY")
            assert late.messages == [] and late.publishers == 0
        log = stop_clean(node)
        assert (f"{TOPIC}: 1 subscriber\n" in log) == override
    finally:
        for p in (late, node, producer, diag):
            if p is not None:
                p.stop()


def test_reliable_subscriber_does_not_match_a_best_effort_override(mw, tmp_path):
    node, producer, diag = start(mw, tmp_path, "reliability:=best_effort", "depth:=3")
    reliable = QosSubscriber(mw.env, TOPIC, "geometry_msgs/msg/Point",
                             QoS(reliability="reliable")).start()
    best_effort = QosSubscriber(mw.env, TOPIC, "geometry_msgs/msg/Point",
                                QoS(reliability="best_effort")).start()
    try:
        node.wait_log(f"{TOPIC}: 1 subscriber\n")
        wait_incompatible(reliable, "RELIABILITY")
        best_effort.wait_publishers(1)
        assert best_effort.publisher_qos[0]["reliability"] == "best_effort"
        producer.write([VALUE["x"], VALUE["y"], VALUE["z"]])
        assert best_effort.wait_for(1)[0].msg == VALUE
        diag.wait(lambda: diag.messages and published(diag) == 1, 60, "one message published")
        assert reliable.messages == [] and reliable.publishers == 0
        log = stop_clean(node)
        assert f"{TOPIC}: 2 subscribers" not in log
    finally:
        for p in (reliable, best_effort, node, producer, diag):
            p.stop()


def test_a_bad_override_is_an_error(mw, tmp_path):
    folder = generate(tmp_path, CONFIG, NODE, "ros2")
    node = Node(mw.env, folder / f"{NODE}_node.py", "--ros-args", "-p",
                f"qos_overrides.{TOPIC}.publisher.reliability:=sometimes").start()
    try:
        assert node.wait_exit(60) != 0
        log = node.log_text()
        assert f"cannot advertise {TOPIC}" in log and "sometimes" in log, log
        assert "Traceback" not in log, log
    finally:
        node.stop()


@pytest.mark.parametrize("asked", ["override", "mux", None])
def test_subscription_override(mw, tmp_path, asked):
    """The node's subscription asks for transient_local, by the override or
    by its mux (`durability = transient_local` in the config): a volatile
    publisher is then incompatible (its rclpy says so), as it is not with the
    node's own best-effort volatile subscription."""
    config = READER if asked != "mux" else READER.replace("via = ros2\n", "via = ros2\ndurability = transient_local\n")
    folder = generate(tmp_path, config, "qos_reader", "ros2")
    args = ["--ros-args", "-p", "qos_overrides./qos/goal.subscription.durability:=transient_local"]
    pub = Ros2Publisher(mw.env, "/qos/goal", "geometry_msgs/msg/Point").start()
    node = Node(mw.env, folder / "qos_reader_node.py", *(args if asked == "override" else [])).start()
    try:
        node.wait_log("publishing")
        if asked:
            wait_incompatible(pub, "DURABILITY", "subscription discovered", "requesting")
            assert pub.matched == 0
        else:
            node.wait_log("/qos/goal: 1 publisher\n")
            pub.wait(lambda: pub.matched == 1, 60, "the node's subscription matched")
        stop_clean(node)
    finally:
        node.stop()
        pub.stop()
