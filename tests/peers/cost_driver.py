"""Drives a bridge module in lockstep, for the cost guard (tests/test_cost.py):
one tick at a time, never two in flight, so that what the module does for a
tick can be counted without depending on how fast the machine is.

Config: {"sources": ["/port:o", ...], "width": n,
         "output": "/module/out:o" (a YARP port the module writes) or null,
         "topic": "/ros2/topic" (a sensor_msgs/JointState the module publishes) or null,
         "reader": "/cost/reader:i"}
A tick is one Bottle of ``width`` float64 on each source port (a strict
write, acknowledged by the module's port), all with one envelope stamp (the
tick's number and time), as a robot's state ports stamp a sample; the next
tick is written once the module's message of this one has reached the reader.
Commands: {"cmd": "run", "ticks": n, "period": s (optional)}: n ticks (one every
            ``period`` seconds at most, when given), then event "ran" (ticks, lost, seconds)
          {"cmd": "quit"}
Events: ready; connected (the module reads every source and the reader
reads the module); ran; error (message).
"""
import threading
import time

import peer_io
import yarp

#: how long a tick's message may take before the tick counts as lost
TICK_TIMEOUT = 2.0


class Counter(yarp.BottleCallback):
    """The YARP reader's callback: counts the messages."""

    def __init__(self, arrived):
        yarp.BottleCallback.__init__(self)
        self.arrived = arrived

    def onRead(self, bottle, *reader):
        self.arrived()


def main():
    cfg = peer_io.config()
    peer_io.exit_on_signals()
    yarp.Network.init()
    cond = threading.Condition()
    got = [0]

    def arrived(*_):
        with cond:
            got[0] += 1
            cond.notify_all()

    ports = []
    for name in cfg["sources"]:
        port = yarp.Port()
        port.setWriteOnly()
        if not port.open(name):
            peer_io.emit("error", message="cannot open " + name)
            return 1
        ports.append(port)
    spin = None
    if cfg.get("topic"):
        import rclpy
        from rclpy.qos import QoSProfile, ReliabilityPolicy
        from sensor_msgs.msg import JointState

        rclpy.init()
        node = rclpy.create_node("cost_driver")
        qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
        node.create_subscription(JointState, cfg["topic"], arrived, qos)

        def spin_once(timeout):
            rclpy.spin_once(node, timeout_sec=timeout)

        spin = spin_once

        def linked():
            return node.count_publishers(cfg["topic"]) > 0
    else:
        reader = yarp.BufferedPortBottle()
        reader.setStrict(True)
        callback = Counter(arrived)
        reader.useCallback(callback)
        if not reader.open(cfg["reader"]):
            peer_io.emit("error", message="cannot open " + cfg["reader"])
            return 1

        def linked():
            if reader.getInputCount() > 0:
                return True
            if yarp.Network.exists(cfg["output"], True):
                yarp.Network.connect(cfg["output"], cfg["reader"], "tcp", True)
            return False
    peer_io.emit("ready")

    def wait_for(n, timeout):
        """Until ``n`` messages have arrived (True), or ``timeout`` seconds."""
        end = time.monotonic() + timeout
        while True:
            with cond:
                if got[0] >= n:
                    return True
                left = end - time.monotonic()
                if left <= 0:
                    return False
                if spin is None:
                    cond.wait(left)
                    continue
            spin(min(left, 0.05))

    end = time.monotonic() + 60
    while not (all(p.getOutputCount() > 0 for p in ports) and linked()):
        if time.monotonic() > end:
            peer_io.emit("error", message="the module did not connect")
            return 1
        if spin is not None:
            spin(0.05)
        else:
            time.sleep(0.05)
    peer_io.emit("connected")

    bottle = yarp.Bottle()
    tick = [0]
    gap = cfg.get("gap") or 0.0

    def one_tick():
        """Writes a tick; True when its message arrived."""
        k = tick[0]
        tick[0] += 1
        with cond:
            want = got[0] + 1
        stamp = yarp.Stamp(k, time.time())
        for i, port in enumerate(ports):
            if i and gap:
                time.sleep(gap)
            bottle.clear()
            for j in range(cfg["width"]):
                bottle.addFloat64(float(k % 360) + j + i / 100.0)
            port.setEnvelope(stamp)
            port.write(bottle)
        arrived = wait_for(want, TICK_TIMEOUT)
        if gap:
            time.sleep(gap)
        return arrived

    commands = peer_io.commands()
    while True:
        cmd = commands.get()
        if cmd is None or cmd.get("cmd") == "quit":
            break
        if cmd.get("cmd") == "run":
            t0 = time.monotonic()
            period = cmd.get("period") or 0.0
            lost = 0
            for k in range(int(cmd["ticks"])):
                if period:
                    time.sleep(max(0.0, t0 + k * period - time.monotonic()))
                lost += 0 if one_tick() else 1
            peer_io.emit("ran", ticks=int(cmd["ticks"]), lost=lost, seconds=time.monotonic() - t0)
    for port in ports:
        port.close()
    peer_io.emit("done")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
