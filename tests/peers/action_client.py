"""An rclpy ActionClient of control_msgs/FollowJointTrajectory (venv python,
with control_msgs built into it): MoveIt's side of the action, for the
actions' tests.

Config: {"action": "/arm_controller/follow_joint_trajectory", "node": "ybg_test_client"}
Commands:
  {"cmd": "goal", "id": "g1", "joints": [...], "points": [{"positions": [...],
   "velocities": [...], "time": 1.5}, ...], "path_tolerance": [[name, pos, vel, acc], ...],
   "goal_tolerance": [...], "goal_time_tolerance": 0.5, "stamp_offset": -3.0}
      sends a goal (``stamp_offset``: the header's stamp that many seconds
      from now; without it, 0: start when it comes);
  {"cmd": "cancel", "id": "g1"}   cancels it.
Events: ready (the server is there); accepted / rejected (id); feedback (id,
joint_names, desired, actual, error, t); result (id, status, error_code,
error_string, t); canceling (id, accepted).
"""
import os
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import peer_io  # noqa: E402
import rclpy  # noqa: E402
from builtin_interfaces.msg import Duration  # noqa: E402
from control_msgs.action import FollowJointTrajectory  # noqa: E402
from control_msgs.msg import JointTolerance  # noqa: E402
from rclpy.action import ActionClient  # noqa: E402
from rclpy.executors import MultiThreadedExecutor  # noqa: E402
from trajectory_msgs.msg import JointTrajectoryPoint  # noqa: E402


def duration(seconds):
    sec = int(seconds // 1)
    return Duration(sec=sec, nanosec=int(round((seconds - sec) * 1e9)))


def tolerances(rows):
    return [JointTolerance(name=r[0], position=float(r[1]), velocity=float(r[2]), acceleration=float(r[3]))
            for r in rows or []]


def main():
    cfg = peer_io.config()
    rclpy.init()
    node = rclpy.create_node(cfg.get("node", "ybg_test_client"))
    client = ActionClient(node, FollowJointTrajectory, cfg["action"])
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    threading.Thread(target=executor.spin, daemon=True).start()
    peer_io.exit_on_signals()
    if not client.wait_for_server(timeout_sec=60.0):
        peer_io.emit("error", message="no server for %s" % cfg["action"])
        return 1
    peer_io.emit("ready")
    handles = {}

    def on_feedback(gid, msg):
        f = msg.feedback
        peer_io.emit("feedback", id=gid, joint_names=list(f.joint_names), desired=list(f.desired.positions),
                     actual=list(f.actual.positions), error=list(f.error.positions), t=time.monotonic())

    def on_result(gid, future):
        r = future.result()
        peer_io.emit("result", id=gid, status=int(r.status), error_code=int(r.result.error_code),
                     error_string=r.result.error_string, t=time.monotonic())

    def on_goal(gid, future):
        handle = future.result()
        if not handle.accepted:
            peer_io.emit("rejected", id=gid)
            return
        handles[gid] = handle
        peer_io.emit("accepted", id=gid, t=time.monotonic())
        handle.get_result_async().add_done_callback(lambda f: on_result(gid, f))

    commands = peer_io.commands()
    while True:
        c = commands.get()
        if c is None:
            return 0
        if c["cmd"] == "goal":
            goal = FollowJointTrajectory.Goal()
            goal.trajectory.joint_names = list(c["joints"])
            if "stamp_offset" in c:
                now = node.get_clock().now().nanoseconds * 1e-9 + c["stamp_offset"]
                goal.trajectory.header.stamp.sec = int(now)
                goal.trajectory.header.stamp.nanosec = int((now - int(now)) * 1e9)
            for p in c["points"]:
                goal.trajectory.points.append(JointTrajectoryPoint(
                    positions=[float(x) for x in p["positions"]],
                    velocities=[float(x) for x in p.get("velocities", [])],
                    accelerations=[float(x) for x in p.get("accelerations", [])],
                    time_from_start=duration(p["time"])))
            goal.path_tolerance = tolerances(c.get("path_tolerance"))
            goal.goal_tolerance = tolerances(c.get("goal_tolerance"))
            goal.goal_time_tolerance = duration(c.get("goal_time_tolerance", 0.0))
            gid = c["id"]
            future = client.send_goal_async(goal, feedback_callback=lambda msg, gid=gid: on_feedback(gid, msg))
            future.add_done_callback(lambda f, gid=gid: on_goal(gid, f))
        elif c["cmd"] == "cancel":
            gid = c["id"]
            handle = handles.get(gid)
            if handle is None:
                peer_io.emit("error", message="no goal %s to cancel" % gid)
                continue
            handle.cancel_goal_async().add_done_callback(
                lambda f, gid=gid: peer_io.emit("canceling", id=gid, accepted=len(f.result().goals_canceling) > 0))


if __name__ == "__main__":
    sys.exit(main())
