"""A simulated YARP controlboard (venv python with the yarp bindings of any
YARP version), for the actions' tests: it takes set points on a port and
moves each joint toward its own at a bounded speed, writing its encoders on
its state port.

- ``<prefix>/setpoints:i``: Bottles of float64, one a joint, degrees (the
  newest counts); each one read is an event ``setpoint`` (its values and
  the time it came) when ``"report": true``;
- ``<prefix>/state:o``: the joints' positions in degrees, then ``extra``
  float64 of 0 (a part's other values), at ``rate`` Hz;
- ``speed``: degrees a second each joint moves at most.

Config: {"prefix": "/simarm", "joints": 4, "start": [deg, ...], "speed": 90,
         "rate": 100, "extra": 2, "report": false}
Commands: {"cmd": "hold", "joint": k} (joint k moves no more: a joint held
back), {"cmd": "release", "joint": k}, {"cmd": "stall"} (no more encoder
Bottles), {"cmd": "resume"}, {"cmd": "state"} (an event ``state``: the
positions, the set points received, the steps the joints have taken).
Events: ready; setpoint (values, t) when reporting; state (positions, received, ticks).
"""
import os
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import peer_io  # noqa: E402
import yarp  # noqa: E402


class SetpointReader(yarp.BottleCallback):
    def __init__(self, arm):
        yarp.BottleCallback.__init__(self)
        self.arm = arm

    def onRead(self, bottle, *reader):
        try:
            values = [bottle.get(k).asFloat64() for k in range(bottle.size())]
            with self.arm.lock:
                if len(values) == len(self.arm.target):
                    self.arm.target = values
                    self.arm.received += 1
            if self.arm.report:
                peer_io.emit("setpoint", values=values, t=time.monotonic())
        except Exception as e:  # never an exception into YARP's thread
            peer_io.emit("error", message=repr(e))


class Arm:
    def __init__(self, cfg):
        n = cfg["joints"]
        self.pos = [float(x) for x in cfg.get("start", [0.0] * n)]
        self.target = list(self.pos)
        self.speed = float(cfg.get("speed", 90.0))
        self.period = 1.0 / float(cfg.get("rate", 100))
        self.extra = int(cfg.get("extra", 0))
        self.report = bool(cfg.get("report", False))
        self.held = set()
        self.stalled = False
        self.received = 0
        self.ticks = 0
        self.lock = threading.Lock()

    def step(self, dt):
        with self.lock:
            for k, goal in enumerate(self.target):
                if k in self.held:
                    continue
                delta = max(-self.speed * dt, min(self.speed * dt, goal - self.pos[k]))
                self.pos[k] += delta
            self.ticks += 1
            return list(self.pos)


def main():
    cfg = peer_io.config()
    prefix = cfg.get("prefix", "/simarm")
    yarp.Network.init()
    arm = Arm(cfg)
    state = yarp.BufferedPortBottle()
    setpoints = yarp.BufferedPortBottle()
    reader = SetpointReader(arm)
    setpoints.useCallback(reader)
    if not state.open(prefix + "/state:o") or not setpoints.open(prefix + "/setpoints:i"):
        peer_io.emit("error", message="cannot open the ports")
        return 1
    commands = peer_io.commands()
    peer_io.exit_on_signals()
    peer_io.emit("ready")
    last = time.monotonic()
    next_tick = last
    while True:
        while not commands.empty():
            c = commands.get()
            if c is None:
                return 0
            with arm.lock:
                if c["cmd"] == "hold":
                    arm.held.add(c["joint"])
                elif c["cmd"] == "release":
                    arm.held.discard(c["joint"])
                elif c["cmd"] == "stall":
                    arm.stalled = True
                elif c["cmd"] == "resume":
                    arm.stalled = False
                elif c["cmd"] == "state":
                    peer_io.emit("state", positions=list(arm.pos), received=arm.received, ticks=arm.ticks)
        now = time.monotonic()
        positions = arm.step(now - last)
        last = now
        if not arm.stalled:
            b = state.prepare()
            b.clear()
            for v in positions + [0.0] * arm.extra:
                b.addFloat64(v)
            state.write()
        next_tick += arm.period
        time.sleep(max(0.0, next_tick - time.monotonic()))


if __name__ == "__main__":
    sys.exit(main())
