"""Benchmark consumer on ROS 2: an rclpy subscriber of sensor_msgs/JointState
that records the receive time of every message and the sequence numbers and
send times found in its ``position`` (laid out as bench/tools/producer.cpp
writes them: blocks of WIDTH values [seq, t, port, fillers...], multiplied by
pi/180 with ``--scale deg``).

    python ros2_sink.py --topic /bench/joint_states --width 15 [--scale deg]
                        [--stall-every S --stall-for D] [--no-record]

Same command protocol as bench_consumer (stdin lines: count, reset,
dump PATH, quit; "ready" when up, "connected" once a publisher is matched).
The callback does the least it can (one tuple appended per message); records
are laid out as bench_consumer dumps them (11 float64 each).
"""
import argparse
import array
import math
import sys
import threading
import time


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--topic", default="/bench/joint_states")
    ap.add_argument("--width", type=int, default=15)
    ap.add_argument("--scale", default="1")
    ap.add_argument("--depth", type=int, default=100)
    ap.add_argument("--stall-every", type=float, default=0.0)
    ap.add_argument("--stall-for", type=float, default=0.0)
    ap.add_argument("--no-record", action="store_true")
    args = ap.parse_args()
    scale = math.pi / 180.0 if args.scale == "deg" else float(args.scale)
    width = args.width

    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    rclpy.init(args=[])
    node = rclpy.create_node("bench_sink")
    lock = threading.Lock()
    state = {"recs": [], "count": 0, "bad": 0, "next_stall": 0.0}
    record = not args.no_record
    mono = time.monotonic

    def on_msg(msg):
        recv = mono()
        pos = msg.position
        n = len(pos)
        bad = 0
        blocks = n // width if n and n % width == 0 else 0
        if not blocks:
            bad = 1
        rec = [recv, blocks, 0.0]
        for k in range(min(blocks, 4)):
            base = k * width
            port = round(pos[base + 2] / scale)
            want = (port * 1000.0 + 3.5) * scale
            if abs(pos[base + 3] - want) > 1e-9 * abs(want):
                bad = 1
            rec.append(round(pos[base] / scale))
            rec.append(pos[base + 1] / scale)
        rec.extend([0.0] * (11 - len(rec)))
        rec[2] = bad
        with lock:
            state["count"] += 1
            state["bad"] += bad
            if record:
                state["recs"].append(rec)
        if args.stall_every > 0 and args.stall_for > 0:
            if not state["next_stall"]:
                state["next_stall"] = recv + args.stall_every
            elif recv >= state["next_stall"]:
                time.sleep(args.stall_for)
                state["next_stall"] = mono() + args.stall_every

    qos = QoSProfile(depth=args.depth, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE)
    sub = node.create_subscription(JointState, args.topic, on_msg, qos)
    executor = SingleThreadedExecutor()
    executor.add_node(node)

    def say(text):
        sys.stdout.write("@" + text + "\n")
        sys.stdout.flush()

    def watch_publishers():
        while not stop.is_set():
            if sub.get_publisher_count() > 0:
                say("connected")
                return
            time.sleep(0.05)

    def commands():
        for line in sys.stdin:
            parts = line.split()
            if not parts:
                continue
            cmd = parts[0]
            if cmd == "count":
                with lock:
                    say(f"count {state['count']} {state['bad']}")
            elif cmd == "reset":
                with lock:
                    state["recs"] = []
                    state["count"] = 0
                    state["bad"] = 0
                say("reset")
            elif cmd == "dump":
                with lock:
                    recs = state["recs"]
                    state["recs"] = list(recs)
                flat = array.array("d")
                for r in recs:
                    flat.extend(r)
                with open(parts[1], "wb") as f:
                    flat.tofile(f)
                say(f"dumped {len(recs)}")
            elif cmd == "quit":
                break
        stop.set()

    stop = threading.Event()
    threading.Thread(target=watch_publishers, daemon=True).start()
    threading.Thread(target=commands, daemon=True).start()
    say("ready")
    try:
        while not stop.is_set():
            executor.spin_once(timeout_sec=0.2)
    except KeyboardInterrupt:
        pass
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
