"""The native ROS 2 module's QoS and clock the ROS way, as the Python node's
(tests/test_qos_overrides.py): ``qos_overrides./<topic>.publisher.<policy>``
and ``.subscription.`` parameters on top of the config's QoS, seen from the
peers' side (a late TRANSIENT_LOCAL subscriber gets the last message only with
the override; a RELIABLE subscriber does not match a publisher made best
effort while a BEST_EFFORT one does; a subscription made transient_local is
incompatible with a volatile publisher); a value ROS 2 refuses stops the
module with the parameter and what it accepts; the overrides name a topic as
remapped. And ``use_sim_time`` for a module whose output is a YARP port: the
times it writes are the simulated time of /clock, as the Python node's are;
the Python node's options as ROS parameters (``-p rate:=25``); ``--help``.

The unit tests of the parameters and overrides themselves (node names,
parameter files, each refused value) are in tests/runtime/ros2/.
"""
from __future__ import annotations

import signal
import time

import pytest

from harness.build import Builds
from harness.generated import generate
from harness.module import EXIT_BOUND, Module, Node
from harness.programs import QOS_SIM_TIME, QOS_VALUE as VALUE
from harness.ros2 import QosSubscriber, Ros2Publisher, ros2_environment, wait_incompatible
from harness.yarp import YarpProducer, YarpReader
from ybg.compiler.ir import QoS

pytestmark = pytest.mark.yarp_min((4, 0))  # the ROS 2 side depends on no YARP release

TOPIC = "/qos/point"



@pytest.fixture
def built(builds) -> Builds:
    """The session's modules of ``yarp`` (conftest.py), among them
    ``qos_point``, ``qos_reader`` and ``qos_sim`` (harness.programs's
    QOS_CONFIG, QOS_READER and QOS_SIM_TIME)."""
    return builds


@pytest.fixture
def env(yarp_server, ros2_domain):
    return ros2_environment(yarp_server.env, ros2_domain)


def start(built, env, *args):
    """The module publishing /qos/point, started with ``args`` and its producer connected."""
    producer = YarpProducer(env, "/qos/p:o").start()
    module = Module([built.exe("qos_point"), *args], env=env, name="qos_bridge").start()
    module.wait_log("event-driven")
    producer.wait_outputs(1)
    return module, producer


def overrides(*policies, entity="publisher", topic=TOPIC):
    args = ["--ros-args"]
    for p in policies:
        args += ["-p", f"qos_overrides.{topic}.{entity}.{p}"]
    return args


def stop_clean(module):
    """SIGINT: exit 0 within EXIT_BOUND."""
    rc, took = module.interrupt(signal.SIGINT)
    assert rc == 0 and took < EXIT_BOUND, module.log_text()[-2000:]


@pytest.mark.timeout(900)  # the first test builds the modules
@pytest.mark.parametrize("override", [True, False], ids=["transient_local", "config"])
def test_late_transient_local_subscriber(built, env, override):
    module, producer = start(built, env, *(overrides("durability:=transient_local") if override else []))
    early = late = None
    try:
        durability = "transient_local" if override else "volatile"
        module.wait_log(f"geometry_msgs/msg/Point on the ROS 2 topic {TOPIC} (node qos_bridge, reliable, "
                        f"{durability}, depth 10)")
        # one message, received by a subscriber there from the start: published before the late one joins
        early = QosSubscriber(env, TOPIC, "geometry_msgs/msg/Point", QoS(reliability="reliable")).start()
        early.wait_publishers(1)
        producer.write([VALUE["x"], VALUE["y"], VALUE["z"]])
        assert early.wait_for(1)[0].msg == VALUE
        late = QosSubscriber(env, TOPIC, "geometry_msgs/msg/Point",
                             QoS(reliability="reliable", durability="transient_local")).start()
        if override:
            assert late.wait_for(1)[0].msg == VALUE  # the message published before it joined
            late.wait_publishers(1)
            assert late.publisher_qos[0]["durability"] == "transient_local"
        else:
            wait_incompatible(late, "DURABILITY")
            assert late.messages == [] and late.publishers == 0
        assert len(early.messages) == 1  # event-driven: that one message only
        stop_clean(module)
    finally:
        for p in (late, early, module, producer):
            if p is not None:
                p.stop()


def test_reliable_subscriber_does_not_match_a_best_effort_override(built, env):
    module, producer = start(built, env, *overrides("reliability:=best_effort", "depth:=3"))
    reliable = QosSubscriber(env, TOPIC, "geometry_msgs/msg/Point", QoS(reliability="reliable")).start()
    best_effort = QosSubscriber(env, TOPIC, "geometry_msgs/msg/Point", QoS(reliability="best_effort")).start()
    try:
        module.wait_log(f"{TOPIC} (node qos_bridge, best_effort, volatile, depth 3)")
        wait_incompatible(reliable, "RELIABILITY")
        best_effort.wait_publishers(1)
        assert best_effort.publisher_qos[0]["reliability"] == "best_effort"
        # best effort: a message may be lost (a busy machine), so the Bottle again until one arrives
        end = time.monotonic() + 60
        while not best_effort.messages:
            assert time.monotonic() < end, "no message for the best-effort subscriber"
            producer.write([VALUE["x"], VALUE["y"], VALUE["z"]])
            time.sleep(0.3)
        assert best_effort.wait_for(1)[0].msg == VALUE
        assert reliable.messages == [] and reliable.publishers == 0
        stop_clean(module)
    finally:
        for p in (reliable, best_effort, module, producer):
            p.stop()


@pytest.mark.parametrize("value, said", [
    ("reliability:=sometimes", "reliability: 'sometimes' is not one of reliable, best_effort"),
    ("depth:=-2", "depth: -2 is not an integer of at least 0"),
])
def test_a_bad_override_is_an_error(built, env, value, said):
    module = Module([built.exe("qos_point"), *overrides(value)], env=env, name="qos_bridge_bad").start()
    try:
        end = time.monotonic() + 60
        while module.alive:
            assert time.monotonic() < end, module.log_text()[-2000:]
            time.sleep(0.05)
        log = module.log_text()
        assert module.returncode != 0, log
        assert f"cannot publish geometry_msgs/msg/Point on {TOPIC}: qos_overrides.{TOPIC}.publisher.{said}" in log
    finally:
        module.stop()


def test_the_overrides_name_the_remapped_topic(built, env):
    """With `-r /qos/point:=/qos/moved` the publisher is on /qos/moved and the
    overrides of /qos/moved apply, as rclpy resolves the name they give."""
    args = ["--ros-args", "-r", f"{TOPIC}:=/qos/moved", "-p",
            "qos_overrides./qos/moved.publisher.durability:=transient_local", "-p",
            f"qos_overrides.{TOPIC}.publisher.depth:=4"]
    module, producer = start(built, env, *args)
    late = None
    try:
        module.wait_log("on the ROS 2 topic /qos/moved (node qos_bridge, reliable, transient_local, depth 10)")
        late = QosSubscriber(env, "/qos/moved", "geometry_msgs/msg/Point",
                             QoS(reliability="reliable", durability="transient_local")).start()
        late.wait_publishers(1)
        producer.write([VALUE["x"], VALUE["y"], VALUE["z"]])
        assert late.wait_for(1)[0].msg == VALUE
        stop_clean(module)
    finally:
        for p in (late, module, producer):
            if p is not None:
                p.stop()


@pytest.mark.parametrize("override", [True, False], ids=["transient_local", "config"])
def test_subscription_override(built, env, override):
    """The module's subscription asks for transient_local with the override: a
    volatile publisher is then incompatible (its rclpy says so), as it is not
    with the module's own best-effort volatile subscription."""
    args = overrides("durability:=transient_local", entity="subscription", topic="/qos/goal")
    pub = Ros2Publisher(env, "/qos/goal", "geometry_msgs/msg/Point").start()
    module = Module([built.exe("qos_reader"), *(args if override else [])], env=env, name="qos_reader").start()
    try:
        durability = "transient_local" if override else "volatile"
        module.wait_log(f"/qos/goal (geometry_msgs/msg/Point; best_effort, {durability}, depth 1)")
        if override:
            wait_incompatible(pub, "DURABILITY", "subscription discovered", "requesting")
            assert pub.matched == 0
        else:
            pub.wait_matched(1, timeout=60)
        stop_clean(module)
    finally:
        module.stop()
        pub.stop()


@pytest.mark.parametrize("backend", ["cpp", "ros2"])
def test_yarp_output_use_sim_time_writes_the_simulated_time(built, env, tmp_path, backend):
    """A ROS 2 input, a YARP output, `-p use_sim_time:=true`: `time` and
    `timestamp` are the simulated time of /clock, 0 until the first /clock
    message, from the native module as from the Python node."""
    sim = {"sec": 4242, "nanosec": 500000000}
    clock = Ros2Publisher(env, "/clock", "rosgraph_msgs/msg/Clock", messages=[{"clock": sim}], rate=50)
    args = ["--ros-args", "-p", "use_sim_time:=true"]
    if backend == "cpp":
        module = Module([built.exe("qos_sim"), *args], env=env, name="sim_reader")
    else:
        folder = generate(tmp_path, QOS_SIM_TIME, "sim_reader", "ros2")
        module = Node(env, folder / "sim_reader_node.py", *args)
    reader = YarpReader(env, "/sim_reader/check:i", source="/sim_reader/out:o")
    goal = Ros2Publisher(env, "/sim/goal", "geometry_msgs/msg/Point")
    procs = [clock, module, reader, goal]
    try:
        for p in procs:
            p.start()
        if backend == "cpp":
            module.wait_log("use_sim_time: stamps from /clock")
        reader.wait_connected()
        clock.wait_matched(1, timeout=60)
        goal.wait_matched(1, timeout=60)
        end = time.monotonic() + 60
        while not any(b.data[3] == 4242.5 for b in reader.bottles):
            assert time.monotonic() < end, reader.bottles[-3:]
            goal.publish({"x": 1.0, "y": 2.0, "z": 3.0})
            time.sleep(0.3)
        got = next(b.data for b in reader.bottles if b.data[3] == 4242.5)
        assert got == [1.0, 2.0, 3.0, 4242.5, [4242, 500000000]]
        # never the wall clock: 0 before the first /clock message, then the simulated time
        assert {b.data[3] for b in reader.bottles} <= {0.0, 4242.5}
        stop_clean(module)
    finally:
        for p in reversed(procs):
            p.stop()


def test_help_lists_the_ros_arguments(built):
    """--help of a module with a ROS 2 side, an output or inputs, says the
    ROS arguments it takes."""
    import subprocess

    for key in ("qos_point", "qos_reader"):
        r = subprocess.run([str(built.exe(key)), "--help"], capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr
        for word in ("--ros-args", "use_sim_time", "diagnostic_updater.period", "qos_overrides./TOPIC.publisher"):
            assert word in r.stdout, (key, r.stdout)
        assert r.stdout.rstrip().endswith(".ini.")  # the config it came from, last


def test_options_as_ros_parameters(built, env):
    """The options the Python node takes as parameters (a launch file's
    `parameters`), the command line's own winning; a refused value exits 2
    before anything opens."""
    producer = YarpProducer(env, "/qos/p:o").start()
    module = Module([built.exe("qos_point"), "--ros-args", "-p", "rate:=25", "-p", "prefix:=/qos_params"], env=env,
                    name="qos_params").start()
    try:
        module.wait_log(", 25 Hz")
        module.wait_log("connected /qos/p:o -> /qos_params/")  # its own ports under the prefix
        stop_clean(module)
    finally:
        module.stop()
        producer.stop()
    module = Module([built.exe("qos_point"), "--rate", "10", "--ros-args", "-p", "rate:=25"], env=env,
                    name="qos_params_line").start()
    try:
        module.wait_log(", 10 Hz")
        stop_clean(module)
    finally:
        module.stop()
    module = Module([built.exe("qos_point"), "--ros-args", "-p", "rate:=-3"], env=env, name="qos_params_bad").start()
    try:
        assert module.wait_exit(60) == 2
        assert "parameter rate must be 0 (event-driven) or positive" in module.log_text()
    finally:
        module.stop()
