"""ROS 1 subscriber peer: run with Debian's /usr/bin/python3 (rospy).

Config: {"topic": "/joint_states", "type": "sensor_msgs/JointState",
         "node": "ybg_test_listener"}
Needs ROS_MASTER_URI / ROS_IP in the environment.
Events: ready; publishers (n, when the number of connected publishers
changes); msg (t = receive time, msg = the message as nested dicts, times as
{"secs", "nsecs"}).
"""
import time

import peer_io
import rospy
import roslib.message


def to_py(m):
    if hasattr(m, "__slots__"):
        return {k: to_py(getattr(m, k)) for k in m.__slots__}
    if isinstance(m, (bytes, bytearray)):
        return list(m)
    if isinstance(m, (list, tuple)):
        return [to_py(x) for x in m]
    return m


def main():
    cfg = peer_io.config()
    peer_io.exit_on_signals()
    peer_io.exit_at_stdin_eof()
    cls = roslib.message.get_message_class(cfg["type"])
    if cls is None:
        peer_io.emit("error", message="unknown type " + cfg["type"])
        return 1
    rospy.init_node(cfg.get("node") or "ybg_test_listener", anonymous=True,
                    disable_signals=True)

    def on_msg(msg):
        peer_io.emit("msg", t=time.time(), msg=to_py(msg))

    sub = rospy.Subscriber(cfg["topic"], cls, on_msg, queue_size=1000)
    peer_io.emit("ready")
    n = -1
    while True:
        k = sub.get_num_connections()
        if k != n:
            n = k
            peer_io.emit("publishers", n=k)
        time.sleep(0.05)


if __name__ == "__main__":
    raise SystemExit(main())
