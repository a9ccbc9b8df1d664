"""ROS 2 subscriber peer with a chosen QoS (venv python with rclpy).

Config: {"topic": "/imu/data", "type": "sensor_msgs/msg/Imu",
         "node": "ybg_test_qos_sub", "reliability": "reliable" | "best_effort",
         "durability": "volatile" | "transient_local", "depth": 100}
Events: ready; matched (n, the number of publishers when it changes; qos,
the reliability and durability each publisher offers);
msg (t = receive time, msg = nested dicts, Time as {"sec", "nanosec"}).
"""
import time

import peer_io
from rclpy_peer import msg_class, to_py


def main():
    cfg = peer_io.config()
    peer_io.exit_on_signals()
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(cfg.get("node") or "ybg_test_qos_sub")
    qos = QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=int(cfg.get("depth") or 100),
        reliability={"reliable": ReliabilityPolicy.RELIABLE,
                     "best_effort": ReliabilityPolicy.BEST_EFFORT}[cfg.get("reliability", "reliable")],
        durability={"volatile": DurabilityPolicy.VOLATILE,
                    "transient_local": DurabilityPolicy.TRANSIENT_LOCAL}[cfg.get("durability", "volatile")],
    )

    def on_msg(msg):
        peer_io.emit("msg", t=time.time(), msg=to_py(msg))

    sub = node.create_subscription(msg_class(cfg["type"]), cfg["topic"], on_msg, qos)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    peer_io.emit("ready")
    matched = -1
    while True:
        ex.spin_once(timeout_sec=0.02)
        n = sub.get_publisher_count()
        if n != matched:
            matched = n
            peer_io.emit("matched", n=n, qos=[
                {"reliability": i.qos_profile.reliability.name.lower(),
                 "durability": i.qos_profile.durability.name.lower()}
                for i in node.get_publishers_info_by_topic(cfg["topic"])])


if __name__ == "__main__":
    raise SystemExit(main())
