"""The incompatible peers of a module's ROS 2 publisher and subscriptions,
at run time, for the native module (``cpp``, rcl events) and the rclpy node
(``ros2``), which say and count them alike:

- a peer of an incompatible QoS (a reliable subscriber of the module's
  publisher made best effort; a transient_local one; a volatile publisher
  of a topic the module reads as transient_local): the first is said once
  per endpoint with the policy and both QoS, every one counted in `stats`,
  /diagnostics and the exit totals;
- a peer whose type has the same name and another definition
  (``ybg_demo_msgs/Polygon`` with one field more: tests/harness/variant.py):
  what Fast DDS (the wheels' rmw) does with it, which is to raise no
  incompatible-type event at all: the two never match, no message passes,
  the module says nothing and counts 0 (docs/ros2-native.md).

One name server and one ROS 2 domain for the file, one build of the module.
"""
from __future__ import annotations

import os
import re
import subprocess
from types import SimpleNamespace

import pytest

from harness.build import Builds
from harness.env import ROOT, VENV
from harness.generated import YBGC
from harness.module import Module, Node, stop_clean
from harness.ros2 import QosSubscriber, Ros2Domain, Ros2Publisher, ros2_environment, statuses
from harness.variant import variant_env
from harness.yarp import YarpServer, rpc
from ybg.backends import check_result
from ybg.lower import ros2_events as texts
from ybg.runtime import core
from ybg.compiler.ir import QoS
from ybg.compiler.options import Options
from ybg.compiler.pipeline import compile_text

NAME = "events_bridge"
OUT = "/events/out"
IN = "/events/in"
POLYGON = "ybg_demo_msgs/msg/Polygon"

#: a ROS 2 topic in, a ROS 2 topic out, both of a message of the venv's own
#: package (the variant's is its other definition), and a YARP port
CONFIG = f"""\
[module]
name = {NAME}

[output]
topic = {OUT}
type = ybg_demo_msgs/Polygon
via = ros2

[mux m]
topics = {IN} (ybg_demo_msgs/Polygon header.stamp)
via = ros2

[mux y]
ports = /events/y:o (float64 x1)

[message]
header.stamp = timestamp(m)
label = "events"
corners[0].x = m[0]
corners[1].x = y[0]
"""

#: the module's publisher made best effort, its subscription transient_local
OVERRIDES = ("--ros-args", "-p", f"qos_overrides.{OUT}.publisher.reliability:=best_effort",
             "-p", f"qos_overrides.{IN}.subscription.durability:=transient_local")

# `yarp rpc` prints a topic quoted
STATS_ROS2 = re.compile(r'^\s*ros2 (publisher|subscription) "?([^"\s]+)"? '
                        r"incompatible_qos (\d+) incompatible_type (\d+)$", re.M)


def environ() -> dict:
    """ybgc finds ybg_demo_msgs in the venv, as its user does (AMENT_PREFIX_PATH)."""
    return dict(os.environ, AMENT_PREFIX_PATH=str(VENV))


@pytest.fixture(scope="module")
def mw(yarp):
    with Ros2Domain() as domain, YarpServer(install=yarp) as server:
        yield SimpleNamespace(env=ros2_environment(server.env, domain), server=server)


@pytest.fixture(scope="module")
def modules(tmp_path_factory, yarp) -> dict:
    """How to start each backend's module: the native one built once, the
    node generated once."""
    result = check_result(compile_text(CONFIG, f"{NAME}.ini", Options(environ=environ())), "cpp")
    assert result.ok, [str(d) for d in result.diagnostics]
    builds = Builds(tmp_path_factory.mktemp("ros2_events"), yarp)
    builds.add(NAME, result.program)
    folder = tmp_path_factory.mktemp("ros2_events_node")
    cfg = folder / f"{NAME}.ini"
    cfg.write_text(CONFIG)
    r = subprocess.run([str(YBGC), str(cfg), "--backend", "ros2", "-o", str(folder / "node")],
                       capture_output=True, text=True, timeout=60, env=environ())
    assert r.returncode == 0, r.stdout + r.stderr
    return {"cpp": lambda env, *args: Module([builds.exe(NAME), *args], env=env, name=f"{NAME}_cpp"),
            "ros2": lambda env, *args: Node(env, folder / "node" / f"{NAME}_node.py", *args, name=f"{NAME}_node")}


def events_stats(server) -> dict:
    """{(kind, topic): (incompatible QoS, incompatible type)} of `stats`,
    and its text ("text")."""
    text = rpc(server, f"/{NAME}/rpc:i", "stats")
    return {"text": text, **{(m[0], m[1]): (int(m[2]), int(m[3])) for m in STATS_ROS2.findall(text)}}


def qos_line(kind: str, topic: str, peer: str, policy: str, theirs: str, ours: str) -> str:
    """The line the module says of its first peer of an incompatible QoS."""
    text = texts.INCOMPATIBLE_QOS_TEXT.format(kind=kind, topic=topic, peer=peer, policy=policy, theirs=theirs,
                                              ours=ours)
    return f"{NAME}: {text}\n"


def cpp_text(name: str) -> str:
    """The text of the C++ runtime's string constant ``name`` (adjacent literals joined)."""
    source = (ROOT / "ybg" / "runtime" / "cpp" / "ybgc_ros2_events.cpp").read_text()
    m = re.search(rf"{name} =\s*((?:\"[^\"]*\"\s*)+);", source)
    assert m, name
    return "".join(re.findall(r'"([^"]*)"', m.group(1)))


def test_both_runtimes_say_the_lowering_librarys_texts():
    """What each runtime says is ybg/lower/ros2_events.py's, word for word
    (the type's text is never said with Fast DDS: only this shows it)."""
    assert core.INCOMPATIBLE_QOS_TEXT == texts.INCOMPATIBLE_QOS_TEXT == cpp_text("kIncompatibleQosText")
    assert core.INCOMPATIBLE_TYPE_TEXT == texts.INCOMPATIBLE_TYPE_TEXT == cpp_text("kIncompatibleTypeText")
    assert core.EVENTS_TOTALS_LINE == texts.EVENTS_TOTALS_LINE
    assert core.SUBSCRIBERS_TEXT == texts.SUBSCRIBERS_TEXT == cpp_text("kSubscribersText")
    assert core.PUBLISHERS_TEXT == texts.PUBLISHERS_TEXT == cpp_text("kPublishersText")


#: the ROS 2 side depends on no YARP release: one of the matrix
ros2_side = pytest.mark.yarp_min((4, 0))


@ros2_side
@pytest.mark.parametrize("backend", ["cpp", "ros2"])
def test_incompatible_qos_said_once_and_counted(mw, modules, backend):
    """Two subscribers the module's publisher cannot serve (reliable against
    its best effort; transient_local against its volatile) and a publisher
    its subscription refuses (volatile against its transient_local): each
    endpoint says its first, with the policy and both QoS, and counts every
    one, in `stats`, /diagnostics and the exit totals."""
    env = mw.env
    diag = QosSubscriber(env, "/diagnostics", "diagnostic_msgs/msg/DiagnosticArray").start()
    module = modules[backend](env, *OVERRIDES).start()
    peers = [diag]
    try:
        module.wait_log("publishing")
        reliable = QosSubscriber(env, OUT, POLYGON, QoS(reliability="reliable", durability="volatile")).start()
        peers.append(reliable)
        said = qos_line("publisher", OUT, "subscription", "reliability", "reliable, volatile", "best_effort, volatile")
        module.wait_log(said)
        late = QosSubscriber(env, OUT, POLYGON, QoS(reliability="best_effort", durability="transient_local")).start()
        peers.append(late)
        volatile = Ros2Publisher(env, IN, POLYGON).start()
        peers.append(volatile)
        module.wait_log(qos_line("subscription", IN, "publisher", "durability", "reliable, volatile",
                                 "best_effort, transient_local"))
        got = {}

        def counted():
            got.update(events_stats(mw.server))
            return got.get(("publisher", OUT)) == (2, 0)
        volatile.wait(counted, 30, "the second incompatible subscriber counted")
        text = got.pop("text")
        assert got == {("publisher", OUT): (2, 0), ("subscription", IN): (1, 0)}, text

        def diagnosed():
            if not diag.messages:
                return False
            st = statuses(diag.messages[-1].msg)
            out, inp = st[f"{NAME}: output {OUT}"][2], st[f"{NAME}: input {IN}"][2]
            return (out["incompatible QoS"], out["incompatible type"], inp["incompatible QoS"]) == ("2", "0", "1")
        diag.wait(diagnosed, 30, "the counts on /diagnostics")
        assert reliable.publishers == 0 and late.publishers == 0 and volatile.matched == 0
        log = stop_clean(module)
    finally:
        for p in [module, *peers]:
            p.stop()
    assert log.count("incompatible QoS events of it") == 2, log  # one said per endpoint
    for line in (("publisher", OUT, 2, 0), ("subscription", IN, 1, 0)):
        assert "  " + texts.EVENTS_TOTALS_LINE % line + "\n" in log, log


@ros2_side
@pytest.mark.parametrize("backend", ["cpp", "ros2"])
def test_another_definition_of_the_type(mw, modules, backend):
    """Peers of the variant Polygon (its name, another definition and type
    hash): Fast DDS never matches them with the module, raises no
    incompatible-type event, and no message passes either way; the venv's
    Polygon, on the same topics at the same time, matches and passes."""
    env = mw.env
    other = variant_env(env)
    module = modules[backend](env).start()
    peers = []
    try:
        module.wait_log("publishing")
        # the other definition's peers first: discovered before the control's
        variant_sub = QosSubscriber(other, OUT, POLYGON).start()
        variant_pub = Ros2Publisher(other, IN, POLYGON, messages=[{"label": "variant"}], rate=20.0).start()
        peers += [variant_sub, variant_pub]
        own_sub = QosSubscriber(env, OUT, POLYGON).start()
        own_pub = Ros2Publisher(env, IN, POLYGON).start()
        peers += [own_sub, own_pub]
        own_sub.wait_publishers(1)
        own_pub.wait_matched(1)
        # the module's side of both matches (its subscription is best effort:
        # a message sent before it has matched the publisher is lost)
        module.wait_log(f"{OUT}: 1 subscriber\n")
        module.wait_log(f"{IN}: 1 publisher\n")
        own_pub.publish({"label": "own"})
        got = {}

        def received():
            text = rpc(mw.server, f"/{NAME}/rpc:i", "stats")
            m = re.search(rf'^\s*input "?{IN}"? received (\d+)', text, re.M)
            got.update(events_stats(mw.server))
            return m is not None and int(m.group(1)) >= 1
        own_pub.wait(received, 30, "the module received the message of its own Polygon")
        assert len(variant_pub.sent) > 0
        assert variant_sub.publishers == 0 and variant_sub.messages == [], variant_sub.log_text()[-2000:]
        assert variant_pub.matched == 0
        text = got.pop("text")
        assert got == {("publisher", OUT): (0, 0), ("subscription", IN): (0, 0)}, text
        log = stop_clean(module)
    finally:
        for p in [module, *peers]:
            p.stop()
    assert re.search(rf"input {IN}: received 1, dropped 0", log), log
    assert "another definition" not in log, log
    # the variant's peers never matched, seen from the module's side too
    assert f"{OUT}: 2 subscribers" not in log and f"{IN}: 2 publishers" not in log, log
