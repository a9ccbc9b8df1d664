"""Benchmark producer on ROS 2 (the bare rclpy hop, for reference): an rclpy
publisher of sensor_msgs/JointState whose ``position`` holds BLOCKS blocks of
WIDTH values laid out as bench/tools/producer.cpp writes them ([seq, t, port,
fillers...], t = CLOCK_MONOTONIC seconds just before publishing), so that
ros2_sink.py reads it as it reads the bridge's output.

    python ros2_source.py --topic /bench/joint_states --width 15 --blocks 2

Commands on stdin, as bench_producer: "wait N TIMEOUT" (N matched
subscriptions), "run COUNT RATE" (absolute deadlines), "quit".
"""
import argparse
import sys
import time


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--topic", default="/bench/joint_states")
    ap.add_argument("--width", type=int, default=15)
    ap.add_argument("--blocks", type=int, default=2)
    ap.add_argument("--depth", type=int, default=10)
    args = ap.parse_args()

    import rclpy
    from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    rclpy.init(args=[])
    node = rclpy.create_node("bench_source")
    qos = QoSProfile(depth=args.depth, history=HistoryPolicy.KEEP_LAST,
                     reliability=ReliabilityPolicy.RELIABLE)
    pub = node.create_publisher(JointState, args.topic, qos)
    width, blocks = args.width, args.blocks
    n = width * blocks
    msg = JointState()
    msg.header.frame_id = "base_link"
    msg.name = [f"j{i}" for i in range(n)]
    values = [0.0] * n
    for k in range(blocks):
        values[k * width + 2] = float(k)
        for i in range(3, width):
            values[k * width + i] = k * 1000.0 + i + 0.5
    clock = node.get_clock()
    mono = time.monotonic

    def say(text):
        sys.stdout.write("@" + text + "\n")
        sys.stdout.flush()

    say("ready")
    seq = 0
    for line in sys.stdin:
        parts = line.split()
        if not parts:
            continue
        if parts[0] == "wait":
            want, timeout = int(parts[1]), float(parts[2])
            end = mono() + timeout
            while pub.get_subscription_count() < want and mono() < end:
                time.sleep(0.02)
            got = pub.get_subscription_count()
            say(("ok " if got >= want else "timeout ") + str(got))
        elif parts[0] == "run":
            count, rate = int(parts[1]), float(parts[2])
            period = 1.0 / rate
            first = seq + 1
            late = 0
            t0 = mono()
            nxt = t0
            for _ in range(count):
                seq += 1
                msg.header.stamp = clock.now().to_msg()
                t = mono()
                for k in range(blocks):
                    values[k * width] = float(seq)
                    values[k * width + 1] = t
                msg.position = values
                pub.publish(msg)
                nxt += period
                delay = nxt - mono()
                if delay > 0:
                    time.sleep(delay)
                else:
                    late += 1
            say(f"done {first} {count} {late} {mono() - t0:.9f}")
        elif parts[0] == "quit":
            break
    node.destroy_node()
    rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
