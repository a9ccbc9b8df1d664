"""A YARP RPC client peer (venv python with the yarp bindings of any YARP
version): sends commands to an RPC port and records each reply and its
times; several clients at once, each a port of its own.

Config: {"name": "/test/rpc_client", "target": "/robot_gate/rpc:i",
         "clients": 1, "timeout": 10.0}
Client i is the port <name>/<i> (a yarp.Port, whose calls let the
interpreter lock go on every YARP version: the clients of a batch run
at once), with a socket timeout of ``timeout`` s.
Commands: {"cmd": "connect", "timeout": s}: connects every client to the
            target, trying again until it exists; event "connected" (n) or
            "error"
          {"cmd": "call", "id": x, "client": i, "data": [...]}: one command,
            event "reply"
          {"cmd": "batch", "calls": [[{"id": x, "data": [...]}, ...], ...]}:
            one list per client, each client's calls one after another, the
            clients at once; a "reply" event per call, then "batch" (n, t0, t1)
          {"cmd": "quit"}
Events: ready; connected (n); reply (id, client, ok: write() said so, data,
        types, text, t0: before the write, t1: after the reply);
        batch (n, t0, t1); error (message).
"""
import threading
import time

import bottle_codec
import peer_io
import yarp


def main():
    cfg = peer_io.config()
    peer_io.exit_on_signals()
    yarp.Network.init()
    name = cfg.get("name") or "/test/rpc_client"
    target = cfg["target"]
    timeout = float(cfg.get("timeout") or 10.0)
    ports = []
    for i in range(int(cfg.get("clients") or 1)):
        p = yarp.Port()
        p.setRpcClient()
        p.setTimeout(timeout)
        if not p.open("%s/%d" % (name, i)):
            peer_io.emit("error", message="cannot open %s/%d" % (name, i))
            return 1
        ports.append(p)
    locks = [threading.Lock() for _ in ports]

    def call(i, ident, data):
        cmd = yarp.Bottle()
        bottle_codec.fill(cmd, data)
        reply = yarp.Bottle()
        with locks[i]:
            t0 = time.time()
            ok = ports[i].write(cmd, reply)
            t1 = time.time()
        values, types = bottle_codec.to_py(reply)
        peer_io.emit("reply", id=ident, client=i, ok=bool(ok), data=values, types=types,
                     text=reply.toString(), t0=t0, t1=t1)

    def connect(limit):
        end = time.monotonic() + limit
        style = yarp.ContactStyle()
        style.quiet = True
        for i, p in enumerate(ports):
            src = "%s/%d" % (name, i)
            while not yarp.Network.isConnected(src, target, style):
                if yarp.Network.exists(target, True):
                    yarp.Network.connect(src, target, "", True)
                    if yarp.Network.isConnected(src, target, style):
                        break
                if time.monotonic() > end:
                    peer_io.emit("error", message="%s: no connection to %s in %s s" % (src, target, limit))
                    return
                time.sleep(0.05)
        peer_io.emit("connected", n=len(ports))

    def batch(calls):
        t0 = time.time()
        threads = [threading.Thread(target=lambda i=i, mine=mine: [call(i, c.get("id"), c["data"]) for c in mine])
                   for i, mine in enumerate(calls)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        peer_io.emit("batch", n=sum(len(m) for m in calls), t0=t0, t1=time.time())

    peer_io.emit("ready")
    q = peer_io.commands()
    while True:
        c = q.get()
        if c is None or c.get("cmd") == "quit":
            break
        if c["cmd"] == "connect":
            threading.Thread(target=connect, args=(float(c.get("timeout") or 30.0),), daemon=True).start()
        elif c["cmd"] == "call":
            threading.Thread(target=call, args=(int(c.get("client") or 0), c.get("id"), c["data"]),
                             daemon=True).start()
        elif c["cmd"] == "batch":
            threading.Thread(target=batch, args=(c["calls"],), daemon=True).start()
    for p in ports:
        p.interrupt()
        p.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
