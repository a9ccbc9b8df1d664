"""An rclpy service server peer (venv python): answers ROS 2 services by a
script and records every request.

Config: {"node": "ybg_test_service_server",
         "services": {"/robot/home": {"type": "std_srvs/srv/Trigger",
                                      "response": {field: value, ...},
                                      "delay": seconds}, ...}}
A response value that is a string is formatted with the request's fields
and n (the service's request number from 0): "homed {n}", "x {x}"; a string
"=field" is the request's field itself (SetBool: "success": "=data").
Each request is answered in a thread of its own (a delay holds up only its
own request).
Commands: {"cmd": "script", "service": name, "response": {...}, "delay": s}
            (event "script"), {"cmd": "quit"} (the node destroyed and rclpy
            shut down, as a server ends: its clients see it go at once).
Events: ready; request (service, n, request, t: when it arrived);
        responded (service, n, response, t: when the callback returned it).
"""
import os
import threading
import time

import peer_io
from rclpy_peer import fill, msg_class, to_py


def main():
    cfg = peer_io.config()
    peer_io.exit_on_signals()
    import rclpy
    from rclpy.callback_groups import ReentrantCallbackGroup
    from rclpy.executors import MultiThreadedExecutor
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(cfg.get("node") or "ybg_test_service_server")
    lock = threading.Lock()
    group = ReentrantCallbackGroup()
    state = {}

    def serve(name, spec):
        state[name] = {"n": 0, "response": spec.get("response") or {},
                       "delay": float(spec.get("delay") or 0)}

        def answer(request, response):
            t = time.time()
            req = to_py(request)
            with lock:
                s = state[name]
                n = s["n"]
                s["n"] += 1
                script = dict(s["response"])
                delay = s["delay"]
            peer_io.emit("request", service=name, n=n, request=req, t=t)
            if delay > 0:
                time.sleep(delay)
            values = {}
            for k, v in script.items():
                if isinstance(v, str) and v.startswith("="):
                    v = req[v[1:]]
                elif isinstance(v, str):
                    v = v.format(n=n, **req)
                values[k] = v
            fill(response, values)
            peer_io.emit("responded", service=name, n=n, response=to_py(response), t=time.time())
            return response

        node.create_service(msg_class(spec["type"]), name, answer, callback_group=group)

    for name, spec in cfg["services"].items():
        serve(name, spec)
    ex = MultiThreadedExecutor(num_threads=12)
    ex.add_node(node)
    # the executor in a thread of its own: the main thread takes the commands,
    # and the signals (a thread blocked in rclpy's wait would never see them)
    threading.Thread(target=ex.spin, daemon=True).start()
    q = peer_io.commands()
    peer_io.emit("ready")
    while True:
        c = q.get()
        if c is None or c.get("cmd") == "quit":
            try:
                ex.shutdown(timeout_sec=1.0)
                node.destroy_node()
                rclpy.shutdown()
            finally:
                os._exit(0)  # rclpy threads stop with the process
        if c["cmd"] == "script":
            with lock:
                s = state[c["service"]]
                if "response" in c:
                    s["response"] = c["response"] or {}
                if "delay" in c:
                    s["delay"] = float(c["delay"] or 0)
            peer_io.emit("script", service=c["service"])


if __name__ == "__main__":
    raise SystemExit(main())
