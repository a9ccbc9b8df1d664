"""ROS 2 peer (venv python with rclpy): a subscriber or a publisher.

Config: {"mode": "sub" | "pub", "topic": "/joint_states",
         "type": "sensor_msgs/msg/JointState", "node": "ybg_test_peer",
         "depth": 100,
         # pub only:
         "messages": [{...}, ...], "rate": hz or null, "count": n or null,
         "wait_matched": bool, "stamp_now": bool}
Messages are nested dicts of field values (missing fields keep defaults);
with "stamp_now" a header.stamp is set to the current time before each publish.
Commands (pub): {"cmd": "publish", "msg": {...}}, {"cmd": "quit"}.
Events: ready; matched (n, the number of matched peers when it changes);
sub: msg (t = receive time, msg = nested dicts, Time as {"sec", "nanosec"});
pub: sent (n, t), done.
"""
import importlib
import queue
import time

import peer_io


def msg_class(name):
    pkg, kind, typ = name.split("/")
    return getattr(importlib.import_module(pkg + "." + kind), typ)


def to_py(m):
    if hasattr(m, "get_fields_and_field_types"):
        return {k: to_py(getattr(m, k)) for k in m.get_fields_and_field_types()}
    if isinstance(m, (bytes, bytearray)):
        return list(m)
    if hasattr(m, "tolist"):
        return m.tolist()
    if isinstance(m, (list, tuple)):
        return [to_py(x) for x in m]
    return m


def element_class(field_type):
    """The message class of the elements of an array of messages, from its
    rosidl type: "sequence<trajectory_msgs/JointTrajectoryPoint>",
    "geometry_msgs/Point[5]"."""
    name = field_type.split("<", 1)[-1].split(",")[0].rstrip(">").split("[")[0]
    pkg, typ = name.split("/")
    return getattr(importlib.import_module(pkg + ".msg"), typ)


def fill(m, fields):
    for k, v in fields.items():
        cur = getattr(m, k)
        if isinstance(v, dict) and hasattr(cur, "get_fields_and_field_types"):
            fill(cur, v)
        elif isinstance(v, list) and v and isinstance(v[0], dict):  # an array of messages
            cls = element_class(m.get_fields_and_field_types()[k])
            setattr(m, k, [fill(cls(), x) for x in v])
        else:
            setattr(m, k, v)
    return m


def main():
    cfg = peer_io.config()
    peer_io.exit_on_signals()
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    cls = msg_class(cfg["type"])
    node = rclpy.create_node(cfg.get("node") or "ybg_test_peer")
    depth = int(cfg.get("depth") or 100)
    ex = SingleThreadedExecutor()
    ex.add_node(node)
    mode = cfg.get("mode", "sub")

    if mode == "sub":
        def on_msg(msg):
            peer_io.emit("msg", t=time.time(), msg=to_py(msg))
        ent = node.create_subscription(cls, cfg["topic"], on_msg, depth)
        count = ent.get_publisher_count
    else:
        ent = node.create_publisher(cls, cfg["topic"], depth)
        count = ent.get_subscription_count

    seq = [0]

    def publish(fields):
        msg = fill(cls(), fields)
        if cfg.get("stamp_now") and hasattr(msg, "header"):
            msg.header.stamp = node.get_clock().now().to_msg()
        t = time.time()
        ent.publish(msg)
        peer_io.emit("sent", n=seq[0], t=t)
        seq[0] += 1

    if mode == "pub":
        q = peer_io.commands()
    else:
        q = queue.Queue()
        peer_io.exit_at_stdin_eof()
    peer_io.emit("ready")
    matched = -1
    messages = cfg.get("messages") or []
    rate = cfg.get("rate")
    limit = cfg.get("count")
    period = 1.0 / rate if rate else None
    nxt = None
    i = 0
    while True:
        ex.spin_once(timeout_sec=0.001 if period else 0.02)
        k = count()
        if k != matched:
            matched = k
            peer_io.emit("matched", n=k)
        if mode == "pub":
            try:
                while True:
                    c = q.get_nowait()
                    if c is None or c.get("cmd") == "quit":
                        return 0
                    if c["cmd"] == "publish":
                        publish(c.get("msg") or {})
            except queue.Empty:
                pass
            if period and messages and (limit is None or i < limit) \
                    and (not cfg.get("wait_matched") or matched > 0):
                now = time.monotonic()
                if nxt is None:
                    nxt = now
                if now >= nxt:
                    publish(messages[i % len(messages)])
                    i += 1
                    nxt += period
                    if limit is not None and i == limit:
                        peer_io.emit("done", n=i)


if __name__ == "__main__":
    raise SystemExit(main())
