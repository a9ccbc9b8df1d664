"""An rclpy service client peer (venv python): calls ROS 2 services and
records each response with its times; several callers at once, each with
clients of its own.

Config: {"node": "ybg_test_service_client", "callers": 1, "depth": 1000,
         "services": {"/icub/left_arm/home": "std_srvs/srv/Trigger", ...}}
Each client keeps the last ``depth`` responses (rclpy's default keeps 10):
Fast DDS delivers every response of a service to every client of it, each
taking its own, and with 8 callers a client's own response is otherwise
sometimes pushed out by the others' before it is taken (a lost call, with
any server).
Commands: {"cmd": "wait_service", "service": name, "timeout": s, "ready": true}:
            event "service" (service, ready: every caller's client sees the
            server); with "ready": false, waits until none sees one (ready:
            false once so)
          {"cmd": "call", "service": name, "id": x, "caller": i,
            "request": {...}, "timeout": s}: one call, event "response"
          {"cmd": "batch", "service": name, "requests": [[{...}, ...], ...],
            "timeout": s}: one list per caller, each caller's calls one after
            another, the callers at once (ids "<caller>.<k>"); a "response"
            event per call, then "batch" (service, n, t0, t1)
          {"cmd": "quit"}
Events: ready; service (service, ready); response (service, id, caller, k,
        response: the response's fields, or null when none came within the
        timeout; timed_out; t0: before the call; t1: when the response
        arrived, or the timeout ended); batch (service, n, t0, t1).
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
    from rclpy.qos import QoSProfile
    from rclpy.signals import SignalHandlerOptions

    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node(cfg.get("node") or "ybg_test_service_client")
    group = ReentrantCallbackGroup()
    callers = int(cfg.get("callers") or 1)
    classes = {name: msg_class(t) for name, t in cfg["services"].items()}
    qos = QoSProfile(depth=int(cfg.get("depth") or 1000))
    clients = {name: [node.create_client(cls, name, qos_profile=qos, callback_group=group) for _ in range(callers)]
               for name, cls in classes.items()}
    ex = MultiThreadedExecutor(num_threads=4)
    ex.add_node(node)
    threading.Thread(target=ex.spin, daemon=True).start()

    def call(service, i, ident, k, fields, timeout):
        client = clients[service][i]
        request = fill(classes[service].Request(), fields or {})
        done = threading.Event()
        arrived = []

        def on_done(_future):
            arrived.append(time.time())
            done.set()

        t0 = time.time()
        future = client.call_async(request)
        future.add_done_callback(on_done)
        if done.wait(timeout) and future.result() is not None:
            peer_io.emit("response", service=service, id=ident, caller=i, k=k,
                         response=to_py(future.result()), timed_out=False, t0=t0, t1=arrived[0])
        else:
            client.remove_pending_request(future)
            peer_io.emit("response", service=service, id=ident, caller=i, k=k, response=None,
                         timed_out=True, t0=t0, t1=time.time())

    def batch(service, requests, timeout):
        t0 = time.time()

        def run(i, mine):
            for k, fields in enumerate(mine):
                call(service, i, "%d.%d" % (i, k), k, fields, timeout)
        threads = [threading.Thread(target=run, args=(i, mine)) for i, mine in enumerate(requests)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        peer_io.emit("batch", service=service, n=sum(len(m) for m in requests), t0=t0, t1=time.time())

    def wait_service(service, timeout, want):
        end = time.monotonic() + timeout
        if want:
            ready = all(c.wait_for_service(timeout_sec=max(0.0, end - time.monotonic()))
                        for c in clients[service])
        else:
            while any(c.service_is_ready() for c in clients[service]) and time.monotonic() < end:
                time.sleep(0.02)
            ready = any(c.service_is_ready() for c in clients[service])
        peer_io.emit("service", service=service, ready=ready)

    peer_io.emit("ready")
    q = peer_io.commands()
    while True:
        c = q.get()
        if c is None or c.get("cmd") == "quit":
            break
        timeout = float(c.get("timeout") or 10.0)
        if c["cmd"] == "wait_service":
            threading.Thread(target=wait_service, args=(c["service"], timeout, c.get("ready", True)),
                             daemon=True).start()
        elif c["cmd"] == "call":
            threading.Thread(target=call, args=(c["service"], int(c.get("caller") or 0), c.get("id"), 0,
                                                c.get("request"), timeout), daemon=True).start()
        elif c["cmd"] == "batch":
            threading.Thread(target=batch, args=(c["service"], c["requests"], timeout), daemon=True).start()
    os._exit(0)  # rclpy threads stop with the process


if __name__ == "__main__":
    raise SystemExit(main())
