"""The subjects of the bridge benchmark (bench/run.py) and their rigs: the
shapes of the workloads, what each subject is, and one subject wired up
(source -> [module] -> sink), with a name server and a ROS 2 domain of its
own (Isolated), several started and stopped at once (start_rigs, stop_rigs).
bench/run.py, bench/compare.py and bench/profile.py run them.
"""
from __future__ import annotations

import re
import threading
from dataclasses import dataclass
from typing import Optional

import blocks as h
from blocks import BenchError, mw

BENCH = h.BENCH


@dataclass(frozen=True)
class Shape:
    name: str
    config: str
    ros2_config: str
    ports: int
    width: int
    label: str


SHAPES = {
    "joints": Shape("joints", "joints_2x15.ini", "joints_2x15_ros2.ini", 2, 15,
                    "2 ports x 15 float64 (30-joint state)"),
    "wide": Shape("wide", "wide_4x50.ini", "wide_4x50_ros2.ini", 4, 50, "4 ports x 50 float64"),
}
SUBJECTS = ("direct", "relay", "relay-strict", "cpp", "py", "ros2", "cpp-ros2", "rclpy", "rcl", "rcl-relay")
# the subjects of the fixed-rate and memory stages (relay-strict is
# event-driven only: it is the floor of the latency stage's CPU)
MODULES = ("relay", "cpp", "py", "ros2", "cpp-ros2")
# the memory stage's: the modules, and the floor of cpp-ros2 (event-driven only)
MEMORY_SUBJECTS = MODULES + ("rcl-relay",)
FLOORS = ("direct", "relay", "relay-strict")  # nothing generated: always available
ROS2_OUT = ("ros2", "cpp-ros2", "rclpy", "rcl", "rcl-relay")
ROS2_ONLY = ("rclpy", "rcl")  # a ROS 2 hop alone, no YARP
GENERATED = ("cpp", "py", "ros2", "cpp-ros2", "rcl", "rcl-relay")  # the subjects built (rcl, rcl-relay: bench/rcl)
DESCRIPTION = {
    "direct": "producer -> consumer, one YARP hop (no bridge)",
    "relay": "hand-written C++ relay (bench/relay/relay.cpp), two YARP hops: the floor",
    "relay-strict": "hand-written C++ relay reading as strictly as the C++ module "
                    "(bench/relay/strict_relay.cpp): the floor of the same work",
    "cpp": "generated C++ module (--backend cpp)",
    "py": "generated Python module (--backend py)",
    "ros2": "generated ROS 2 node (--backend ros2): YARP in, ROS 2 JointState out",
    "cpp-ros2": "generated C++ module publishing through rcl (--backend cpp): YARP in, ROS 2 JointState out",
    "rclpy": "bare rclpy publisher -> rclpy subscriber, one ROS 2 hop (reference)",
    "rcl": "bare rcl publisher (bench/rcl) -> rclpy subscriber, one ROS 2 hop: the C rcl hop",
    "rcl-relay": "hand-written C++ relay from YARP ports to a ROS 2 JointState through rcl "
                 "(bench/rcl/rcl_relay.cpp): the floor of cpp-ros2's chain",
}

STALL_EVERY, STALL_FOR = 3.0, 2.0   # the stalling consumer of the memory stage


# --------------------------------------------------------------------------
# one subject wired up: source -> [module] -> sink


class Rig:
    """The processes of one subject on one shape: source, module, sink."""

    def __init__(self, ctx: dict, subject: str, shape: Shape, rate: Optional[float],
                 stall: bool = False, record: bool = True, wrap: Optional[list] = None):
        self.ctx, self.subject, self.shape, self.rate = ctx, subject, shape, rate
        self.stall, self.record = stall, record
        self.wrap = list(wrap or [])  # a command the module runs under (bench/profile.py: valgrind)
        self.module: Optional[mw.Proc] = None
        self.source: Optional[h.Source] = None
        self.sink: Optional[h.Sink] = None
        self.per_block = subject == "direct"
        self.ticks_total = 0       # ticks the source sent (every run)
        self.received_total = 0    # records the sink received (every run)
        self.kind = subject.split("+")[0]

    # names of the YARP ports of the producer
    def src_ports(self) -> list:
        return [f"/bench/src{i}:o" for i in range(self.shape.ports)]

    def start(self) -> "Rig":
        ctx, sh = self.ctx, self.shape
        s = self.subject.split("+")[0]  # "cpp+variant": a variant's binary, run as cpp
        tools = ctx["tools"]
        yenv = ctx.get("yarp_env")
        renv = dict(ctx["ros2_env"]) if ctx.get("ros2_env") else None
        stall = (["--stall-every", str(STALL_EVERY), "--stall-for", str(STALL_FOR)]
                 if self.stall else [])
        norec = [] if self.record else ["--no-record"]
        tag = ctx.get("tag", "")
        try:
            if s == "rclpy":
                self.source = h.Source([h.PYTHON, BENCH / "peers" / "ros2_source.py",
                                        "--width", sh.width, "--blocks", sh.ports],
                                       env=renv, name=f"ros2_source{tag}").start()
            elif s == "rcl":
                self.source = h.Source([ctx["subjects"]["rcl"][sh.name], "--width", sh.width,
                                        "--blocks", sh.ports], env=renv, name=f"rcl_source{tag}").start()
            else:
                self.source = h.Source([tools["producer"], "--ports", ",".join(self.src_ports()),
                                        "--width", sh.width], env=yenv,
                                       name=f"producer{tag}").start()
            if s in ROS2_OUT:
                scale = "deg" if s in ("ros2", "cpp-ros2", "rcl-relay") else "1"
                self.sink = h.Sink([h.PYTHON, BENCH / "peers" / "ros2_sink.py", "--width", sh.width,
                                    "--scale", scale, *stall, *norec], env=renv,
                                   name=f"ros2_sink{tag}").start()
            else:
                if s == "direct":
                    sources = self.src_ports()
                elif s == "relay":
                    sources = ["/bench/relay/out:o"]
                elif s == "relay-strict":
                    sources = ["/bench/relay_strict/out:o"]
                else:
                    sources = [f"/bench_{sh.name}/out:o"]
                argv = [tools["consumer"], "--port", "/bench/sink:i", "--width", sh.width,
                        "--scale", "1" if s == "direct" else "deg", *stall, *norec]
                for src in sources:
                    argv += ["--source", src]
                self.sink = h.Sink(argv, env=yenv, name=f"consumer{tag}").start()
            rate_args = []
            info = ctx["subjects"].get(self.subject, {})
            if s == "relay":
                argv = [tools["relay"], "--inputs", ",".join(self.src_ports()),
                        "--output", "/bench/relay/out:o", "--prefix", "/bench/relay"]
                if self.rate:
                    argv += ["--rate", self.rate]
                self.module = mw.Proc(argv, env=yenv, name=f"relay{tag}", die_with_parent=True)
            elif s == "relay-strict":
                argv = [tools["relay-strict"], "--inputs", ",".join(self.src_ports()),
                        "--width", sh.width, "--output", "/bench/relay_strict/out:o",
                        "--prefix", "/bench/relay_strict"]
                self.module = mw.Proc(argv, env=yenv, name=f"relay_strict{tag}",
                                      die_with_parent=True)
            elif s == "cpp":
                if self.rate:
                    rate_args = ["--rate", self.rate]
                self.module = mw.Proc([info[sh.name], "--prefix", "/bench/cpp", *rate_args],
                                      env=yenv, name=f"cpp_module{tag}", die_with_parent=True)
            elif s == "py":
                if self.rate:
                    rate_args = ["--rate", self.rate]
                self.module = mw.Proc([h.PYTHON, info[sh.name], "--prefix", "/bench/py", *rate_args],
                                      env=yenv, name=f"py_module{tag}", die_with_parent=True)
            elif s == "rcl-relay":
                env = dict(yenv)
                env.update(ctx["ros2_vars"])
                self.module = mw.Proc([info[sh.name], "--inputs", ",".join(self.src_ports()),
                                       "--prefix", "/bench/rcl_relay"],
                                      env=env, name=f"rcl_relay{tag}", die_with_parent=True)
            elif s == "cpp-ros2":
                env = dict(yenv)
                env.update(ctx["ros2_vars"])
                if self.rate:
                    rate_args = ["--rate", self.rate]
                self.module = mw.Proc([info[sh.name], "--prefix", "/bench/cpp_ros2", *rate_args],
                                      env=env, name=f"cpp_ros2_module{tag}", die_with_parent=True)
            elif s == "ros2":
                env = dict(yenv)
                env.update(ctx["ros2_vars"])
                params = ["-p", "prefix:=/bench/ros2"]
                if self.rate:
                    params += ["-p", f"rate:={float(self.rate)}"]
                self.module = mw.Proc([h.PYTHON, info[sh.name], "--ros-args", *params],
                                      env=env, name=f"ros2_node{tag}", die_with_parent=True)
            if self.module is not None:
                self.module.argv = [str(a) for a in self.wrap] + self.module.argv
                self.module.start()
            self.sink.wait_connected(timeout=30, proc=self.module)
            self.source.wait_outputs(1, timeout=30, proc=self.module)
        except BaseException:
            self.stop()
            raise
        return self

    def check_alive(self) -> None:
        if self.module is not None and not self.module.alive:
            raise BenchError(f"{self.module.name} exited (status {self.module.returncode}); log:\n"
                             f"{self.module.log_text()[-3000:]}")

    def stop(self) -> Optional[int]:
        status = None
        if self.source is not None:
            self.source.quit()
        if self.module is not None:
            status = self.module.stop(timeout=5)
        if self.sink is not None:
            self.sink.quit()
        return status

    def totals(self) -> dict:
        """The totals a generated module prints at exit (docs/runtime.md):
        published messages and skipped cycles (after stop())."""
        text = self.module.log_text() if self.module is not None else ""
        out = {}
        m = re.search(r"published (\d+) messages, skipped (\d+) cycles", text)
        if m:
            out = {"module_published": int(m.group(1)), "module_skipped_cycles": int(m.group(2))}
        received = [int(x) for x in re.findall(r"input \S+: received (\d+)", text)]
        if received:
            out["module_inputs_received"] = received
        return out


# --------------------------------------------------------------------------
# rigs of their own name server and ROS 2 domain, up at once


class Isolated:
    """A name server and/or a ROS 2 domain of one rig's own, so that several
    rigs (whose configs use the same port and topic names) can be up at once."""

    def __init__(self, ctx: dict, subject: str, tag: str = ""):
        self.base, self.subject, self.tag = ctx, subject, tag
        self.server: Optional[mw.YarpServer] = None
        self.domain: Optional[mw.Ros2Domain] = None

    def start(self) -> dict:
        ctx = dict(self.base, tag=self.tag)
        try:
            kind = self.subject.split("+")[0]
            if kind not in ROS2_ONLY:
                self.server = mw.YarpServer().start()
                ctx["yarp_env"] = self.server.env
            if kind in ROS2_OUT:
                self.domain = mw.Ros2Domain().start()
                env = dict(self.domain.env)
                if self.server is not None:
                    env.update(self.server.env)
                env.update(self.domain.ros_env)
                ctx["ros2_env"] = env
                ctx["ros2_vars"] = self.domain.ros_env
        except BaseException:
            self.stop()
            raise
        return ctx

    def stop(self) -> None:
        if self.server is not None:
            self.server.stop()
        if self.domain is not None:
            self.domain.stop()


def start_rigs(ctx: dict, subjects: list, shape: Shape, stall: bool = False,
               record: bool = True, tag: str = "") -> dict:
    """Starts the rigs of ``subjects`` at once (threads: each mostly waits
    for its processes), each isolated; {subject: (Isolated, Rig) or error}."""
    out: dict = {}
    lock = threading.Lock()

    def one(s):
        iso = Isolated(ctx, s, tag=f"{tag}_{s}")
        try:
            rig = Rig(iso.start(), s, shape, None, stall=stall, record=record).start()
            got = (iso, rig)
        except (BenchError, OSError, RuntimeError, TimeoutError) as e:
            iso.stop()
            got = str(e).strip() or type(e).__name__
        with lock:
            out[s] = got

    threads = [threading.Thread(target=one, args=(s,), daemon=True) for s in subjects]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return {s: out[s] for s in subjects}


def stop_rigs(rigs: dict) -> dict:
    """Stops the rigs at once; {subject: the module's exit status}."""
    out: dict = {}

    def one(s, rig):
        try:
            out[s] = rig.stop()
        except Exception as e:  # noqa: BLE001 (reported as the status)
            out[s] = f"stop failed: {e}"

    threads = [threading.Thread(target=one, args=(s, r), daemon=True) for s, r in rigs.items()]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    return out
