"""YARP Bottle reader peer (venv python with the yarp bindings).

Config: {"port": "/name", "source": "/port" or null, "carrier": "tcp" or "",
         "poll": 0.2, "head": null or N}
Opens a BufferedPortBottle (strict: keeps every Bottle). With a source, the
reader keeps the connection source -> port alive: every `poll` seconds it
connects it again if it is missing (so a source that starts late, or is killed
and restarted, is picked up).
Events: ready; connected / disconnected (source); bottle with t (receive time,
time.time()), data, types, stamp ([seq, time] or null), text; with a head,
data and types of the first N values only and no text (large Bottles counted,
not read).
"""
import time

import peer_io
import bottle_codec
import yarp


def main():
    cfg = peer_io.config()
    peer_io.exit_on_signals()
    peer_io.exit_at_stdin_eof()
    yarp.Network.init()
    port = yarp.BufferedPortBottle()
    port.setStrict(True)
    port.setReadOnly()  # required for a ROS topic name such as /topic@/node
    name = cfg["port"]
    if not port.open(name):
        peer_io.emit("error", message="cannot open " + name)
        return 1
    src = cfg.get("source")
    carrier = cfg.get("carrier") or ""
    poll = float(cfg.get("poll") or 0.2)
    head = cfg.get("head")
    # the connection is looked for with its carrier: YARP 4 does not count a
    # fast_tcp connection as one of the default carrier, and connecting again
    # replaces it (what is in flight is lost)
    style = yarp.ContactStyle()
    style.quiet = True
    if carrier:
        style.carrier = carrier
    peer_io.emit("ready")
    connected = False
    last_state = None
    next_check = 0.0
    # polled (the bindings' blocking read keeps the interpreter lock from YARP
    # 3.12.1): every 0.5 ms while Bottles come, backing off to 4 ms while none
    # do, so that a reader waiting costs little CPU
    nap = 0.0005
    while True:
        now = time.monotonic()
        if src and now >= next_check:
            next_check = now + poll
            ok = yarp.Network.isConnected(src, name, style)
            state = ("connected",) if ok else None
            if not ok:
                there = yarp.Network.exists(src, True)
                if there:
                    ok = yarp.Network.connect(src, name, carrier, True)
                state = ("exists" if there else "missing", "connect ok" if ok else "no connect")
            if state != last_state:
                last_state = state
                peer_io.emit("check", state=list(state))
            if ok != connected:
                connected = ok
                peer_io.emit("connected" if ok else "disconnected", source=src)
        got = False
        while True:
            b = port.read(False)
            if b is None:
                break
            got = True
            t = time.time()
            data, types = bottle_codec.to_py(b, head)
            st = None
            stamp = yarp.Stamp()
            if port.getEnvelope(stamp) and stamp.isValid():
                st = [stamp.getCount(), stamp.getTime()]
            peer_io.emit("bottle", t=t, data=data, types=types, stamp=st,
                         text="" if head else b.toString())
        if got:
            nap = 0.0005
        else:
            time.sleep(nap)
            nap = min(nap * 2, 0.004)


if __name__ == "__main__":
    raise SystemExit(main())
