"""A simulated YARP robot (venv python with the yarp bindings of any YARP
version), the ports a running robot opens, for ``ybgc init``:

- each part's controlboard: ``<prefix>/<part>/state:o``, joint positions
  in degrees at ``rate`` Hz with an envelope stamp; ``<prefix>/<part>/rpc:i``
  answering as YARP's controlboard server does (``[get] [axes]`` ->
  ``[is] [axes] N (stamp) [ok]``, ``[get] [name] j`` -> ``[is] [name] "..."
  (stamp) [ok]``, anything else ``[fail]``; a part with ``"names": null``
  answers nothing but ``[fail]``); ``<prefix>/<part>/command:i``, an input;
- ``<prefix>/inertial``: 12 float64 (rpy deg, acc, gyro deg/s, mag);
- ``<prefix>/<ft>/analog:o``: 6 float64 (force, torque);
- ``<prefix>/cam/left``: ``width`` x ``height`` rgb images
  (tests/peers/image_data.pixels with seed 7) at 10 Hz;
- ``<prefix>/homing/rpc:i``: answers `help` with a list of its commands;
- ``<prefix>/silent:o``: sends nothing; ``<prefix>/odd:o``: Bottles of
  changing layouts.

Config: {"prefix": "/sim", "rate": 100, "parts": {"head": ["neck_pitch", ...] or null, ...},
         "ft": "left_arm", "width": 32, "height": 24}
The values: at write n (counted from 0, the same n for every port of a
write), joint k of the i-th part (in the config's order) is
``10 * (i + 1) + k + 0.001 * (n % 1000)`` degrees; the inertial port's
element k is ``k + 1 + 0.001 * (n % 1000)``; the force/torque port's
``-(k + 1) - 0.001 * (n % 1000)``. A test finds n from one value and checks
the others (tests/test_init.py).
Events: ready; written (n) every 100 writes.
"""
import ctypes
import os
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import image_data  # noqa: E402
import peer_io  # noqa: E402
import yarp  # noqa: E402


def joint(i, k, n):
    return 10.0 * (i + 1) + k + 0.001 * (n % 1000)


def inertial(k, n):
    return k + 1 + 0.001 * (n % 1000)


def wrench(k, n):
    return -(k + 1) - 0.001 * (n % 1000)


class Responder(yarp.PortReader):
    """An RPC port's reader: each command read, answered (``answer``), and
    the reply written back, in YARP's thread of the connection."""

    def read(self, connection):
        try:
            cmd = yarp.Bottle()
            if not cmd.read(connection):
                return False
            reply = yarp.Bottle()
            self.answer(cmd, reply)
            writer = connection.getWriter()
            if writer is not None:
                reply.write(writer)
            return True
        except Exception as e:  # never an exception into YARP's thread
            peer_io.emit("error", message=repr(e))
            return False


class Controlboard(Responder):
    """The RPC side of a controlboard: axes and their names."""

    def __init__(self, names, axes):
        Responder.__init__(self)
        self.names = names
        self.axes = axes

    def answer(self, cmd, reply):
        answered = True
        words = [cmd.get(k) for k in range(cmd.size())]
        verb = yarp.decode(words[0].asVocab32()) if words and words[0].isVocab32() else ""
        what = yarp.decode(words[1].asVocab32()) if len(words) > 1 and words[1].isVocab32() else ""
        if self.names is not None and verb == "get" and what == "axes":
            reply.addVocab32("is")
            reply.add(words[1])
            reply.addInt32(self.axes)
        elif self.names is not None and verb == "get" and what == "name" and len(words) > 2 \
                and 0 <= words[2].asInt32() < self.axes:
            reply.addVocab32("is")
            reply.add(words[1])
            reply.addString(self.names[words[2].asInt32()])
        else:
            answered = False
            reply.addVocab32("fail")
        if answered:
            stamp = reply.addList()
            stamp.addInt32(1)
            stamp.addFloat64(time.time())
            reply.addVocab32("ok")


class Helpful(Responder):
    """An RPC port that lists its commands on `help`."""

    def answer(self, cmd, reply):
        if cmd.get(0).asString() == "help":
            reply.addVocab32("many")
            reply.addString("home all: every part to its home position")
            reply.addString("home <part>: one part")
        else:
            reply.addString("nack")


def open_port(name, reader=None, output=True):
    port = yarp.Port()
    if reader is not None:
        port.setReader(reader)
    if not output:
        port.setInputMode(True)
        port.setOutputMode(False)
    if not port.open(name):
        peer_io.emit("error", message="cannot open " + name)
        sys.exit(1)
    return port


def main():
    cfg = peer_io.config()
    peer_io.exit_on_signals()
    yarp.Network.init()
    prefix = cfg.get("prefix", "/sim").rstrip("/")
    rate = float(cfg.get("rate", 100))
    parts = cfg["parts"]
    keep = []  # the readers, alive as long as their ports
    states = []
    for part, names in parts.items():
        axes = len(names) if names else int(cfg.get("axes", {}).get(part, 4))
        states.append((open_port(f"{prefix}/{part}/state:o"), axes))
        rpc = Controlboard(names, axes)
        keep.append(rpc)
        keep.append(open_port(f"{prefix}/{part}/rpc:i", rpc, output=False))
        keep.append(open_port(f"{prefix}/{part}/command:i", output=False))
    imu = open_port(f"{prefix}/inertial")
    ft = open_port(f"{prefix}/{cfg.get('ft', 'left_arm')}/analog:o")
    helpful = Helpful()
    keep.append(helpful)
    keep.append(open_port(f"{prefix}/homing/rpc:i", helpful, output=False))
    keep.append(open_port(f"{prefix}/silent:o"))
    odd = open_port(f"{prefix}/odd:o")
    cam = open_port(f"{prefix}/cam/left")
    w, h = int(cfg.get("width", 32)), int(cfg.get("height", 24))
    image = yarp.FlexImage()
    image.setPixelCode(image_data.yarp_code(yarp, "rgb8"))
    image.setQuantum(8)
    image.resize(w, h)
    raw = (ctypes.c_ubyte * image.getRawImageSize()).from_address(int(image.getRawImage()))
    src = image_data.pixels(w, h, 3, 7)
    row = image.getRowSize()
    for y in range(h):
        ctypes.memmove(ctypes.addressof(raw) + y * row, src[y * w * 3:(y + 1) * w * 3], w * 3)

    stop = threading.Event()

    def commands():
        q = peer_io.commands()
        while True:
            c = q.get()
            if c is None or c.get("cmd") == "quit":
                stop.set()
                return

    threading.Thread(target=commands, daemon=True).start()
    peer_io.emit("ready")
    period = 1.0 / rate
    n = 0
    next_t = time.monotonic()
    while not stop.is_set():
        stamp = yarp.Stamp(n, time.time())
        for i, (port, axes) in enumerate(states):
            b = yarp.Bottle()
            for k in range(axes):
                b.addFloat64(joint(i, k, n))
            port.setEnvelope(stamp)
            port.write(b)
        b = yarp.Bottle()
        for k in range(12):
            b.addFloat64(inertial(k, n))
        imu.setEnvelope(stamp)
        imu.write(b)
        b = yarp.Bottle()
        for k in range(6):
            b.addFloat64(wrench(k, n))
        ft.setEnvelope(stamp)
        ft.write(b)
        b = yarp.Bottle()
        if n % 2:
            b.addString("odd")
        else:
            b.addFloat64(1.0)
            b.addFloat64(2.0)
        odd.write(b)
        if n % max(1, int(rate / 10)) == 0:
            cam.setEnvelope(stamp)
            cam.write(image)
        if n % 100 == 0:
            peer_io.emit("written", n=n)
        n += 1
        next_t += period
        time.sleep(max(0.0, next_t - time.monotonic()))
    for port in [p for p, _ in states] + [imu, ft, odd, cam] + [k for k in keep if isinstance(k, yarp.Port)]:
        port.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
