"""The iCub of examples/icub_robot composed and run end to end, as every
backend's compose test runs it (tests/test_compose_py.py, ros2;
tests/test_compose_cpp.py, cpp): its 14 configs, the values each producer
sends and each bridge must publish, the peers (a real YARP producer on every
input port, real rclpy subscribers on every topic, the camera, the
trajectory's planner and YARP reader), and the checks, each taking the
running process and its peers (``icub``: .env, .server, .node (the composed
process, a Module), .programs (its stream bridges), .producers, .camera,
.subs, .image, .planner, .player; and, when the process has bridges of
commands too, .commands (module -> ir.Commands) and .feed_commands(), which
makes a call of each of their services through the process):

    start_peers(env, programs) -> peers
    check_values(icub)          every bridge's values, through the one process
    check_one_process(icub)     one process, one DDS participant, a node per bridge, /diagnostics
    check_isolation(icub)       a stalled producer, stalled consumers and malformed Bottles delay no
                                other bridge (rates within 1 %: stall_window, tried again at most
                                twice on a machine whose cores are all taken), the stalled one
                                publishes nothing stale
    check_stats_and_quit(icub)  `help`, `stats` and `quit` on /icub/rpc:i, exit 0 after its `[bye]`
                                (EXIT_BOUND), the totals at least the stats; it feeds every bridge
                                itself (each check stands alone, whatever ran before it)

and what they read: composed_stats(server, port), bridge_stats(text),
wait_bridges(server, port, pred), feed_the_bridges_on_command(icub),
bridge_totals(log, module), published(diagnostics, program), slope(points),
graph(env, nodes), plan_through(icub, plan), frame_through(icub, frame),
cpu_seconds(pid), run_delay(pid).
"""
from __future__ import annotations

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

from harness import geometry_reference
from harness.env import EXAMPLES, VENV_PYTHON
from harness.images import ImagePeer, frame, sha_of
from harness.module import EXIT_BOUND, quit_over_rpc
from harness.procs import wait_until
from harness.ros2 import Ros2Publisher, Ros2Subscriber, subscriber_for
from harness.yarp import YarpProducer, YarpReader, rpc

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
    stale, unused, refused)}, published (n, skipped, failures, missed), rate."""
    inputs = {m[0]: tuple(map(int, m[1:])) for m in re.findall(
        r'\(input "?([^"\s]+)"? received (\d+) dropped (\d+) stale (\d+) unused (\d+) refused (\d+)\)', text)}
    published = re.search(r"\(published (\d+) skipped (\d+) failures (\d+) missed (\d+)\)", text)
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


def start_peers(env: dict, programs: dict) -> SimpleNamespace:
    """A producer on every input port of the iCub (the torso's alternating
    with a malformed Bottle, at twice the rate), the camera, a subscriber of
    every topic (with the QoS each bridge offers) and of /diagnostics, an
    image subscriber, the trajectory's planner and its YARP reader: started
    at once. ``.peers``: every one, to stop."""
    producers = {}
    for module, port in JOINTS.items():
        good = joint_values(module, joint_width(programs[module]))
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
    try:
        run_parallel(*(p.start for p in peers))
    except BaseException:
        for p in peers:
            p.stop()
        raise
    return SimpleNamespace(producers=producers, camera=camera, subs=subs, image=image, planner=planner,
                           player=player, peers=peers)


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


def frame_through(icub, f: dict) -> dict:
    """Send frame ``f`` from the camera until the image subscriber gets it
    (the camera's connection to the bridge's port is made by the bridge's
    watcher, within 0.5 s of its start: a frame sent before it is lost); the
    subscriber's event."""
    for _ in range(15):
        mark = len(icub.image.events)
        icub.camera.send(**f)
        try:
            return icub.image.wait_event("frame", since=mark, timeout=2.0)
        except TimeoutError:
            continue
    raise AssertionError("no frame through the left eye's bridge")


def joint_names(program) -> list[str]:
    field = next(f for f in program.message.fields if f.name == "name")
    return list(field.source.values)


def cpu_seconds(pid: int) -> float:
    """The CPU time (user and system) process ``pid`` has used."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def joint_width(program) -> int:
    return sum(g.count for g in program.muxes[0].inputs[0].layout)


def first_joint_name(program) -> str:
    return joint_names(program)[0]


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
    cpu0, waited0 = cpu_seconds(icub.node.pid), run_delay(icub.node.pid)
    t0 = time.time()
    for proc in stalled:
        os.kill(proc.pid, signal.SIGSTOP)
    try:
        planning.start()
        icub.producers["icub_torso"].burst([["bad"]] * 300)
        time.sleep(max(0.0, STALL - (time.time() - t0)))
    finally:
        t1 = time.time()
        cpu, waited = cpu_seconds(icub.node.pid) - cpu0, run_delay(icub.node.pid) - waited0
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
    rates, samples = {}, {}
    for module in rated:
        inside = [(t, n) for t, n in published(diagnostics, icub.programs[module]) if t0 <= t <= t1]
        # at least half the statuses of the window's whole periods (a window
        # of 5.0001 s has 10 periods, not 10.0002: half of them is 5)
        assert len(inside) >= 0.5 * int(window / DIAGNOSTICS_PERIOD), (module, inside)
        rates[module] = round(slope(inside), 2)
        samples[module] = inside
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
                           samples=samples, counted=counted, skipped=skipped, short=short, late=late, sent=len(sent),
                           published_traj=published_traj, before=before, after=after)


def longest_without_progress(points: list[tuple[float, int]]) -> float:
    """The longest span of time between two statuses of a bridge, (stamp,
    messages published), with no message published in between."""
    longest, since = 0.0, None
    for (a, m), (b, n) in zip(points, points[1:]):
        if n <= m:
            since = a if since is None else since
            longest = max(longest, b - since)
        else:
            since = None
    return longest


def run_delay(pid: int) -> float:
    """The seconds the threads of process ``pid`` have waited, runnable, for
    a CPU (their schedstat), summed."""
    total = 0
    for task in Path(f"/proc/{pid}/task").iterdir():
        try:
            total += int((task / "schedstat").read_text().split()[1])
        except (OSError, IndexError, ValueError):
            pass
    return total / 1e9


# --------------------------------------------------------------------------
# the checks


def check_values(icub):
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
        return next((m for m in JOINTS if msg["name"] and msg["name"][0] == first_joint_name(icub.programs[m])),
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
        width = joint_width(program)
        assert msg["name"] == joint_names(program), module
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
    got = frame_through(icub, f)
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


def check_one_process(icub):
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


def check_isolation(icub):
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
    of 1 % is tried again, twice at most, and one must hold. Unless, in
    every window, the process's threads waited for a CPU longer than
    they ran: then its rates are the machine's, and what is asserted is
    what a stall would break whatever the load: no other bridge went 2 s
    of the window without publishing (told by its statuses on
    /diagnostics, every 0.5 s, from the same process), where one held up
    by a stalled peer would publish nothing for the stall's 5 s."""
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
        print("the machine left the composed process too little CPU to hold 100 Hz: each bridge's progress "
              "from status to status is asserted instead of its rate")
        for module, points in w.samples.items():
            held = longest_without_progress(points)
            assert held < 0.4 * STALL, (f"{module} published nothing for {held:.2f} s of the {STALL} s stall "
                                        f"(its statuses: {points})\n{summary}")
    else:
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


def wait_bridges(server, port: str, pred, timeout: float = 60.0, only=None) -> dict:
    """The first `stats` of a composed module whose bridges (those named in
    ``only``, else all) all satisfy ``pred`` (their bridge_stats()):
    {bridge: bridge_stats}."""
    end = time.monotonic() + timeout
    while True:
        got = {m: bridge_stats(t) for m, t in composed_stats(server, port).items() if only is None or m in only}
        if got and all(pred(s) for s in got.values()):
            return got
        if time.monotonic() > end:
            raise AssertionError(f"stats never matched in {timeout} s: {got}")
        time.sleep(0.2)


def feed_the_bridges_on_command(icub) -> None:
    """The two bridges that only the test feeds: a frame through the left
    eye, a trajectory into YARP (the others have their producers streaming
    from the fixture on)."""
    wait_until(lambda: icub.image.events_of("matched") and icub.image.events_of("matched")[-1]["n"] >= 1, 30,
               "the image subscriber matched")
    frame_through(icub, frame(32, 24, "rgb8", seed=9))
    plan_through(icub, trajectory(points=2, joints=7))


#: a service's list of `stats`, as `yarp rpc` prints it
SERVICE_STATS = re.compile(r'\(service "?([^"\s]+)"? calls (\d+) answered (\d+) failed (\d+) timed_out (\d+) '
                           r'no_server (\d+) unfit (\d+)\)')


def service_totals(log: str, module: str) -> dict:
    """The totals of a bridge of commands printed at exit, under its name:
    {service: (calls, answered, failed)}."""
    return {m.group(1): tuple(int(x) for x in m.groups()[1:]) for m in re.finditer(
        rf"^{module}: service (\S+): calls (\d+), answered (\d+), failed (\d+) ", log, re.M)}


def check_stats_and_quit(icub):
    """`help`, `stats` (a list per bridge: its name then its own stats)
    and `quit` on /icub/rpc:i: every bridge stops and prints its totals
    under its name, which hold at least what its `stats` said; the process
    exits 0 (timed from the `[bye]` reply: EXIT_BOUND); no bridge's own RPC
    port is open. It feeds every bridge itself, whatever ran before it
    (a bridge of commands: a call of each service, its list of each)."""
    commands = getattr(icub, "commands", {})
    feed_the_bridges_on_command(icub)
    if commands:
        icub.feed_commands()
    helped = rpc(icub.server, "/icub/rpc:i", "help")
    assert "stats: one list per bridge" in helped and "quit: stop every bridge" in helped
    # every bridge has published (the streaming ones, once their producers are connected)
    stats = wait_bridges(icub.server, "/icub/rpc:i", lambda s: s["published"] and s["published"][0] > 0,
                         only=icub.programs)
    assert sorted(stats) == sorted(icub.programs), stats
    texts = composed_stats(icub.server, "/icub/rpc:i")
    assert sorted(texts) == sorted([*icub.programs, *commands]), texts
    listed = {}
    for module, program in commands.items():
        listed[module] = {m[0]: tuple(map(int, m[1:])) for m in SERVICE_STATS.findall(texts[module])}
        assert sorted(listed[module]) == sorted(s.name for s in program.services), texts[module]
        assert all(n[0] >= 1 and n[0] == n[1] + n[2] for n in listed[module].values()), texts[module]
    for module, s in stats.items():
        sources = [i.name for m in icub.programs[module].muxes for i in m.inputs]
        assert sorted(s["inputs"]) == sorted(sources), (module, s)
        rate = RATES.get(module)
        assert s["rate"][1] == ("event-driven" if rate is None else repr(rate)), (module, s)
    # the torso's producer sends a malformed Bottle every other one, the head's none
    assert stats["icub_torso"]["inputs"]["/icub/torso/state:o"][1] > 0, stats["icub_torso"]
    assert stats["icub_head"]["inputs"]["/icub/head/state:o"][1] == 0, stats["icub_head"]
    ports = icub.server.yarp("name", "list").stdout
    assert "/icub/rpc:i" in ports
    assert not any(f"/{m}/rpc:i" in ports for m in [*icub.programs, *commands]), ports
    rc, took = quit_over_rpc(icub.env, icub.node, "/icub/rpc:i")
    log = icub.node.log_text()
    assert rc == 0, log[-3000:]
    assert took < EXIT_BOUND, f"took {took:.2f} s to exit after its [bye]"
    assert "Traceback" not in log, log[-5000:]
    for module, program in icub.programs.items():
        totals = bridge_totals(log, module)
        assert totals.get("published", 0) >= stats[module]["published"][0], (module, stats[module], log[-3000:])
        for mux in program.muxes:
            for i in mux.inputs:
                assert i.name in totals, (module, i.name)
                # received and dropped: the totals count on from `stats`
                got, said = totals[i.name], stats[module]["inputs"][i.name]
                assert got[0] >= said[0] and got[1] >= said[1], (module, i.name, got, said)
    assert bridge_totals(log, "icub_head")["/icub/head/state:o"][1] == 0
    for module in commands:
        totals = service_totals(log, module)
        assert sorted(totals) == sorted(listed[module]), (module, log[-3000:])
        for name, (calls, answered, failed) in totals.items():
            assert calls >= listed[module][name][0] and calls == answered + failed, (module, name, totals)
    assert "/icub/rpc:i" not in icub.server.yarp("name", "list").stdout
