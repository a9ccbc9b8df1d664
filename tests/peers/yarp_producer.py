"""YARP Bottle producer peer (venv python with the yarp bindings).

Config: {"port": "/name", "bottles": [[...], ...], "rate": hz or null,
         "count": n or null, "envelope": bool, "wait_connected": bool,
         "connect_to": ["/port", ...], "carrier": "tcp", "socket": n or null}
With a socket, the port opens at that port number (of this host, YARP_IP)
instead of the one the name server hands out, and registers its name there
(YARP does not register a port opened at a given address).
With a rate, writes the bottles in turn (cycling) at that rate (count times, or
forever); without, writes only on command.
Commands: {"cmd": "write", "data": [...], "stamp": [seq, time] (optional)}
          {"cmd": "burst", "bottles": [[...], ...]}: writes them back to back
            (strict), waits until the last is delivered (with YARP's default
            tcp carrier: the reader's port has it), then event "burst" (n, t0, t1)
          {"cmd": "outputs"} -> event "outputs" with n
          {"cmd": "quit"}
Events: ready, sent (n, t), burst (n, t0, t1), outputs (n), done.
"""
import os
import threading
import time

import peer_io
import bottle_codec
import yarp


def main():
    cfg = peer_io.config()
    peer_io.exit_on_signals()
    yarp.Network.init()
    port = yarp.BufferedPortBottle()
    port.setWriteOnly()  # required for a ROS topic name such as /topic@/node
    where = cfg["port"]
    if cfg.get("socket"):
        where = yarp.Contact(cfg["port"], "tcp", os.environ.get("YARP_IP", "127.0.0.1"), int(cfg["socket"]))
    if not port.open(where):
        peer_io.emit("error", message="cannot open " + cfg["port"])
        return 1
    if cfg.get("socket"):
        yarp.Network.registerContact(port.where())
    for dst in cfg.get("connect_to") or []:
        yarp.Network.connect(cfg["port"], dst, cfg.get("carrier") or "", True)
    lock = threading.Lock()
    seq = [0]

    def write(data, stamp=None):
        with lock:
            b = port.prepare()
            bottle_codec.fill(b, data)
            if stamp is not None:
                port.setEnvelope(yarp.Stamp(int(stamp[0]), float(stamp[1])))
            elif cfg.get("envelope"):
                port.setEnvelope(yarp.Stamp(seq[0], time.time()))
            t = time.time()
            port.write(True)  # strict: never drop a queued bottle
            n = seq[0]
            seq[0] += 1
        peer_io.emit("sent", n=n, t=t)

    peer_io.emit("ready")

    rate = cfg.get("rate")
    bottles = cfg.get("bottles") or []
    if rate and bottles:
        def stream():
            if cfg.get("wait_connected"):
                while port.getOutputCount() < 1:
                    time.sleep(0.01)
            period = 1.0 / rate
            nxt = time.monotonic()
            i = 0
            count = cfg.get("count")
            while count is None or i < count:
                write(bottles[i % len(bottles)])
                i += 1
                nxt += period
                d = nxt - time.monotonic()
                if d > 0:
                    time.sleep(d)
            peer_io.emit("done", n=i)
        threading.Thread(target=stream, daemon=True).start()

    q = peer_io.commands()
    while True:
        c = q.get()
        if c is None or c.get("cmd") == "quit":
            break
        if c["cmd"] == "write":
            write(c["data"], c.get("stamp"))
        elif c["cmd"] == "burst":
            t0 = time.time()
            for data in c["bottles"]:
                write(data)
            with lock:
                port.waitForWrite()
            peer_io.emit("burst", n=len(c["bottles"]), t0=t0, t1=time.time())
        elif c["cmd"] == "outputs":
            peer_io.emit("outputs", n=port.getOutputCount())
    port.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
