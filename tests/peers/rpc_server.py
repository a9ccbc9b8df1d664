"""A YARP RPC server peer (venv python with the yarp bindings of any YARP
version): answers the commands that arrive on its port by a script, and
says what it got.

Config: {"port": "/robot/rpc:i", "rules": [rule, ...]}
A rule: {"match": "home" (the command's text, Bottle::toString, starts with
it; "" or absent: every command),
         "reply": [...] (a fixed reply Bottle: bottle_codec's values)
         | "echo": true (the command itself, after "prefix": [...])
         | "garbage": true (a reply that fits no declaration: a nested list and a number),
         "delay": seconds before replying (default 0)}
The first rule that matches answers; a command no rule matches gets
["nack", "no rule for", <its text>].
Commands: {"cmd": "rules", "rules": [...]} (replaces them; event "rules"),
          {"cmd": "count"} (event "count", n: commands got so far), {"cmd": "quit"}.
Events: ready; command (n, data, types, text, t: when it arrived);
        replied (n, data, text, t: when the reply was written).

The commands are read in YARP's own thread for each connection (a
PortReader, as the runtime's RPC port does): no binding call blocks while
holding the interpreter lock (YARP 3.12's bindings keep it in some).
"""
import threading
import time

import bottle_codec
import peer_io
import yarp

GARBAGE = [["garbage", 1.5], 42]


class Server(yarp.PortReader):
    def __init__(self, rules):
        yarp.PortReader.__init__(self)
        self.rules = rules
        self.lock = threading.Lock()
        self.n = 0

    def rule_for(self, text):
        with self.lock:
            rules = list(self.rules)
        for r in rules:
            if text.startswith(r.get("match") or ""):
                return r
        return None

    def read(self, connection):
        try:
            command = yarp.Bottle()
            if not command.read(connection):
                return False
            t = time.time()
            data, types = bottle_codec.to_py(command)
            text = command.toString()
            with self.lock:
                n = self.n
                self.n += 1
            peer_io.emit("command", n=n, data=data, types=types, text=text, t=t)
            rule = self.rule_for(text)
            delay = float((rule or {}).get("delay") or 0)
            if delay > 0:
                time.sleep(delay)
            reply = yarp.Bottle()
            if rule is None:
                bottle_codec.fill(reply, ["nack", "no rule for", text])
            elif rule.get("echo"):
                # the command's own values, with their own wire types
                bottle_codec.fill(reply, list(rule.get("prefix") or []))
                for i in range(command.size()):
                    reply.add(command.get(i))
            elif rule.get("garbage"):
                bottle_codec.fill(reply, GARBAGE)
            else:
                bottle_codec.fill(reply, list(rule.get("reply") or []))
            writer = connection.getWriter()
            if writer is not None:
                reply.write(writer)
            peer_io.emit("replied", n=n, data=bottle_codec.to_py(reply)[0], text=reply.toString(),
                         t=time.time())
            return True
        except Exception as e:  # never a traceback out of YARP's thread
            peer_io.emit("error", message="%s: %s" % (type(e).__name__, e))
            return False


def main():
    cfg = peer_io.config()
    peer_io.exit_on_signals()
    yarp.Network.init()
    server = Server(cfg.get("rules") or [])
    port = yarp.RpcServer()
    port.setReader(server)
    if not port.open(cfg["port"]):
        peer_io.emit("error", message="cannot open " + cfg["port"])
        return 1
    peer_io.emit("ready")
    q = peer_io.commands()
    while True:
        c = q.get()
        if c is None or c.get("cmd") == "quit":
            break
        if c["cmd"] == "rules":
            with server.lock:
                server.rules = c.get("rules") or []
            peer_io.emit("rules", n=len(server.rules))
        elif c["cmd"] == "count":
            with server.lock:
                n = server.n
            peer_io.emit("count", n=n)
    port.interrupt()
    port.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
