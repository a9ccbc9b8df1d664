"""``ybgc compose`` with the Python backends (docs/compose.md): several
configs, one process.

- ``ros2``: the 14 configs of a whole iCub (examples/icub_robot/) composed
  and run end to end in one process, one rclpy context: a real YARP producer
  on every input port, real rclpy subscribers on every topic, a trajectory
  published into YARP; every bridge's values; every node on the graph, all
  of one DDS participant, one process; isolation (a producer stalled for
  5 s, a ROS 2 subscriber and a YARP reader stalled, malformed Bottles on one
  bridge: the other bridges keep their rate within 1 %, the stalled one
  publishes nothing stale); `stats` and `quit` on ``/icub/rpc:i``. One
  composed process serves every test of the class.
- ``ros2 --package``: one ament_python package, one executable, a launch
  file and the parameter file keyed by node name.
- ``py``: three YARP-output configs in one process, one of them unable to
  start (its output port taken): the others' values, `stats`, exit 1.
"""
from __future__ import annotations

import ast
import concurrent.futures
import json
import math
import os
import re
import signal
import subprocess
import threading
import time
from pathlib import Path
from types import SimpleNamespace

import pytest

from harness import geometry_reference
from harness.env import EXAMPLES, VENV_PYTHON, yarp_install
from harness.generated import ybgc
from harness.images import ImagePeer, frame, sha_of
from harness.module import Node
from harness.procs import Proc, wait_until
from harness.ros2 import Ros2Domain, Ros2Publisher, Ros2Subscriber, ros2_environment, subscriber_for
from harness.yarp import YarpProducer, YarpReader, YarpServer, rpc
from ybg.compiler.pipeline import compile_path

ICUB = EXAMPLES / "icub_robot"
#: deg_to_rad and rad_to_deg, as docs/runtime.md defines them
DEG = 0.017453292519943295
RAD = 57.29577951308232
#: the producers' rate (the bridges publish at their own, 100 Hz and 50 Hz,
#: the newest values while they are fresh)
PRODUCER_HZ = 20
#: the seconds one producer and two consumers are stalled
STALL = 5.0
#: the seconds between two /diagnostics messages of each node
DIAGNOSTICS_PERIOD = 0.5

#: the joint state bridges: module -> (port, node name), their values
#: distinct per part (degrees)
JOINTS = {
    "icub_head": "/icub/head/state:o",
    "icub_torso": "/icub/torso/state:o",
    "icub_left_arm": "/icub/left_arm/state:o",
    "icub_right_arm": "/icub/right_arm/state:o",
    "icub_left_leg": "/icub/left_leg/state:o",
    "icub_right_leg": "/icub/right_leg/state:o",
}
WRENCHES = {
    "icub_ft_left_arm": ("/icub/left_arm/analog:o", "/icub/left_arm/wrench", "l_arm_ft_sensor"),
    "icub_ft_right_arm": ("/icub/right_arm/analog:o", "/icub/right_arm/wrench", "r_arm_ft_sensor"),
    "icub_ft_left_leg": ("/icub/left_leg/analog:o", "/icub/left_leg/wrench", "l_leg_ft_sensor"),
    "icub_ft_right_leg": ("/icub/right_leg/analog:o", "/icub/right_leg/wrench", "r_leg_ft_sensor"),
}
IMU_PORT = "/icub/inertial"
#: roll pitch yaw (deg), acceleration, angular velocity (deg/s), magnetometer
IMU_VALUES = [10.0, -20.0, 30.0, 0.1, 0.2, 9.81, 5.0, -5.0, 15.0, 0.3, 0.4, 0.5]
TF_PORTS = {"l_hand_cartesian": "/icub/cartesianController/left_arm/state:o",
            "r_hand_cartesian": "/icub/cartesianController/right_arm/state:o"}
#: x y z and the axis-angle ax ay az theta of each hand
TF_VALUES = {"l_hand_cartesian": [0.1, 0.2, 0.3, 0.0, 0.0, 1.0, 0.5],
             "r_hand_cartesian": [-0.1, 0.25, 0.35, 1.0, 0.0, 0.0, -0.75]}
CAMERA = "/icub/cam/left"
IMAGE_TOPIC = "/icub/cam/left/image_raw"
TRAJECTORY_TOPIC = "/left_arm_controller/joint_trajectory"
TRAJECTORY_PORT = "/icub/left_arm/trajectory/plan:i"
#: the bridges at a fixed rate, and theirs (Hz)
RATES = {**{m: 100.0 for m in JOINTS}, "icub_imu": 100.0, **{m: 100.0 for m in WRENCHES}, "icub_tf_hands": 50.0}


def joint_values(module: str, width: int) -> list[float]:
    k = sorted(JOINTS).index(module)
    return [10.0 * k + 1.5 * j - 7.25 for j in range(width)]


def wrench_values(module: str) -> list[float]:
    k = sorted(WRENCHES).index(module)
    return [1.5 + k, -2.25 - k, 30.0 + k, 0.125 * k, -0.5, 0.75 + k]


def trajectory(points: int = 60, joints: int = 7) -> dict:
    """A JointTrajectory of ``points`` points (big enough that a stalled
    reader's connection fills up within the stall)."""
    return {"joint_names": [f"j{j}" for j in range(joints)],
            "points": [{"positions": [0.01 * p + 0.1 * j for j in range(joints)],
                        "time_from_start": {"sec": p // 10, "nanosec": (p % 10) * 100_000_000}}
                       for p in range(points)]}


def close(a, b, tol=1e-12) -> bool:
    return len(a) == len(b) and all(math.isclose(x, y, rel_tol=0, abs_tol=tol) for x, y in zip(a, b))


def stamp(t: dict) -> float:
    return t["sec"] + t["nanosec"] * 1e-9


def run_parallel(*starts):
    """Start peers at once (each waits for its own `ready`)."""
    with concurrent.futures.ThreadPoolExecutor(max_workers=8) as pool:
        for f in [pool.submit(s) for s in starts]:
            f.result()


# --------------------------------------------------------------------------
# the graph, as a separate rclpy process sees it


GRAPH_PROBE = r"""
import json, sys, time
import rclpy
from rclpy.signals import SignalHandlerOptions
want = set(json.loads(sys.argv[1]))
rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
node = rclpy.create_node("ybg_test_graph_probe")
end = time.monotonic() + 30
while True:
    names = {n for n, ns in node.get_node_names_and_namespaces()}
    writers = node.get_publishers_info_by_topic("/diagnostics")
    seen = {w.node_name for w in writers}
    if (want <= names and want <= seen) or time.monotonic() > end:
        break
    time.sleep(0.1)
print(json.dumps({"nodes": sorted(names),
                  "diagnostics": [[w.node_name, bytes(w.endpoint_gid).hex()] for w in writers]}))
node.destroy_node()
rclpy.shutdown()
"""


def graph(env: dict, nodes: list[str]) -> dict:
    """The node names and the /diagnostics writers (node, gid) that an rclpy
    process finds on the graph (waiting, up to 30 s, for ``nodes``)."""
    r = subprocess.run([str(VENV_PYTHON), "-c", GRAPH_PROBE, json.dumps(nodes)], env=env, capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


# --------------------------------------------------------------------------
# the composed iCub


def composed_stats(server, port: str) -> dict:
    """`stats` of a composed module: {bridge: text of its list}."""
    text = rpc(server, port, "stats")
    out = {}
    for line in text.splitlines():
        m = re.match(r"^\s*(\w+) (.*)$", line)
        if m and m.group(1) not in ("Responses", "Response"):
            out[m.group(1)] = m.group(2)
    return out


def bridge_stats(text: str) -> dict:
    """One bridge's list of `stats`: inputs {source: (received, dropped,
    stale, unused, refused)}, published (n, skipped, failures), rate."""
    inputs = {m[0]: tuple(map(int, m[1:])) for m in re.findall(
        r'\(input "?([^"\s]+)"? received (\d+) dropped (\d+) stale (\d+) unused (\d+) refused (\d+)\)', text)}
    published = re.search(r"\(published (\d+) skipped (\d+) failures (\d+)\)", text)
    rate = re.search(r'\(rate "?([^"\s]+)"? configured "?([^"\s)]+)"?\)', text)
    return {"inputs": inputs, "published": tuple(map(int, published.groups())) if published else None,
            "rate": rate.groups() if rate else None}


def bridge_totals(log: str, module: str) -> dict:
    """The totals one bridge printed at exit, under its name."""
    out = {}
    for m in re.finditer(rf"^{module}:   input (\S+): received (\d+), dropped (\d+), stale periods (\d+), "
                         r"unused (\d+)", log, re.M):
        out[m.group(1)] = tuple(int(x) for x in m.groups()[1:])
    m = re.search(rf"^{module}:   published (\d+) messages, skipped (\d+) cycles, build failures (\d+)", log, re.M)
    if m:
        out["published"] = int(m.group(1))
    return out


@pytest.fixture(scope="module")
def icub(tmp_path_factory):
    """The iCub composed (ybgc compose --backend ros2) and running, with a
    producer on every input port and a subscriber on every topic."""
    tmp = tmp_path_factory.mktemp("icub")
    out = tmp / "icub"
    configs = sorted(ICUB.glob("*.ini"))
    r = ybgc("compose", *configs, "--backend", "ros2", "--name", "icub", "-o", out)
    assert r.returncode == 0, r.stdout + r.stderr
    programs = {p.module: p for p in (compile_path(c).program for c in configs)}
    peers = []
    with Ros2Domain() as domain, YarpServer(install=yarp_install("3.5")) as server:
        env = ros2_environment(server.env, domain)
        try:
            producers = {}
            for module, port in JOINTS.items():
                width = _width(programs[module])
                good = joint_values(module, width)
                # the torso's producer alternates with a malformed Bottle
                bottles = [good, ["not", "a", "joint"]] if module == "icub_torso" else [good]
                rate = 2 * PRODUCER_HZ if module == "icub_torso" else PRODUCER_HZ
                producers[module] = YarpProducer(env, port, bottles=bottles, rate=rate, envelope=True)
            for module, (port, _, _) in WRENCHES.items():
                producers[module] = YarpProducer(env, port, bottles=[wrench_values(module)], rate=PRODUCER_HZ,
                                                 envelope=True)
            producers["icub_imu"] = YarpProducer(env, IMU_PORT, bottles=[IMU_VALUES], rate=PRODUCER_HZ,
                                                 envelope=True)
            for child, port in TF_PORTS.items():
                producers[child] = YarpProducer(env, port, bottles=[TF_VALUES[child]], rate=PRODUCER_HZ,
                                                envelope=True)
            camera = ImagePeer(env, {"mode": "yarp_pub", "port": CAMERA})
            subs = {
                "/joint_states": Ros2Subscriber(env, "/joint_states", "sensor_msgs/msg/JointState",
                                                node="ybg_test_joints", depth=1000),
                # with the QoS each bridge offers (the IMU's is best effort)
                "/icub/imu": subscriber_for(env, programs["icub_imu"]),
                "/tf": subscriber_for(env, programs["icub_tf_hands"]),
                "/diagnostics": Ros2Subscriber(env, "/diagnostics", "diagnostic_msgs/msg/DiagnosticArray",
                                               node="ybg_test_diagnostics"),
            }
            for module, (_, topic, _) in WRENCHES.items():
                subs[topic] = subscriber_for(env, programs[module])
            image = ImagePeer(env, {"mode": "ros2_sub", "topic": IMAGE_TOPIC,
                                    "node": "ybg_test_image"})
            planner = Ros2Publisher(env, TRAJECTORY_TOPIC, "trajectory_msgs/msg/JointTrajectory",
                                    node="ybg_test_planner")
            player = YarpReader(env, TRAJECTORY_PORT)
            peers = [*producers.values(), camera, *subs.values(), image, planner, player]
            t0 = time.monotonic()
            run_parallel(*(p.start for p in peers))
            # the image subscriber is reliable: the left eye's publisher made so by a
            # parameter of its node alone (its QoS override)
            # /diagnostics twice a second, every node (the rates measured from it)
            node = Node(env, out / "icub_node.py", "--ros-args", "-p",
                        f"icub_left_eye:qos_overrides.{IMAGE_TOPIC}.publisher.reliability:=reliable",
                        "-p", f"diagnostic_updater.period:={DIAGNOSTICS_PERIOD}")
            node.start()
            node.wait_log("icub: 14 bridges running", timeout=60)
            started = time.monotonic() - t0
            yield SimpleNamespace(env=env, server=server, node=node, out=out, programs=programs,
                                  producers=producers, camera=camera, subs=subs, image=image, planner=planner,
                                  player=player, started=started)
        finally:
            for p in peers:
                p.stop()
            Node.started[:] = [n for n in Node.started if n.name != "icub_node"]


@pytest.fixture(autouse=True)
def _print_node_logs():
    """The logs of the composed processes a test ran, shown when it fails."""
    yield
    for node in Node.started:
        print(f"---- log of {node.name}:\n{node.log_text()[-6000:]}")


def published(diagnostics, program) -> list[tuple[float, int]]:
    """(stamp, messages published) of the bridge's output status in each
    DiagnosticArray its node published."""
    name = f"{program.module}: output {program.output.name}"
    out = []
    for x in list(diagnostics.messages):
        for status in x.msg["status"]:
            if status["name"] == name:
                values = {kv["key"]: kv["value"] for kv in status["values"]}
                out.append((stamp(x.msg["header"]["stamp"]), int(values["published"])))
    return sorted(out)


def slope(points: list[tuple[float, int]]) -> float:
    """The least-squares slope of (t, n) points: messages a second."""
    mt = sum(t for t, _ in points) / len(points)
    mn = sum(n for _, n in points) / len(points)
    return sum((t - mt) * (n - mn) for t, n in points) / sum((t - mt) ** 2 for t, _ in points)


def plan_through(icub, plan: dict):
    """Publish ``plan`` until its Bottle reaches the trajectory's YARP
    reader (the node's subscription is best effort: a message is lost until
    its reader has matched the planner too); the Bottle."""
    icub.planner.wait_matched(1)
    for _ in range(30):
        icub.player.clear()
        icub.planner.publish(plan)
        try:
            return icub.player.wait_for(1, timeout=1.0)[0]
        except TimeoutError:
            continue
    raise AssertionError("no trajectory into YARP")


def stall_window(icub) -> SimpleNamespace:
    """One window of STALL seconds: the IMU's producer, the subscriber of
    /joint_states and the trajectory's YARP reader SIGSTOPped, trajectories
    published all along, 300 malformed Bottles into the torso. What each
    bridge published over it (rates, from /diagnostics), what the
    subscribers of one bridge each received (counted), the cycles skipped,
    the IMU's messages after its input went stale (late), ``short``: a rate
    or a count more than 1 % off."""
    stalled_sub = icub.subs["/joint_states"]
    stalled = (icub.producers["icub_imu"], stalled_sub, icub.player)
    before = {m: bridge_stats(t) for m, t in composed_stats(icub.server, "/icub/rpc:i").items()}
    big = trajectory()
    plan_through(icub, big)
    sent = []
    stop = threading.Event()

    def plan():
        while not stop.is_set():
            icub.planner.publish(big)
            sent.append(time.time())
            time.sleep(0.02)

    planning = threading.Thread(target=plan, daemon=True)
    cpu0, waited0 = _cpu_seconds(icub.node.pid), _run_delay(icub.node.pid)
    t0 = time.time()
    for proc in stalled:
        os.kill(proc.pid, signal.SIGSTOP)
    try:
        planning.start()
        icub.producers["icub_torso"].burst([["bad"]] * 300)
        time.sleep(max(0.0, STALL - (time.time() - t0)))
    finally:
        t1 = time.time()
        cpu, waited = _cpu_seconds(icub.node.pid) - cpu0, _run_delay(icub.node.pid) - waited0
        stop.set()
        for proc in stalled:
            os.kill(proc.pid, signal.SIGCONT)
        planning.join(5)
    window = t1 - t0
    # each bridge's rate over the window, from what it published: the
    # `published` of its status on /diagnostics, stamped by its node's
    # clock (the subscriber of /joint_states is stalled; one subscriber of
    # its 600 messages a second would fall behind on a loaded machine, a
    # measure of the subscriber, not of the bridges)
    diagnostics = icub.subs["/diagnostics"]
    rated = [m for m in RATES if m != "icub_imu"]
    wait_until(lambda: all(any(t > t1 for t, _ in published(diagnostics, icub.programs[m])) for m in rated), 30,
               "a /diagnostics status of every bridge after the window")
    rates = {}
    for module in rated:
        inside = [(t, n) for t, n in published(diagnostics, icub.programs[module]) if t0 <= t <= t1]
        assert len(inside) >= 0.5 * window / DIAGNOSTICS_PERIOD, (module, inside)
        rates[module] = round(slope(inside), 2)
    # and the messages the subscribers of one bridge each (the wrenches,
    # /tf) received over the window
    streams = {module: icub.subs[topic] for module, (_, topic, _) in WRENCHES.items()}
    streams["icub_tf_hands"] = icub.subs["/tf"]
    for module, sub in streams.items():
        wait_until(lambda: any(x.t > t1 + 0.1 for x in list(sub.messages)), 30, f"{module}: a message after the window")
    counted = {module: sum(1 for x in list(sub.messages) if t0 <= x.t < t1) for module, sub in streams.items()}
    after = {m: bridge_stats(t) for m, t in composed_stats(icub.server, "/icub/rpc:i").items()}
    skipped = {m: after[m]["published"][1] - before[m]["published"][1] for m in rated}
    short = any(abs(rate - RATES[m]) > 0.01 * RATES[m] for m, rate in rates.items()) or \
        any(abs(n - RATES[m] * window) > 0.01 * RATES[m] * window for m, n in counted.items())
    late = [round(x.t - t0, 3) for x in list(icub.subs["/icub/imu"].messages) if t0 + 1.0 + 0.3 < x.t < t1]
    published_traj = (after["icub_left_arm_trajectory"]["published"][0]
                      - before["icub_left_arm_trajectory"]["published"][0])
    return SimpleNamespace(t0=t0, t1=t1, window=window, cpu=cpu, waited=waited, load=os.getloadavg()[0], rates=rates,
                           counted=counted, skipped=skipped, short=short, late=late, sent=len(sent),
                           published_traj=published_traj, before=before, after=after)


class TestComposedIcub:
    """examples/icub_robot, 14 configs, one process (the shared fixture)."""

    def test_every_bridge_publishes_its_values(self, icub):
        """Joint names and radians of every part on /joint_states, the four
        wrenches, the IMU's quaternion, both hands on /tf, the camera's
        image and a MoveIt trajectory's rows into YARP: all through the one
        process."""
        t_start = time.time() - 60
        # every producer connected, every subscriber matched
        for p in icub.producers.values():
            p.wait_outputs(1)
        icub.subs["/joint_states"].wait_publishers(6)
        # joint states: one message of every part, exact radians
        joints = icub.subs["/joint_states"]
        def part_of(msg):
            return next((m for m in JOINTS if msg["name"] and msg["name"][0] == _first_name(icub.programs[m])),
                        None)

        seen = {}
        wait_until(lambda: len({part_of(x.msg) for x in joints.messages} - {None}) == len(JOINTS), 60,
                   "a joint state of every part")
        for x in list(joints.messages):
            part = part_of(x.msg)
            if part is not None and part not in seen:
                seen[part] = x.msg
        for module, msg in seen.items():
            program = icub.programs[module]
            width = _width(program)
            assert msg["name"] == _names(program), module
            assert len(msg["name"]) == width
            assert msg["position"] == [x * DEG + 0.0 for x in joint_values(module, width)], module
            assert msg["velocity"] == [] and msg["effort"] == []
            assert t_start < stamp(msg["header"]["stamp"]) < time.time() + 1, module  # the producer's envelope
        # the four wrenches
        for module, (_, topic, frame_id) in WRENCHES.items():
            (got, *_) = icub.subs[topic].wait_for(1)
            v = wrench_values(module)
            w = got.msg["wrench"]
            assert [w["force"][k] for k in "xyz"] == v[0:3], module
            assert [w["torque"][k] for k in "xyz"] == v[3:6], module
            assert got.msg["header"]["frame_id"] == frame_id
            assert t_start < stamp(got.msg["header"]["stamp"]) < time.time() + 1
        # the IMU: roll pitch yaw (deg) as a quaternion, angular velocity in rad/s
        (imu, *_) = icub.subs["/icub/imu"].wait_for(1)
        q = imu.msg["orientation"]
        want = geometry_reference.geometry("euler_to_quat", IMU_VALUES[0:3], "xyz", degrees=True)
        assert close([q["x"], q["y"], q["z"], q["w"]], want), (q, want)
        assert [imu.msg["linear_acceleration"][k] for k in "xyz"] == IMU_VALUES[3:6]
        assert [imu.msg["angular_velocity"][k] for k in "xyz"] == [x * DEG + 0.0 for x in IMU_VALUES[6:9]]
        assert imu.msg["header"]["frame_id"] == "head_imu_0"
        # both hands on /tf, from the root link
        (tf, *_) = icub.subs["/tf"].wait_for(1)
        transforms = {t["child_frame_id"]: t for t in tf.msg["transforms"]}
        assert sorted(transforms) == sorted(TF_VALUES)
        for child, values in TF_VALUES.items():
            t = transforms[child]
            assert t["header"]["frame_id"] == "root_link"
            assert [t["transform"]["translation"][k] for k in "xyz"] == values[0:3]
            r = t["transform"]["rotation"]
            assert close([r["x"], r["y"], r["z"], r["w"]],
                         geometry_reference.geometry("axis_angle_to_quat", values[3:7])), child
        # the left eye: one frame, every pixel
        f = frame(64, 48, "rgb8", seed=7)
        wait_until(lambda: icub.image.events_of("matched") and icub.image.events_of("matched")[-1]["n"] >= 1, 30,
                   "the image subscriber matched")
        mark = len(icub.image.events)
        icub.camera.send(**f)
        got = icub.image.wait_event("frame", since=mark, timeout=30)
        assert (got["width"], got["height"], got["pixel"], got["sha"]) == (64, 48, "rgb8", sha_of(f))
        assert got["frame_id"] == "l_eye"
        # a trajectory into YARP: a row per point, its time then its positions in degrees
        icub.planner.wait_matched(1)
        plan = trajectory(points=3, joints=7)
        bottle = plan_through(icub, plan)
        rows = [[stamp(p["time_from_start"])] + [x * RAD + 0.0 for x in p["positions"]] for p in plan["points"]]
        assert len(bottle.data) == len(rows), bottle.text
        for got_row, want_row in zip(bottle.data, rows):
            assert close(got_row, want_row), (got_row, want_row)

    def test_one_process_one_participant_a_node_per_bridge(self, icub):
        """Every bridge's node is on the graph with its own name; their
        /diagnostics writers all belong to one DDS participant (one GUID
        prefix); the module is one process."""
        nodes = sorted(icub.programs)
        seen = graph(icub.env, nodes)
        assert set(nodes) <= set(seen["nodes"]), seen["nodes"]
        prefixes = {gid[:24] for name, gid in seen["diagnostics"] if name in nodes}
        assert {name for name, _ in seen["diagnostics"]} >= set(nodes)
        assert len(prefixes) == 1, seen["diagnostics"]
        assert len(icub.node.tree()) == 1, icub.node.tree()
        # and each bridge's status on /diagnostics, under its node's name
        want = {f"{n}: output {icub.programs[n].output.name}" for n in nodes}
        diag = icub.subs["/diagnostics"]

        def named():
            return {s["name"] for x in list(diag.messages) for s in x.msg["status"]}
        wait_until(lambda: want <= named(), 30, "a /diagnostics status of every bridge")
        assert {s["hardware_id"] for x in list(diag.messages) for s in x.msg["status"]} >= set(nodes)

    def test_a_stall_or_malformed_bottles_delay_no_other_bridge(self, icub):
        """For 5 s: the IMU's producer SIGSTOPped, the subscriber of
        /joint_states SIGSTOPped (six bridges publish to it), the
        trajectory's YARP reader SIGSTOPped while trajectories come, and
        malformed Bottles into the torso (besides the every other one it
        always gets). Every other bridge keeps its rate within 1 % (the
        messages it published over the window, and those its subscriber
        counted where one bridge publishes to one), the IMU's publishes
        nothing once its input is stale, the torso counts the malformed
        Bottles as dropped, the trajectories go on into YARP.

        A machine whose cores are all taken (other processes) makes every
        bridge of the process miss cycles alike, at random; a stall that
        delayed the others would delay them in every window: a window short
        of 1 % is tried again, twice at most, and one must hold (unless, in
        every window, the process's threads waited for a CPU longer than
        they ran: then nothing can be said of its rates, and the test is
        skipped with the figures)."""
        for topic in ("/joint_states", "/icub/imu", "/tf", *[w[1] for w in WRENCHES.values()]):
            icub.subs[topic].wait_for(10)
        attempts = []
        for _ in range(3):
            w = stall_window(icub)
            attempts.append(w)
            if not w.short:
                break
        summary = "\n".join(f"window {w.window:.3f} s, CPU {w.cpu:.2f} s, waited for a CPU {w.waited:.2f} s, "
                            f"load {w.load:.1f}: rates {w.rates}; messages "
                            f"received {w.counted}; cycles skipped {w.skipped}" for w in attempts)
        print(summary)
        if w.short and all(a.waited > a.cpu for a in attempts):
            # its threads waited for a CPU longer than they ran, in every
            # window: the machine's other processes, not this process's bridges
            pytest.skip(f"the machine left the composed process too little CPU to hold 100 Hz:\n{summary}")
        assert not w.short, f"no window held every rate within 1 %:\n{summary}"
        # the stalled bridge: nothing after its input went stale (timeout 1 s), in every window
        for a in attempts:
            assert not a.late, f"the IMU published {len(a.late)} messages after its input went stale: {a.late[:5]}"
        imu = icub.subs["/icub/imu"]
        icub.node.wait_log("icub_imu: input /icub/inertial is stale", count=len(attempts))
        icub.node.wait_log("icub_imu: input /icub/inertial is fresh again", timeout=30, count=len(attempts))
        wait_until(lambda: any(x.t > w.t1 for x in list(imu.messages)), 30, "the IMU publishing again")
        # the subscriber that was stalled gets messages again
        wait_until(lambda: any(x.t > w.t1 for x in list(icub.subs["/joint_states"].messages)), 30,
                   "the stalled subscriber's messages")
        # the trajectories went on into YARP while their reader stalled (the
        # port drops what its busy connection cannot take), and reach it again
        assert w.sent > 50 and w.published_traj >= w.sent // 2, (w.sent, w.published_traj)
        wait_until(lambda: any(b.t > w.t1 for b in list(icub.player.bottles)), 30, "a trajectory after the stall")
        # the torso: the malformed Bottles dropped and counted, and its rate held (above)
        (received0, dropped0, *_), = w.before["icub_torso"]["inputs"].values()
        (received1, dropped1, *_), = w.after["icub_torso"]["inputs"].values()
        assert dropped1 - dropped0 >= 300 + (received1 - received0 - 300) // 2 - 5, (w.before, w.after)

    def test_stats_and_quit_on_the_rpc_port(self, icub):
        """`help`, `stats` (a list per bridge: its name then its own stats)
        and `quit` on /icub/rpc:i: every bridge stops, prints its totals
        under its name, the process exits 0 within 2 s; no bridge's own RPC
        port is open."""
        helped = rpc(icub.server, "/icub/rpc:i", "help")
        assert "stats: one list per bridge" in helped and "quit: stop every bridge" in helped
        stats = composed_stats(icub.server, "/icub/rpc:i")
        assert sorted(stats) == sorted(icub.programs), stats
        for module, text in stats.items():
            s = bridge_stats(text)
            sources = [i.name for m in icub.programs[module].muxes for i in m.inputs]
            assert sorted(s["inputs"]) == sorted(sources), text
            assert s["published"][0] > 0, text
            rate = RATES.get(module)
            assert s["rate"][1] == ("event-driven" if rate is None else repr(rate)), text
        ports = icub.server.yarp("name", "list").stdout
        assert "/icub/rpc:i" in ports
        assert not any(f"/{m}/rpc:i" in ports for m in icub.programs), ports
        t0 = time.monotonic()
        assert "[bye]" in rpc(icub.server, "/icub/rpc:i", "quit")
        rc = icub.node.popen.wait(10)
        took = time.monotonic() - t0
        log = icub.node.log_text()
        assert rc == 0, log[-3000:]
        assert took < 2.0, f"took {took:.2f} s to exit"
        assert "Traceback" not in log, log[-5000:]
        for module, program in icub.programs.items():
            totals = bridge_totals(log, module)
            assert totals.get("published", 0) > 0, (module, log[-3000:])
            for mux in program.muxes:
                for i in mux.inputs:
                    assert i.name in totals, (module, i.name)
        torso = bridge_totals(log, "icub_torso")["/icub/torso/state:o"]
        assert torso[1] >= 300, torso  # dropped: the burst and every other Bottle
        assert bridge_totals(log, "icub_head")["/icub/head/state:o"][1] == 0
        assert "/icub/rpc:i" not in icub.server.yarp("name", "list").stdout


def _names(program) -> list[str]:
    field = next(f for f in program.message.fields if f.name == "name")
    return list(field.source.values)


def _cpu_seconds(pid: int) -> float:
    """The CPU time (user and system) process ``pid`` has used."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _run_delay(pid: int) -> float:
    """The seconds the threads of process ``pid`` have waited, runnable, for
    a CPU (their schedstat), summed."""
    total = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            total += int((task / "schedstat").read_text().split()[1])
        except (OSError, IndexError, ValueError):
            pass
    return total / 1e9


def _width(program) -> int:
    return sum(g.count for g in program.muxes[0].inputs[0].layout)


def _first_name(program) -> str:
    return _names(program)[0]


# --------------------------------------------------------------------------
# ros2 --package: one ament_python package, one executable


def test_ros2_package_one_executable_parameters_by_node_name(tmp_path):
    """`ybgc compose --backend ros2 --package`: one ament_python package with
    one executable, the bridges' nodes a subpackage, the runtime inside; its
    launch file starts the one executable with the parameter file keyed by
    node name, and run with that file each node takes its own values."""
    import yaml

    out = tmp_path / "duo"
    configs = [ICUB / "head.ini", ICUB / "torso.ini"]
    r = ybgc("compose", *configs, "--backend", "ros2", "--name", "duo", "--package", "-o", out)
    assert r.returncode == 0, r.stdout + r.stderr
    files = {str(p.relative_to(out)) for p in out.rglob("*") if p.is_file() and "ybgc_runtime" not in p.parts}
    assert files == {"package.xml", "setup.py", "setup.cfg", "resource/duo", "launch/duo.launch.py",
                     "config/duo.yaml", "duo/__init__.py", "duo/duo_node.py", "duo/bridges/__init__.py",
                     "duo/bridges/icub_head_node.py", "duo/bridges/icub_torso_node.py"}, files
    assert (out / "duo" / "ybgc_runtime" / "compose.py").exists()
    setup = (out / "setup.py").read_text()
    assert "'duo_node = duo.duo_node:main'" in setup and setup.count("= duo.") == 1
    assert "package_name + '.bridges'" in setup and "'config/duo.yaml'" in setup
    assert "from .. import ybgc_runtime" in (out / "duo" / "bridges" / "icub_head_node.py").read_text()
    depends = re.findall(r"<exec_depend>(\S+)</exec_depend>", (out / "package.xml").read_text())
    assert {"rclpy", "diagnostic_msgs", "sensor_msgs"} <= set(depends)
    params = yaml.safe_load((out / "config" / "duo.yaml").read_text())
    assert params == {node: {"ros__parameters": {"rate": 100.0, "timeout": 0.0, "prefix": "/" + node,
                                                 "verbose": False, "diagnostics": True}}
                      for node in ("icub_head", "icub_torso")}
    launch = ast.parse((out / "launch" / "duo.launch.py").read_text())
    consts = {t.id: ast.literal_eval(n.value) for n in launch.body if isinstance(n, ast.Assign)
              for t in n.targets}
    assert consts == {"PACKAGE": "duo", "EXECUTABLE": "duo_node", "PARAMS_FILE": "duo.yaml",
                      "NODES": ("icub_head", "icub_torso")}
    assert "name=" not in (out / "launch" / "duo.launch.py").read_text().split("Node(", 1)[1].split(")")[0]
    # the executable, as `ros2 run` starts it, with a parameter file of other values
    params["icub_head"]["ros__parameters"]["rate"] = 25.0
    params["icub_torso"]["ros__parameters"]["prefix"] = "/torso_elsewhere"
    mine = tmp_path / "mine.yaml"
    mine.write_text(yaml.safe_dump(params))
    with Ros2Domain() as domain, YarpServer(install=yarp_install("3.5")) as server:
        env = ros2_environment(server.env, domain)
        node = Proc([VENV_PYTHON, "-c", "import sys; from duo.duo_node import main; sys.exit(main())",
                     "--ros-args", "--params-file", mine], env=env, cwd=out, name="duo_node")
        node.start()
        try:
            wait_until(lambda: "duo: 2 bridges running" in node.log_text(), 60, "the bridges", node)
            stats = composed_stats(server, "/duo/rpc:i")
            assert bridge_stats(stats["icub_head"])["rate"][1] == "25.0", stats
            assert bridge_stats(stats["icub_torso"])["rate"][1] == "100.0", stats
            ports = server.yarp("name", "list").stdout
            assert "/torso_elsewhere/joints/in0:i" in ports and "/icub_head/joints/in0:i" in ports, ports
            assert "[bye]" in rpc(server, "/duo/rpc:i", "quit")
            assert node.popen.wait(10) == 0, node.log_text()[-3000:]
        finally:
            node.stop()


# --------------------------------------------------------------------------
# ros2: configs of commands among the bridges


def test_ros2_commands_among_the_bridges(tmp_path):
    """Two configs of commands composed with a stream config: a ROS 2 service
    served by calling a YARP RPC port (home_arm_trigger.ini), and a YARP RPC
    port served by calling a ROS 2 service (yarp_rpc_to_ros2.ini, the port
    named like the module's own RPC port): each call answered in the one
    process, its counts in the process's `stats` and in its totals under its
    name; the commands' own `stats`/`quit` are the process's, not the port's."""
    from harness.services import RpcClient, RpcServer, ServiceClient, ServiceServer, reply, require_services

    require_services()
    out = tmp_path / "mix"
    configs = [ICUB / "head.ini", EXAMPLES / "home_arm_trigger.ini", EXAMPLES / "yarp_rpc_to_ros2.ini"]
    r = ybgc("compose", *configs, "--backend", "ros2", "--name", "mix", "-o", out)
    assert r.returncode == 0, r.stdout + r.stderr
    assert {p.name for p in (out / "bridges").iterdir()} == {"icub_head_node.py", "left_arm_homing_node.py",
                                                             "robot_gate_node.py"}
    with Ros2Domain() as domain, YarpServer(install=yarp_install("3.5")) as server:
        env = ros2_environment(server.env, domain)
        homing = RpcServer(env, "/icub/left_arm/homing/rpc:i", [reply("home", "ok")])
        robot = ServiceServer(env, {"/robot/home": {"type": "std_srvs/srv/Trigger",
                                                    "response": {"success": True, "message": "homed"}}})
        caller = ServiceClient(env, {"/icub/left_arm/home": "std_srvs/srv/Trigger"})
        gate = RpcClient(env, "/robot_gate/rpc:i")
        peers = [homing, robot, caller]
        try:
            run_parallel(*(p.start for p in peers))
            node = Node(env, out / "mix_node.py")
            node.start()
            node.wait_log("mix: 3 bridges running")
            caller.wait_service("/icub/left_arm/home")
            got = caller.call("/icub/left_arm/home")
            assert got.response == {"success": True, "message": "ok"}, got
            assert homing.wait_commands(1)[-1]["data"] == ["home", "all"]
            gate.start()
            peers.append(gate)
            gate.connect()
            answer = gate.call(["home"])
            assert answer.ok and "homed" in answer.text, answer
            stats = composed_stats(server, "/mix/rpc:i")
            assert sorted(stats) == ["icub_head", "left_arm_homing", "robot_gate"], stats
            assert stats["left_arm_homing"] == "(service home calls 1 answered 1 failed 0 timed_out 0 no_server 0 " \
                                               "unfit 0)", stats
            assert "(service home calls 1 answered 1 failed 0" in stats["robot_gate"], stats
            assert "(service track calls 0" in stats["robot_gate"], stats
            assert "quit" not in gate.call(["help"]).text  # the port's own commands, not the process's
            assert "[bye]" in rpc(server, "/mix/rpc:i", "quit")
            assert node.popen.wait(10) == 0, node.log_text()[-3000:]
            log = node.log_text()
            assert "Traceback" not in log
            assert re.search(r"^left_arm_homing: service home: calls 1, answered 1, failed 0", log, re.M), log[-2000:]
            assert re.search(r"^robot_gate: service home: calls 1, answered 1, failed 0", log, re.M), log[-2000:]
            assert re.search(r"^icub_head:   published 0 messages", log, re.M)
        finally:
            for p in peers:
                p.stop()


# --------------------------------------------------------------------------
# py: YARP bridges in one process

PY_CONFIGS = {
    "pa": "[output]\nport = /pa/out:o\nrate = 50\n\n[mux m]\nports = /src/a:o (float64 x3)\n"
          "convert = deg_to_rad\n\n[message]\nv = m\n",
    "pb": "[output]\nport = /pb/out:o\n\n[mux m]\nports = /src/b:o\n\n[message]\nn = counter\nv = m\n",
    "pc": "[output]\nport = /pc/out:o\nrate = 20\n\n[mux m]\nports = /src/c:o (int32 x2)\n\n[message]\nv = m\n",
    "pd": "[output]\nport = /pd/out:o\n\n[mux m]\nports = /src/d:o\n\n[message]\nv = m\n",
}


def test_py_bridges_in_one_process(tmp_path):
    """Four YARP-output configs composed by the py backend: one process
    whose bridges publish their values (one at a fixed rate, one
    event-driven fed a malformed Bottle too), while the third cannot start
    (its output port is taken) and the fourth's module does not load (it
    imports a package that is not installed): each said with its config,
    listed as not running in `stats`; `quit` stops the others, each printing
    its totals, and the process exits 1 within 2 s."""
    for name, text in PY_CONFIGS.items():
        (tmp_path / f"{name}.ini").write_text(text)
    out = tmp_path / "trio"
    r = ybgc("compose", *(tmp_path / f"{n}.ini" for n in PY_CONFIGS), "--backend", "py", "--name", "trio",
             "-o", out)
    assert r.returncode == 0, r.stdout + r.stderr
    assert {p.name for p in (out / "bridges").iterdir()} == {"pa.py", "pb.py", "pc.py", "pd.py"}
    module = out / "bridges" / "pd.py"
    module.write_text("import ybg_missing_msgs  # a package not installed\n" + module.read_text())
    app = (out / "trio.xml").read_text()
    assert "<parameters>trio.py</parameters>" in app
    assert all(f"<from>/src/{k}:o</from>" in app and f"<to>/p{k}/m/in0:i</to>" in app for k in "abc"), app
    with YarpServer(install=yarp_install("3.5")) as server:
        env = server.env
        ra, rb = YarpReader(env, "/r/a", source="/pa/out:o"), YarpReader(env, "/r/b", source="/pb/out:o")
        taken = YarpProducer(env, "/pc/out:o")
        pa = YarpProducer(env, "/src/a:o", bottles=[[90.0, 180.0, -45.0]], rate=PRODUCER_HZ)
        pb = YarpProducer(env, "/src/b:o")
        peers = [ra, rb, taken, pa, pb]
        try:
            run_parallel(*(p.start for p in peers))
            node = Node(env, out / "trio.py")
            node.start()
            node.wait_log("trio: 2 bridges running; not running: pc, pd")
            node.wait_log("trio: bridge pd (pd.ini:2:1) cannot start: cannot load its module bridges/pd.py "
                          "(ModuleNotFoundError: No module named 'ybg_missing_msgs'); the other bridges run")
            log = node.wait_log("trio: bridge pc (pc.ini:2:1) cannot start: cannot open the output /pc/out:o; "
                                "the other bridges run")
            (a, *_) = ra.wait_for(3)
            assert a.data == [90.0 * DEG + 0.0, 180.0 * DEG + 0.0, -45.0 * DEG + 0.0], a.data
            pb.wait_outputs(1)
            rb.wait_connected()
            pb.write([1, 2.5, -3])
            pb.write(["not a number"])
            pb.write([4, 5.5, 6])
            b = rb.wait_for(2)
            assert [x.data for x in b] == [[0, 1, 2.5, -3], [1, 4, 5.5, 6]], [x.data for x in b]
            stats = composed_stats(server, "/trio/rpc:i")
            assert stats["pc"] == '"not running" "cannot open the output /pc/out:o"', stats
            assert stats["pd"].startswith('"not running" "cannot load its module bridges/pd.py'), stats
            assert bridge_stats(stats["pb"])["inputs"] == {"/src/b:o": (3, 1, 0, 0, 0)}, stats
            assert bridge_stats(stats["pa"])["rate"][1] == "50.0"
            assert not server.exists("/pa/rpc:i") and not server.exists("/pb/rpc:i")
            t0 = time.monotonic()
            assert "[bye]" in rpc(server, "/trio/rpc:i", "quit")
            rc = node.popen.wait(10)
            took = time.monotonic() - t0
            log = node.log_text()
            assert rc == 1 and took < 2.0, (rc, took, log[-3000:])
            assert "Traceback" not in log
            assert bridge_totals(log, "pb") == {"/src/b:o": (3, 1, 0, 0), "published": 2}, log[-2000:]
            assert bridge_totals(log, "pa")["published"] > 0
            assert "pc: not started (cannot open the output /pc/out:o)" in log
            assert "pd: not started (cannot load its module" in log
            assert not server.exists("/trio/rpc:i") and not server.exists("/pa/out:o")
        finally:
            for p in peers:
                p.stop()
