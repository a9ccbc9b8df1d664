"""Actions end to end (docs/actions.md): a FollowJointTrajectory served by
the ros2 backend's node from a simulated YARP controlboard written here
(tests/peers/sim_arm.py: set points on a port, each joint moving toward its
own at a bounded speed, encoders at 100 Hz), goals sent by a real rclpy
ActionClient (tests/peers/action_client.py), on YARP 3.5 and Kilted.

Each of control_msgs' result codes comes from a scenario that causes it;
the joints reach a goal within its tolerance, the joints a goal does not
name stay where they were; a refused goal moves nothing; cancel holds the
joints; a newer goal preempts the one under way; encoders gone quiet abort.
One rig (name server, domain, arm, node, client) serves every scenario;
one goal each on YARP 3.12.3 and 4.0.0, and on ROS 2 Jazzy.
"""
from __future__ import annotations

import contextlib
import json
import math
import subprocess
import textwrap
import time

import pytest

from harness.env import yarp_install
from harness.generated import YBGC
from harness.jazzy import JAZZY_PYTHON, NODE_YARP, jazzy_env, require_jazzy
from harness.module import Module, Node
from harness.procs import Peer
from harness.ros2 import Ros2Domain, Ros2Subscriber, ros2_environment
from harness.yarp import YarpServer, require_yarp

JOINTS = ["j0", "j1", "j2", "j3"]
START = [10.0, -20.0, 30.0, 5.0]  # degrees
SPEED = 90.0                       # degrees a second, each joint at most
PATH_TOL = 0.2                     # radians
GOAL_TOL = 0.01
STATUS = {"succeeded": 4, "canceled": 5, "aborted": 6}

CONFIG = f"""
[module]
name = simarm_trajectory

[action follow]
serve = /simarm_controller/follow_joint_trajectory (control_msgs/FollowJointTrajectory)
joints = "j0", "j1", "j2", "j3"
state = /simarm/state:o (float64 x6)
convert = deg_to_rad
command = /simarm/setpoints:i
rate = 100
feedback_rate = 20
path_tolerance = {PATH_TOL}
goal_tolerance = {GOAL_TOL}
goal_time_tolerance = 1.0
stale = 0.3
"""


class SimArm(Peer):
    script = "sim_arm.py"


class ActionClient(Peer):
    script = "action_client.py"


class JazzyActionClient(ActionClient):
    python = str(JAZZY_PYTHON)


@contextlib.contextmanager
def running(install, tmp, jazzy=False):
    """The name server of ``install``, a ROS 2 domain, the simulated arm and
    the generated node on that release's bindings, and the client: ready;
    with ``jazzy``, the node and the client on ROS 2 Jazzy's Python."""
    require_yarp(install)
    (tmp / "simarm.ini").write_text(textwrap.dedent(CONFIG))
    r = subprocess.run([str(YBGC), str(tmp / "simarm.ini"), "--backend", "ros2", "-o", str(tmp / "node")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stdout + r.stderr
    with YarpServer(install=install) as server, Ros2Domain() as domain:
        env = ros2_environment(server.env, domain)
        arm = SimArm(env, {"prefix": "/simarm", "joints": 4, "start": START, "speed": SPEED, "rate": 100,
                           "extra": 2})
        path = tmp / "node" / "simarm_trajectory_node.py"
        if jazzy:
            node = Module([JAZZY_PYTHON, path], env=jazzy_env(env), name="simarm_trajectory_node")
            client = JazzyActionClient(jazzy_env(env), {"action": "/simarm_controller/follow_joint_trajectory"})
        else:
            node = Node(env, path)
            client = ActionClient(env, {"action": "/simarm_controller/follow_joint_trajectory"})
        try:
            arm.start()
            node.start()
            node.wait_log("/simarm/state:o: encoder values coming, 4 joints", timeout=60)
            client.start()
            yield arm, node, client
        finally:
            for p in (client, node, arm):
                p.stop()


@pytest.fixture(scope="module")
def rig(tmp_path_factory):
    with running(yarp_install("3.5"), tmp_path_factory.mktemp("actions")) as parts:
        yield parts


def state(arm) -> dict:
    n = len(arm.events)
    arm.send(cmd="state")
    return arm.wait_event("state", since=n, timeout=30)


def where(arm) -> tuple[list[float], int]:
    """The arm's joints now (degrees) and the set points it has received."""
    e = state(arm)
    return e["positions"], e["received"]


def settled(arm, timeout=30.0) -> tuple[list[float], int]:
    """The arm's joints once they stopped moving (alike before and after a
    step of the arm), and the set points it has received then."""
    end = time.monotonic() + timeout
    last = state(arm)
    while time.monotonic() < end:
        now = state(arm)
        if now["ticks"] == last["ticks"]:
            continue  # no step between the two: wait for one
        if now["positions"] == last["positions"]:
            return now["positions"], now["received"]
        last = now
    raise AssertionError(f"the arm did not come to rest within {timeout} s: {last}")


_ids = iter(range(10**6))


def send(client, joints, points, **kw) -> str:
    gid = f"g{next(_ids)}"
    client.send(cmd="goal", id=gid, joints=joints, points=points, **kw)
    return gid


def result(client, gid, timeout=60.0) -> dict:
    return client.wait_event("result", lambda e: e["id"] == gid, timeout=timeout)


def feedback(client, gid) -> list[dict]:
    with client._cond:
        return [e for e in client.events if e["ev"] == "feedback" and e["id"] == gid]


def rad(degrees):
    return [math.radians(d) for d in degrees]


def test_the_joints_reach_the_goal_and_feedback_is_true_to_the_encoders(rig):
    arm, node, client = rig
    here, _ = settled(arm)  # at rest: what a scenario before it commanded is done
    target = [here[0] + 20, here[1] - 15, here[2] + 10, here[3] + 25]
    mid = [(a + b) / 2 for a, b in zip(here, target)]
    gid = send(client, JOINTS, [{"positions": rad(mid), "time": 0.5}, {"positions": rad(target), "time": 1.0}])
    r = result(client, gid)
    assert (r["status"], r["error_code"]) == (STATUS["succeeded"], 0), r
    now, _ = where(arm)
    assert rad(now) == pytest.approx(rad(target), abs=GOAL_TOL)
    fb = feedback(client, gid)
    assert fb, "no feedback"
    for f in fb:
        assert f["joint_names"] == JOINTS
        assert f["error"] == pytest.approx([a - d for a, d in zip(f["actual"], f["desired"])], abs=1e-12)
        assert all(abs(e) <= PATH_TOL for e in f["error"])  # else the goal would have aborted
    # the last feedback: where the encoders said the joints were, at the goal
    assert fb[-1]["actual"] == pytest.approx(rad(target), abs=GOAL_TOL)
    # never more often than feedback_rate (20 a second), but for the last one
    span = fb[-1]["t"] - fb[0]["t"]
    assert len(fb) <= span * 20 + 2


def test_a_subset_of_joints_in_another_order_and_the_others_stay(rig):
    arm, node, client = rig
    here, _ = settled(arm)  # at rest: what a scenario before it commanded is done
    gid = send(client, ["j2", "j0"], [{"positions": rad([here[2] - 12, here[0] + 7]), "time": 0.6}])
    r = result(client, gid)
    assert (r["status"], r["error_code"]) == (STATUS["succeeded"], 0), r
    now, _ = where(arm)
    assert rad([now[2], now[0]]) == pytest.approx(rad([here[2] - 12, here[0] + 7]), abs=GOAL_TOL)
    assert now[1] == pytest.approx(here[1], abs=1e-9) and now[3] == pytest.approx(here[3], abs=1e-9)


@pytest.mark.parametrize("joints, points, kw, code, says", [
    (["j0", "wrist"], [{"positions": [0.1, 0.2], "time": 1.0}], {}, -2, "'wrist' not driven"),
    (["j0"], [{"positions": [0.1], "time": 1.0}, {"positions": [0.2], "time": 0.5}], {}, -1, "is not after"),
    (["j0", "j1"], [{"positions": [0.1], "time": 1.0}], {}, -1, "1 positions for 2 joints"),
    (["j0"], [{"positions": [0.1], "time": 1.0}], {"stamp_offset": -10.0}, -3, "ended"),
    (["j0"], [{"positions": [0.1], "time": 1.0}], {"path_tolerance": [["j0", -0.5, 0, 0]]}, -1, "path_tolerance"),
])
def test_a_refused_goal_says_why_and_moves_nothing(rig, joints, points, kw, code, says):
    arm, node, client = rig
    here, received = settled(arm)
    gid = send(client, joints, points, **kw)
    r = result(client, gid)
    assert (r["status"], r["error_code"]) == (STATUS["aborted"], code), r
    assert says in r["error_string"], r
    now, after = where(arm)
    assert after == received and now == here  # not one set point written


def test_a_joint_held_back_violates_the_path_tolerance(rig):
    arm, node, client = rig
    here, _ = settled(arm)  # at rest: what a scenario before it commanded is done
    arm.send(cmd="hold", joint=1)
    try:
        gid = send(client, JOINTS, [{"positions": rad([here[0], here[1] + 40, here[2], here[3]]), "time": 1.0}])
        r = result(client, gid)
        assert (r["status"], r["error_code"]) == (STATUS["aborted"], -4), r
        assert "j1: position error" in r["error_string"] and "path tolerance 0.2" in r["error_string"], r
        # the goal given no path tolerance for j1 (-1 erases the default): it ends, out of the goal tolerance
        gid = send(client, JOINTS, [{"positions": rad([here[0], here[1] + 40, here[2], here[3]]), "time": 0.5}],
                   path_tolerance=[["j1", -1, 0, 0]], goal_time_tolerance=0.2)
        r = result(client, gid)
        assert (r["status"], r["error_code"]) == (STATUS["aborted"], -5), r
        assert "j1: position error" in r["error_string"] and "goal tolerance 0.01" in r["error_string"], r
    finally:
        arm.send(cmd="release", joint=1)


def test_cancel_holds_the_joints_where_they_are(rig):
    arm, node, client = rig
    here, _ = settled(arm)  # at rest: what a scenario before it commanded is done
    gid = send(client, JOINTS, [{"positions": rad([here[0] + 60, here[1], here[2], here[3]]), "time": 3.0}])
    client.wait_event("feedback", lambda e: e["id"] == gid and e["actual"][0] > math.radians(here[0] + 3))
    client.send(cmd="cancel", id=gid)
    r = result(client, gid)
    assert r["status"] == STATUS["canceled"], r
    held, received = settled(arm)
    # held where the encoders said the joints were when the cancel came: the
    # last feedback's, give or take what the arm moves in a feedback period
    last = feedback(client, gid)[-1]
    assert math.radians(held[0]) == pytest.approx(last["actual"][0], abs=math.radians(SPEED / 20))
    assert here[0] + 3 < held[0] < here[0] + 60
    assert held[1:] == pytest.approx(here[1:], abs=1e-9)
    # and nothing sent after the hold
    assert where(arm) == (held, received)


def test_a_newer_goal_preempts_the_one_under_way(rig):
    arm, node, client = rig
    here, _ = settled(arm)  # at rest: what a scenario before it commanded is done
    first = send(client, JOINTS, [{"positions": rad([here[0] + 50, here[1], here[2], here[3]]), "time": 4.0}])
    client.wait_event("feedback", lambda e: e["id"] == first)
    second = send(client, ["j3"], [{"positions": rad([here[3] - 10]), "time": 0.5}])
    r1 = result(client, first)
    assert (r1["status"], r1["error_code"]) == (STATUS["aborted"], -1) and "preempted" in r1["error_string"], r1
    r2 = result(client, second)
    assert (r2["status"], r2["error_code"]) == (STATUS["succeeded"], 0), r2
    now, _ = where(arm)
    assert math.radians(now[3]) == pytest.approx(math.radians(here[3] - 10), abs=GOAL_TOL)
    assert now[0] < here[0] + 50  # the first goal did not go on


def test_encoders_gone_quiet_abort_the_goal(rig):
    arm, node, client = rig
    here, _ = settled(arm)  # at rest: what a scenario before it commanded is done
    gid = send(client, JOINTS, [{"positions": rad([here[0], here[1], here[2] + 40, here[3]]), "time": 3.0}])
    client.wait_event("feedback", lambda e: e["id"] == gid)
    arm.send(cmd="stall")
    try:
        r = result(client, gid)
        assert (r["status"], r["error_code"]) == (STATUS["aborted"], -4), r
        assert "no encoder values from /simarm/state:o" in r["error_string"], r
    finally:
        arm.send(cmd="resume")
    # a goal while the encoders are quiet is refused: where the joints are is not known
    arm.send(cmd="stall")
    try:
        time.sleep(0.5)  # longer than `stale` (0.3 s): what the module last read is old now
        gid = send(client, JOINTS, [{"positions": rad(here), "time": 1.0}])
        r = result(client, gid)
        assert (r["status"], r["error_code"]) == (STATUS["aborted"], -1) and "no encoder values" in r["error_string"]
    finally:
        arm.send(cmd="resume")


@pytest.mark.parametrize("version", ["3.12.3", "4.0.0"])
def test_one_goal_on_other_yarp_releases(version, tmp_path):
    """The arm and the node on that release's bindings: a goal reached."""
    with running(yarp_install(version), tmp_path) as (arm, node, client):
        here, _ = settled(arm)
        target = [here[0] - 15, here[1] + 10, here[2], here[3] + 5]
        gid = send(client, JOINTS, [{"positions": rad(target), "time": 0.8}])
        r = result(client, gid)
        assert (r["status"], r["error_code"]) == (STATUS["succeeded"], 0), r
        now, _ = where(arm)
        assert rad(now) == pytest.approx(rad(target), abs=GOAL_TOL)
        assert feedback(client, gid)


def test_one_goal_on_jazzy(tmp_path):
    """The node and the client on ROS 2 Jazzy's wheels (.venv-jazzy, with
    control_msgs 5.8.0 built there: its feedback has no index), the arm and
    the node on YARP 4.0.0's bindings."""
    require_jazzy()
    with running(NODE_YARP, tmp_path, jazzy=True) as (arm, node, client):
        here, _ = settled(arm)
        target = [here[0] + 12, here[1], here[2] - 8, here[3]]
        gid = send(client, JOINTS, [{"positions": rad(target), "time": 0.8}])
        r = result(client, gid)
        assert (r["status"], r["error_code"]) == (STATUS["succeeded"], 0), r
        now, _ = where(arm)
        assert rad(now) == pytest.approx(rad(target), abs=GOAL_TOL)
        assert feedback(client, gid)


PROBED = """
[module]
name = simarm_trajectory_again

[action follow]
serve = /simarm_controller/follow_joint_trajectory (control_msgs/FollowJointTrajectory)
joints = "j0", "j1", "j2", "j3"
state = /simarm/state:o (float64 x5)
convert = deg_to_rad
command = /simarm/no_such_port:i
"""


def test_probe_checks_the_actions_ports_and_that_no_other_server_has_it(rig, tmp_path):
    """`ybgc probe` of a second config of the rig's action: its state port
    sends 6 values, not the 5 declared (E371); its set-point port is not
    there (E370); the rig's node serves the action already (E376)."""
    arm, node, client = rig
    (tmp_path / "again.ini").write_text(textwrap.dedent(PROBED))
    r = subprocess.run([str(YBGC), "probe", "again.ini", "--format", "json", "--wait", "4"], cwd=tmp_path,
                       env=node.env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 1, r.stdout + r.stderr
    got = {(d["code"], d["line"]) for d in json.loads(r.stdout) if d["severity"] == "error"}
    assert got == {("E371", 5), ("E370", 5), ("E376", 5)}, [(d["code"], d["message"]) for d in json.loads(r.stdout)]
    said = {d["code"]: d["message"] for d in json.loads(r.stdout)}
    assert "/simarm/state:o sends 6 values" in said["E371"], said
    assert "/simarm/no_such_port:i" in said["E370"], said
    assert "the ROS 2 action /simarm_controller/follow_joint_trajectory has 1 server already" in said["E376"], said


JOINT_STATES = """
[module]
name = simarm_joint_states

[output]
topic = /joint_states
type = sensor_msgs/JointState

[mux arm]
ports = /simarm/state:o (float64 x6)
convert = deg_to_rad

[message]
name = "j0", "j1", "j2", "j3"
position = arm[0:4]
"""


def test_a_composed_robot_serves_the_action_beside_its_streams(tmp_path):
    """`ybgc compose` of the arm's action and its joint states: one process,
    a goal reached while /joint_states says where the joints are."""
    install = yarp_install("3.5")
    require_yarp(install)
    (tmp_path / "robot").mkdir()
    (tmp_path / "robot" / "simarm.ini").write_text(textwrap.dedent(CONFIG))
    (tmp_path / "robot" / "joint_states.ini").write_text(textwrap.dedent(JOINT_STATES))
    # the folder is the robot: its config of actions among its configs (check and compose alike)
    r = subprocess.run([str(YBGC), "check", "robot"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert (r.returncode, r.stderr) == (0, ""), r.stderr
    r = subprocess.run([str(YBGC), "compose", str(tmp_path / "robot"), "--backend", "ros2", "--name", "simbot",
                        "-o", str(tmp_path / "simbot")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "of 2 bridges" in r.stderr, r.stdout + r.stderr
    with YarpServer(install=install) as server, Ros2Domain() as domain:
        env = ros2_environment(server.env, domain)
        arm = SimArm(env, {"prefix": "/simarm", "joints": 4, "start": START, "speed": SPEED, "rate": 100,
                           "extra": 2})
        node = Node(env, tmp_path / "simbot" / "simbot_node.py")
        client = ActionClient(env, {"action": "/simarm_controller/follow_joint_trajectory"})
        joints = Ros2Subscriber(env, "/joint_states", "sensor_msgs/msg/JointState", node="simbot_joints", depth=1000)
        try:
            arm.start()
            joints.start()
            node.start()
            node.wait_log("simbot: 2 bridges running", timeout=60)
            node.wait_log("/simarm/state:o: encoder values coming, 4 joints", timeout=60)
            client.start()
            here, _ = settled(arm)
            target = [here[0] + 10, here[1] - 10, here[2], here[3]]
            gid = send(client, JOINTS, [{"positions": rad(target), "time": 0.8}])
            r = result(client, gid)
            assert (r["status"], r["error_code"]) == (STATUS["succeeded"], 0), r
            # the joint states of the same process say where the action left the joints
            def there(m):
                return m.msg["name"] == JOINTS and m.msg["position"] == pytest.approx(rad(target), abs=GOAL_TOL)
            joints.wait(lambda: any(there(m) for m in joints.messages), 30, "a JointState of the goal's positions")
        finally:
            for p in (client, node, joints, arm):
                p.stop()

