"""Benchmark of `ybgc compose`: a whole robot's bridges in one native process
against the same bridges as separate native modules (and, with
``--subjects cpp,ros2``, the composed rclpy node against separate rclpy
nodes).

    .venv/bin/python bench/compose.py                full run: writes bench/results/compose.json
                                                     and the section "A whole robot in one process"
                                                     of docs/benchmarks.md
    .venv/bin/python bench/compose.py --quick        a smoke run: bench/results/quick/compose.json
    .venv/bin/python bench/compose.py --report-only [--results FILE]
                                                     the docs section from a JSON

The robots: the 12 stream configs of examples/icub_robot (its camera and
its trajectory into YARP left out: they need peers of their own), each
input declared 16 float64 wide and each bridge event-driven, so that a
producer at 100 Hz makes each bridge publish at 100 Hz (one message a
Bottle: the latency is the bridge's and the middleware's, with no wait for
a fixed rate's cycle); and a 24-config robot, two of them (the second's
modules, ports and topics under icub2). Everything runs on 127.0.0.1, each
arm with its own yarpserver and ROS 2 domain (the test suite's helpers,
tests/harness/, through bench/blocks.py); the modules are generated from
the working tree's ybgc and built with CMake (Release) against the venv's
YARP 3.5 and ROS 2 wheels under bench/build/compose/.

Each arm, for a robot: one bench_producer (bench/tools/producer.cpp) writes
every input port at 100 Hz, each Bottle's envelope the tick's
CLOCK_MONOTONIC time, which every bridge puts in its message's header.stamp
(timestamp(mux)); one C++ rcl subscriber of every topic
(bench/rcl/stamp_sink.cpp: best effort, keep the last 1000; one thread takes
every message as soon as it is there, so that the sink is not what the
latency measures) records each message's stamp and its receive time
(CLOCK_MONOTONIC): the latency. Then the bridges start: composed, one
process; separate, one process a bridge, all started at once; alone, one
bridge by itself (each of the 12 in turn). Measured: the time from the
start to the first message of every bridge; after 3 s, over a window of
--seconds: each bridge's median and p99 latency, the CPU of the bridges'
processes, their RSS, threads and sockets (sums for separate processes).
"""
from __future__ import annotations

import argparse
import json
import os
import re
import sys
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Optional

sys.path.insert(0, str(Path(__file__).resolve().parent))

import blocks as h  # noqa: E402
from blocks import BenchError, mw  # noqa: E402
from report import fmt_load, loadavg, write_section  # noqa: E402

ROOT = h.ROOT
BENCH = h.BENCH
DOCS = ROOT / "docs" / "benchmarks.md"
SECTION = "## A whole robot in one process"
ICUB = ROOT / "examples" / "icub_robot"
#: the configs of the robot: every stream config of examples/icub_robot from YARP ports to ROS 2
LEFT_OUT = ("left_eye.ini", "trajectory.ini")
WIDTH = 16
RATE = 100.0
SUBJECTS = ("cpp", "ros2")



def say(text: str) -> None:
    print(text, flush=True)


# --------------------------------------------------------------------------
# the robots


def bench_config(text: str, robot: str) -> str:
    """An iCub config made the benchmark's: every input 16 float64 wide,
    event-driven; ``robot`` "icub2": its module, ports and topics the second
    robot's."""
    joints = re.search(r"(?m)^ports = \S+ \(float64 x(\d+)\)\nconvert = deg_to_rad\n", text)
    if joints and re.search(r"(?m)^position = joints$", text):  # a joint state: as many positions as names
        text = re.sub(r"(?m)^position = joints$", f"position = joints[0:{joints.group(1)}]", text)
    text = re.sub(r"\(float64 x\d+\)", f"(float64 x{WIDTH})", text)
    text = re.sub(r"(?m)^rate = .*\n", "", text)
    if robot != "icub":
        text = re.sub(r"(?m)^name = icub_", f"name = {robot}_", text)
        text = text.replace("/icub/", f"/{robot}/")
        text = re.sub(r"(?m)^topic = /(?!" + robot + r"/)", f"topic = /{robot}/", text)
    return text


class Bridge:
    """One bridge of a robot: its config, module, input ports, topic, type,
    and the key of its messages at the sink."""

    def __init__(self, path: Path, config: str):
        self.path = path
        self.config = config
        self.module = re.search(r"(?m)^name = (\S+)", config).group(1)
        self.ports = re.findall(r"(?m)^ports = (\S+)", config)
        self.topic = re.search(r"(?m)^topic = (\S+)", config).group(1)
        self.type = re.search(r"(?m)^type = (\S+)", config).group(1)
        first = re.search(r'(?m)^name = "([^"]+)"', config)
        self.key = f"{self.topic}|{first.group(1)}" if self.type == "sensor_msgs/JointState" else self.topic


def robot_configs(folder: Path, robots: tuple) -> list:
    """The configs of ``robots`` ("icub", "icub2") written in ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    bridges = []
    for robot in robots:
        for src in sorted(ICUB.glob("*.ini")):
            if src.name in LEFT_OUT:
                continue
            text = bench_config(src.read_text(), robot)
            path = folder / f"{robot}_{src.name}"
            path.write_text(text)
            bridges.append(Bridge(path, text))
    return bridges


# --------------------------------------------------------------------------
# building


def build_composed(bridges: list, name: str, backend: str, out: Path) -> Path:
    """``ybgc compose`` of the bridges' configs; built (cpp): the executable,
    else the composed node's script."""
    src = out / "src"
    src.mkdir(parents=True, exist_ok=True)
    r = h.run_cmd([h.YBGC, "compose", *[b.path for b in bridges], "--backend", backend, "--name", name,
                   "-o", src, "--force"], timeout=300)
    if r.returncode:
        raise BenchError(f"ybgc compose --backend {backend} failed:\n{(r.stdout + r.stderr)[-3000:]}")
    if backend == "ros2":
        return src / f"{name}_node.py"
    h.cmake_build(src, out / "build", options=(f"-DYBGC_ROS2_PYTHON_ENV={mw.VENV}",))
    return out / "build" / name


def build_separate(bridges: list, backend: str, out: Path) -> dict:
    """Each bridge's module (``ybgc CONFIG``): {module: executable or script}."""
    modules = {}
    src = out / "src"
    for b in bridges:
        folder = src / b.module
        h.generate(b.path, backend, folder)
        modules[b.module] = folder / (f"{b.module}_node.py" if backend == "ros2" else b.module)
    if backend == "cpp":
        # one CMake project of them all: the runtime library built once
        (src / "CMakeLists.txt").write_text(
            "cmake_minimum_required(VERSION 3.16)\nproject(bench_compose_separate CXX)\n"
            "find_package(YARP REQUIRED COMPONENTS os)\nfind_package(Threads REQUIRED)\n"
            + "".join(f"add_subdirectory({b.module})\n" for b in bridges))
        h.cmake_build(src, out / "build", options=(f"-DYBGC_ROS2_PYTHON_ENV={mw.VENV}",))
        modules = {b.module: out / "build" / b.module / b.module for b in bridges}
    return modules


# --------------------------------------------------------------------------
# one arm


class Sink(h.LinePeer):
    def first(self) -> dict:
        return json.loads(self.ask("first"))


def pss_kb(pid: int) -> int:
    """The proportional set size of a process, kB: its pages, those it shares
    with other processes (the libraries of separate modules) divided among them."""
    try:
        for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
            if line.startswith("Pss:"):
                return int(line.split()[1])
    except (OSError, ValueError, IndexError):
        pass
    return 0


def process_facts(pids: list) -> dict:
    """RSS and PSS (kB), threads and sockets of the processes, summed."""
    rss = pss = threads = sockets = 0
    for pid in pids:
        rss += h.memory_kb(pid).get("VmRSS", 0)
        pss += pss_kb(pid)
        try:
            threads += len(os.listdir(f"/proc/{pid}/task"))
            for fd in os.listdir(f"/proc/{pid}/fd"):
                try:
                    if os.readlink(f"/proc/{pid}/fd/{fd}").startswith("socket:"):
                        sockets += 1
                except OSError:
                    pass
        except OSError:
            pass
    return {"rss_kb": rss, "pss_kb": pss, "threads": threads, "sockets": sockets, "processes": len(pids)}


def latency(records: list, keys: dict) -> dict:
    """{module: {"n", "median_us", "p99_us"}} of the records (key, stamp, recv)."""
    by_key: dict = {}
    for key, stamp, recv in records:
        if stamp > 0:
            by_key.setdefault(key, []).append(recv - stamp)
    out = {}
    for module, key in keys.items():
        lat = sorted(by_key.get(key, []))
        out[module] = {"n": len(lat), "median_us": h.quantile(lat, 0.5) * 1e6 if lat else None,
                       "p99_us": h.quantile(lat, 0.99) * 1e6 if lat else None}
    return out


#: what a module says when YARP's name server gave its port an address still
#: in use (a name registered again at once, its old port handed to another)
PORT_TAKEN = "failed to activate (invalid address)"


def start_to_first(sink, procs: list, keys: dict, label: str, t0: Optional[float] = None,
                   wait: float = 60.0, retries: Optional[list] = None) -> dict:
    """Start ``procs`` (unless ``t0``, when they were started); the seconds
    from then to the first message of each bridge ({module: s}) at the sink.
    A process that exits because YARP gave its port an address in use is
    started again, once (noted in ``retries``)."""
    sink.ask("clear_first")
    if t0 is None:
        t0 = time.monotonic()
        for p in procs:
            p.start()
    end = time.monotonic() + wait
    first: dict = {}
    while time.monotonic() < end:
        first = sink.first()
        if all(k in first for k in keys.values()):
            break
        for p in procs:
            if not p.alive:
                log = p.log_text()
                start = log.rfind("==== start")
                if retries is not None and PORT_TAKEN in log[start:] and p.name not in retries:
                    retries.append(p.name)
                    p.start()
                    continue
                raise BenchError(f"{p.name} exited ({p.returncode}): {log[-2000:]}")
        time.sleep(0.05)
    missing = [m for m, k in keys.items() if k not in first]
    if missing:
        raise BenchError(f"{label}: no message of {', '.join(missing)} within {wait:.0f} s")
    return {m: first[k] - t0 for m, k in keys.items()}


def run_arm(ctx: dict, bridges: list, commands: list, label: str, seconds: float,
            env_extra: Optional[dict] = None, restarts: int = 0) -> dict:
    """Start ``commands`` (one argv a process) beside a producer of every
    input port of ``bridges`` and a sink of every topic; measure. Then stop
    them and start them again ``restarts`` times, for the start alone."""
    tmp = Path(ctx["tmp"])
    server = domain = producer = sink = None
    procs: list = []
    try:
        server = mw.YarpServer().start()
        domain = mw.Ros2Domain().start()
        env = mw.ros2_environment(server.env, domain)
        ports = [p for b in bridges for p in b.ports]
        # plain writes, as a robot's devices write: a strict write waits for
        # a connection of a stopped bridge whose send may never complete
        producer = h.Source([ctx["producer"], "--ports", ",".join(ports), "--width", str(WIDTH),
                             "--write", "plain"], env,
                            f"producer_{label}").start()
        subs = [a for topic, kind in sorted({(b.topic, b.type) for b in bridges}) for a in ("--sub", f"{topic}={kind}")]

        def new_sink() -> Sink:
            return Sink([ctx["sink"], *subs], env, f"sink_{label}").start(timeout=60)
        sink = new_sink()
        # the producer runs until stopped: every port at 100 Hz
        producer.popen.stdin.write(f"run {10 ** 7} {RATE}\n".encode())
        producer.popen.stdin.flush()
        time.sleep(0.5)
        procs = [mw.Proc(argv, env=env, name=f"{label}_{k}", die_with_parent=True) for k, argv in enumerate(commands)]
        keys = {b.module: b.key for b in bridges}
        sink_faults: list = []
        port_retries: list = []

        def started(first_start: bool) -> dict:
            """One start of the processes; a sink that received nothing at
            all from them in 30 s is asked what it matched and replaced by a
            new one (noted in "sink_faults"), which waits for their first
            messages again."""
            nonlocal sink
            t0 = time.monotonic()
            try:
                return start_to_first(sink, procs, keys, label, wait=30.0, retries=port_retries)
            except BenchError:
                if sink.first():
                    raise
                fault = {"start": "first" if first_start else "again", "matched": sink.ask("matched")}
                sink.quit()
                sink = new_sink()
                try:
                    start_to_first(sink, procs, keys, label, t0=t0, wait=30.0)
                    fault["new_sink"] = "received every bridge"
                except BenchError as e:
                    fault["new_sink"] = str(e).splitlines()[0]
                    sink_faults.append(fault)
                    raise BenchError(f"{label}: the sink received nothing, nor a new one: {fault}") from None
                sink_faults.append(fault)
                say(f"    the sink received nothing from a start; a new sink did ({fault['matched']})")
                return {m: float("nan") for m in keys}

        to_first = started(True)
        time.sleep(3.0)
        pids = [p.pid for p in procs]
        sink.ask("reset")
        c0 = [h.cpu_seconds(pid) or 0.0 for pid in pids]
        w0 = time.monotonic()
        time.sleep(seconds / 2)
        facts = process_facts(pids)
        time.sleep(seconds / 2)
        cpu = sum((h.cpu_seconds(pid) or 0.0) - c for pid, c in zip(pids, c0))
        window = time.monotonic() - w0
        path = tmp / f"{label}.json"
        sink.ask(f"dump {path}", timeout=60)
        records = json.loads(path.read_text())
        path.unlink()
        lat = latency(records, keys)
        out = {"start_to_first_s": {"all": max(to_first.values()),
                                    "median": h.quantile(sorted(to_first.values()), 0.5)},
               "cpu_percent": 100.0 * cpu / window, "window_s": window, **facts, "latency": lat,
               "messages_per_second": {m: v["n"] / window for m, v in lat.items()}}
        statuses = [p.stop(timeout=10, sig=mw.signal.SIGINT) for p in procs]
        out["exit_statuses"] = statuses
        # the start again: DDS discovery between a new participant and the
        # sink's is a race whose loser waits for the next announcement
        trials = [out["start_to_first_s"]["all"]]
        for _ in range(restarts):
            time.sleep(1.0)
            trials.append(max(started(False).values()))
            for p in procs:
                p.stop(timeout=10, sig=mw.signal.SIGINT)
        trials = [t for t in trials if t == t]  # a start the sink missed is not one
        out["start_to_first_s"]["trials"] = trials
        out["start_to_first_s"]["median_of_trials"] = h.quantile(sorted(trials), 0.5)
        out["sink_faults"] = sink_faults
        out["port_retries"] = port_retries
        return out
    finally:
        for p in procs:
            p.stop(timeout=5)
        for peer in (sink, producer):
            if peer is not None:
                peer.quit()
        if server is not None:
            server.stop()
        if domain is not None:
            domain.stop()


def summarize(arm: dict) -> str:
    lat = [v["median_us"] for v in arm["latency"].values() if v["median_us"] is not None]
    return (f"RSS {arm['rss_kb'] / 1024:.1f} MB, PSS {arm.get('pss_kb', 0) / 1024:.1f} MB, CPU {arm['cpu_percent']:.1f} %, threads {arm['threads']}, "
            f"sockets {arm['sockets']}, start to every first message {arm['start_to_first_s']['all']:.2f} s, "
            f"median latency (median of the bridges) {h.quantile(sorted(lat), 0.5) if lat else 0:.0f} us")


# --------------------------------------------------------------------------
# stages


def robot_stage(ctx: dict, args, name: str, robots: tuple, backend: str) -> dict:
    bridges = robot_configs(Path(ctx["tmp"]) / f"configs_{name}", robots)
    build_root = args.build_dir / backend / name
    say(f"{name} ({len(bridges)} bridges, {backend}): building")
    t0 = time.monotonic()
    composed = build_composed(bridges, name, backend, build_root / "composed")
    separate = build_separate(bridges, backend, build_root / "separate")
    run = (lambda path: [h.PYTHON, path]) if backend == "ros2" else (lambda path: [path])
    out = {"bridges": [b.module for b in bridges], "build_s": round(time.monotonic() - t0, 1)}
    say(f"  composed: one process of {len(bridges)} bridges")
    out["composed"] = run_arm(ctx, bridges, [run(composed)], f"{name}_{backend}_composed", args.seconds,
                              restarts=args.restarts)
    say(f"    {summarize(out['composed'])}")
    say(f"  separate: {len(bridges)} processes")
    out["separate"] = run_arm(ctx, bridges, [run(separate[b.module]) for b in bridges],
                              f"{name}_{backend}_separate", args.seconds, restarts=args.restarts)
    say(f"    {summarize(out['separate'])}")
    return out


def alone_stage(ctx: dict, args, backend: str) -> dict:
    """Each bridge of the first robot alone (its own process, nothing else)."""
    bridges = robot_configs(Path(ctx["tmp"]) / "configs_alone", ("icub",))
    separate = build_separate(bridges, backend, args.build_dir / backend / "icub12" / "separate")
    run = (lambda path: [h.PYTHON, path]) if backend == "ros2" else (lambda path: [path])
    out = {}
    say(f"alone ({backend}): each bridge by itself")
    for b in bridges[: args.alone or len(bridges)]:
        arm = run_arm(ctx, [b], [run(separate[b.module])], f"alone_{backend}_{b.module}", args.alone_seconds)
        out[b.module] = arm
        lat = arm["latency"][b.module]
        say(f"  {b.module}: RSS {arm['rss_kb'] / 1024:.1f} MB, CPU {arm['cpu_percent']:.1f} %, "
            f"median {lat['median_us']:.0f} us, p99 {lat['p99_us']:.0f} us")
    return out


# --------------------------------------------------------------------------
# report


def ratio(a, b) -> Optional[float]:
    return a / b if a is not None and b else None


def median_of(values) -> Optional[float]:
    values = sorted(v for v in values if v is not None)
    return h.quantile(values, 0.5) if values else None


def worst_bridge(composed: dict, separate: dict) -> tuple:
    """(composed / separate, module) of the bridge whose median latency grows
    most composed; (None, None) when no bridge has both."""
    return max(((ratio(v["median_us"], separate["latency"].get(m, {}).get("median_us")), m)
                for m, v in composed["latency"].items()
                if v["median_us"] is not None and separate["latency"].get(m, {}).get("median_us")),
               default=(None, None))


def figures(data: dict, backend: str) -> list:
    """Rows of the comparison table: (robot, quantity, composed, separate, ratio)."""
    rows = []
    alone = data.get("alone", {}).get(backend, {})
    alone_rss = median_of(a["rss_kb"] for a in alone.values())
    for robot, r in data.get("robots", {}).get(backend, {}).items():
        c, s = r.get("composed"), r.get("separate")
        if not c or not s:
            continue
        n = len(r["bridges"])
        rows.append((robot, "RSS (MB; separate: the sum)", c["rss_kb"] / 1024, s["rss_kb"] / 1024,
                     ratio(c["rss_kb"], s["rss_kb"])))
        if c.get("pss_kb") and s.get("pss_kb"):
            rows.append((robot, "PSS (MB; shared pages divided among the processes)", c["pss_kb"] / 1024,
                         s["pss_kb"] / 1024, ratio(c["pss_kb"], s["pss_kb"])))
        if alone_rss:
            rows.append((robot, "RSS: composed / one bridge alone", c["rss_kb"] / 1024, alone_rss / 1024,
                         ratio(c["rss_kb"], alone_rss)))
        rows.append((robot, "CPU (% of a core)", c["cpu_percent"], s["cpu_percent"],
                     ratio(c["cpu_percent"], s["cpu_percent"])))
        rows.append((robot, "threads", c["threads"], s["threads"], ratio(c["threads"], s["threads"])))
        rows.append((robot, "sockets", c["sockets"], s["sockets"], ratio(c["sockets"], s["sockets"])))
        cs, ss = c["start_to_first_s"], s["start_to_first_s"]
        if "trials" in cs and "trials" in ss:
            k = len(cs["trials"])
            rows.append((robot, f"start to a first message of every bridge (s; median of {k} starts)",
                         cs["median_of_trials"], ss["median_of_trials"],
                         ratio(cs["median_of_trials"], ss["median_of_trials"])))
            rows.append((robot, f"start to a first message of every bridge (s; the slowest of {k} starts)",
                         max(cs["trials"]), max(ss["trials"]), ratio(max(cs["trials"]), max(ss["trials"]))))
        else:
            rows.append((robot, "start to a first message of every bridge (s)", cs["all"], ss["all"],
                         ratio(cs["all"], ss["all"])))
        cm = median_of(v["median_us"] for v in c["latency"].values())
        sm = median_of(v["median_us"] for v in s["latency"].values())
        rows.append((robot, f"latency: median of the {n} bridges' medians (us)", cm, sm, ratio(cm, sm)))
        grows, m = worst_bridge(c, s)
        if m is not None:
            rows.append((robot, f"latency: the bridge whose median grows most composed (`{m}`, us)",
                         c["latency"][m]["median_us"], s["latency"][m]["median_us"], grows))
        cp = median_of(v["p99_us"] for v in c["latency"].values())
        sp = median_of(v["p99_us"] for v in s["latency"].values())
        rows.append((robot, f"latency: median of the {n} bridges' p99 (us)", cp, sp, ratio(cp, sp)))
    return rows


def targets(data: dict) -> list:
    """Rows of the targets table: (target, robot, measured, value, limit, result)."""
    rows = []
    for backend in data.get("backends", []):
        who = "native" if backend == "cpp" else "rclpy"
        alone = data.get("alone", {}).get(backend, {})
        alone_rss = median_of(a["rss_kb"] for a in alone.values())
        for robot, r in data.get("robots", {}).get(backend, {}).items():
            c, s = r.get("composed"), r.get("separate")
            if not c or not s:
                continue

            def row(target, measured, value, limit):
                met = value is not None and value <= limit
                rows.append((f"{who} {target}", robot, measured, value, limit, "met" if met else "missed"))

            if alone_rss:
                row("RSS <= 1.5 x one bridge alone", f"{c['rss_kb'] / 1024:.1f} / {alone_rss / 1024:.1f} MB",
                    ratio(c["rss_kb"], alone_rss), 1.5)
            row("CPU <= the separate processes' sum", f"{c['cpu_percent']:.1f} / {s['cpu_percent']:.1f} %",
                ratio(c["cpu_percent"], s["cpu_percent"]), 1.0)
            grows, m = worst_bridge(c, s)
            if m is not None:
                row("each bridge's median latency <= 1.1 x in its own process",
                    f"`{m}` {c['latency'][m]['median_us'] / 1000:.2f} / "
                    f"{s['latency'][m]['median_us'] / 1000:.2f} ms (the highest ratio)", grows, 1.1)
            cs = c["start_to_first_s"]
            trials = cs.get("trials") or [cs["all"]]
            median = cs.get("median_of_trials", cs["all"])
            row("start to a first message of every bridge < 2 s (median of the starts)", f"{median:.2f} s",
                median, 2.0)
            row("start to a first message of every bridge < 2 s (every start)",
                f"the slowest of {len(trials)}: {max(trials):.2f} s", max(trials), 2.0)
    return rows


def num(v, digits=1) -> str:
    if v is None:
        return "–"
    if isinstance(v, int):
        return str(v)
    return f"{v:.{digits}f}"


def section(data: dict) -> str:
    lines = [SECTION, ""]
    lines.append(
        "`ybgc compose` ([docs/compose.md](compose.md)): a robot's bridges in one native process (one "
        "YARP network, one rcl context, one node per bridge) against the same bridges as separate "
        "native modules. Written by `bench/compose.py` (raw numbers: "
        f"`{data['results_path']}`); `bench/compose.py --report-only` puts this section back.")
    lines.append("")
    lines.append("| run | |")
    lines.append("|---|---|")
    lines.append(f"| date | {data['date']} |")
    lines.append(f"| machine | {data['machine']} |")
    lines.append(f"| command | `.venv/bin/{data['command']}` ({data['durations_s'].get('total', 0):.0f} s, "
                 f"builds {data['durations_s'].get('build', 0):.0f} s) |")
    lines.append(f"| load average (1, 5, 15 min) | before {fmt_load(data.get('load_before'))}, after "
                 f"{fmt_load(data.get('load_after'))} |")
    src = data.get("source", {})
    lines.append(f"| measured | commit {src.get('commit')}; files of ybg/ modified in the working tree: "
                 f"{', '.join(src.get('modified') or []) or 'none'} |")
    lines.append("")
    lines.append(
        f"The robots: the 12 stream configs of `examples/icub_robot` (joint states of six parts on "
        f"/joint_states, four WrenchStamped, the IMU, the hands on /tf; the camera and the trajectory into "
        f"YARP left out), each input {WIDTH} float64 wide and each bridge event-driven, fed at "
        f"{RATE:.0f} Hz by one C++ producer of every port (`bench/tools/producer.cpp`): each bridge "
        f"publishes {RATE:.0f} messages a second; and 24 configs, two such robots (the second under "
        "`icub2`). The latency is from the producer's tick (its envelope, which each bridge stamps "
        "its message with) to the receive time in one C++ rcl subscriber of every topic "
        "(`bench/rcl/stamp_sink.cpp`, best effort: it takes each message as it comes, 1200 (2400) a "
        "second, so that the latency is the bridges' and the middleware's, not the subscriber's queue), "
        f"over {data['seconds']:.0f} s after 3 s of warm-up; CPU over the same window; RSS, PSS, "
        "threads and sockets in its middle (sums over the processes of separate modules). Start: from starting "
        "the process(es), producers already writing, to a first message of every bridge at the "
        "subscriber; the first start of each arm and then, the process(es) stopped, started again "
        f"{data.get('restarts', 0)} times. The machine has 2 cores shared with other work: figures "
        "move from run to run.")
    lines.append("")
    goals = targets(data)
    if goals:
        lines.append("### Targets")
        lines.append("")
        lines.append("| target | robot | measured | value | limit | result |")
        lines.append("|---|---|---|---|---|---|")
        for target, robot, measured, value, limit, result in goals:
            lines.append(f"| {target} | {robot} | {measured} | {num(value, 2)} | {limit:g} | {result} |")
        lines.append("")
    for backend in data.get("backends", []):
        rows = figures(data, backend)
        if not rows:
            continue
        what = "native modules (`--backend cpp`)" if backend == "cpp" else "rclpy nodes (`--backend ros2`)"
        lines.append(f"### Composed against separate {what}")
        lines.append("")
        lines.append("| robot | quantity | composed | separate | composed / separate |")
        lines.append("|---|---|---|---|---|")
        for robot, q, c, s, r in rows:
            other = "one bridge alone" if "alone" in q else "separate"
            lines.append(f"| {robot} | {q} | {num(c)} | {num(s)}{' (' + other + ')' if other != 'separate' else ''} "
                         f"| {num(r, 2)} |")
        lines.append("")
        robots = {name: r for name, r in data["robots"][backend].items() if r.get("composed") and r.get("separate")}
        alone = data.get("alone", {}).get(backend, {})
        first = next(iter(robots.values()), None)
        if first and first.get("composed"):
            lines.append(f"Each bridge's median latency (us), composed and separate "
                         f"({', '.join(robots)}), and alone (its process by itself):")
            lines.append("")
            head = "| bridge | " + " | ".join(f"{r} composed | {r} separate" for r in robots) + " | alone |"
            lines.append(head)
            lines.append("|---|" + "---|---|" * len(robots) + "---|")
            for module in first["bridges"]:
                cells = []
                for r in robots.values():
                    cells.append(num(r["composed"]["latency"].get(module, {}).get("median_us"), 0))
                    cells.append(num(r["separate"]["latency"].get(module, {}).get("median_us"), 0))
                a = alone.get(module, {}).get("latency", {}).get(module, {}).get("median_us")
                lines.append(f"| `{module}` | " + " | ".join(cells) + f" | {num(a, 0)} |")
            lines.append("")
    for n in notes(data):
        lines.append(f"- {n}")
    lines.append("")
    return "\n".join(lines).rstrip() + "\n"


def notes(data: dict) -> list:
    out = [
        "Composed: each bridge keeps the threads it has alone (its loop, its ports' callbacks, its "
        "watcher, its node's /diagnostics); what the process shares is one YARP network and name "
        "server client, one rcl context and so one DDS participant (its discovery, its transports' "
        "threads and sockets), one RPC port, and the runtime's and the middleware's code mapped once. "
        "RSS counts the pages a process shares with others (the libraries of separate modules) in each "
        "of them; PSS divides them among the processes that share them.",
        "Latency: \"separate\" is each bridge in a process of its own, beside the robot's other "
        "bridges, fed by the same producer at the same load: the same bridge alone in its process, "
        "the comparison the target asks for. \"alone\" (the last column) is one bridge's process by "
        "itself on the machine, its producer writing only its port: lower than both arms alike, by "
        "the load, not by composition. At each tick the producer writes the robot's ports one after "
        "another (12, or 24), the bridges are handed their Bottles together, and the two cores take "
        "them in turn: the bridges' latencies rise in the order the producer writes their ports.",
        "The sink is C++ on rcl (`bench/rcl/stamp_sink.cpp`), one thread taking every message as it "
        "comes. Until 2026-11-26 it was one rclpy subscriber, whose own queueing (1200 or 2400 "
        "messages a second in one interpreter) was most of the latency it measured (that run: the 12 "
        "bridges' medians 2.3 to 3.9 ms composed and 2.2 to 3.3 ms separate).",
        "The 24-bridge robot composed: its bridges' medians lie close together (2.2 to 3.1 ms in the "
        "2026-11-26 run), where separate modules' rise with the order the producer writes their ports "
        "(1.6 to 3.3 ms): the median of the medians is lower composed, but the first-written ports' "
        "bridges are up to 1.5 x slower composed, above the 1.1 x target. With 12 bridges every "
        "bridge was faster composed. Not yet explained (Fast DDS's synchronous publication mode for "
        "the composed module was no faster).",
        "Start: from the process(es) started to a first message of every bridge at the sink, most of "
        "it DDS discovery between the new participant(s) and the sink's. The first start of an arm is "
        "a robot's first start; the others start the process(es) again 1 s after stopping them, "
        "against the same sink. Measured by hand (the composed native module against one sink, started "
        "again 1 s after each stop, 133 starts): 62 took 0.15 to 0.53 s; the others waited for a "
        "periodic announcement of the sink's participant, which Fast DDS sends every 3 s, so up to "
        "3.2 s: 68 about 1.8 s (the starts fall in step with the sink's period), one 1.1, one 2.2, "
        "one 3.2 s. Started 5 s after each stop, 13 of 15 took 0.15 to 0.84 s, two 2.2 and 2.8 s. Neither more initial announcements of the "
        "module's participant (20 at 50 ms, by a Fast DDS XML profile) nor UDP alone for it (no "
        "shared memory) changed how often. The separate modules wait for it too: 24 participants "
        "starting together, nearly always.",
        "The producer writes as a robot's devices do, YARP's plain write: a Bottle is not sent on a "
        "connection still busy with the one before. Strict writes (the default of "
        "`bench/tools/producer.cpp`, for the other benchmarks) hung the producer for good, 4 times in "
        "about 300 starts: at a start of the bridges after a stop, the bridges connected their inputs "
        "and their publishers matched the sink, but received nothing (their totals: 0 received), "
        "since the producer was waiting for a send to a stopped bridge that never completed. "
        "Should the sink still receive nothing from a start, the benchmark asks it what it matched, "
        "starts a new sink, notes it below, and leaves that start out of the start figures.",
    ]
    if "ros2" in data.get("backends", []):
        out.append("The composed rclpy node runs its bridges' threads under one interpreter lock: its "
                   "latency is that of one Python process doing every bridge's work in turn (at each "
                   "tick 12 messages, each about 0.7 ms of CPU: separate nodes take 84 % of a core for "
                   "1200 messages a second), where separate nodes share the two cores; and the threads' hand-overs of the lock cost CPU of their own.")
    for backend, robots in data.get("robots", {}).items():
        for robot, r in robots.items():
            for arm in ("composed", "separate"):
                for fault in (r.get(arm) or {}).get("sink_faults", []):
                    out.append(f"{robot} ({backend}, {arm}): at a {fault['start']} start the sink received "
                               f"nothing ({fault['matched']}); a new sink: {fault.get('new_sink')}.")
                retried = (r.get(arm) or {}).get("port_retries", [])
                if retried:
                    out.append(f"{robot} ({backend}, {arm}): {len(retried)} process(es) started again "
                               f"after YARP's name server gave a port of theirs an address still in use "
                               f"({PORT_TAKEN}), when started again 1 s after a stop: "
                               f"{', '.join(retried)}.")
            if "error" in r:
                out.append(f"{robot} ({backend}) not measured: {r['error'].strip().splitlines()[0][:200]}")
    return out


def main(argv=None) -> int:
    import run as bench_run  # bench/run.py: machine(), source_state()

    ap = argparse.ArgumentParser(description="Benchmark of ybgc compose: a robot's bridges in one process "
                                             "against separate processes.")
    ap.add_argument("--quick", action="store_true", help="the 12-config robot only, 3 s windows, 2 bridges alone")
    ap.add_argument("--seconds", type=float, help="the measurement window of each arm (default 10)")
    ap.add_argument("--alone-seconds", type=float, help="the window of each bridge alone (default 5)")
    ap.add_argument("--alone", type=int, help="how many of the 12 bridges to run alone (default all)")
    ap.add_argument("--restarts", type=int, help="how many times each robot is started again for its start "
                    "time (default 4, --quick 1)")
    ap.add_argument("--subjects", default="cpp", help="cpp and/or ros2 (default cpp)")
    ap.add_argument("--robots", help="icub12 and/or icub24 (default both; ros2: icub12)")
    ap.add_argument("--results", type=Path, help="the JSON (default bench/results/compose.json, "
                    "bench/results/quick/compose.json with --quick)")
    ap.add_argument("--docs", action="store_true", help="write the docs section (the default of a full run)")
    ap.add_argument("--docs-file", type=Path, default=DOCS)
    ap.add_argument("--build-dir", type=Path, default=BENCH / "build" / "compose")
    ap.add_argument("--report-only", action="store_true", help="the docs section from the JSON, run nothing")
    args = ap.parse_args(argv)

    mode = "quick" if args.quick else "full"
    args.seconds = args.seconds or (3.0 if args.quick else 10.0)
    args.alone_seconds = args.alone_seconds or (3.0 if args.quick else 5.0)
    if args.restarts is None:
        args.restarts = 1 if args.quick else 4
    if args.alone is None and args.quick:
        args.alone = 2
    json_path = args.results or (BENCH / "results" / ("quick" if args.quick else "") / "compose.json")
    write_docs = args.docs or mode == "full"
    if args.report_only:
        data = json.loads(json_path.read_text())
        write_section(section(data), SECTION, args.docs_file)
        say(f"written: {args.docs_file} (section {SECTION!r})")
        return 0
    backends = [s.strip() for s in args.subjects.split(",") if s.strip()]
    unknown = [s for s in backends if s not in SUBJECTS]
    if unknown:
        ap.error(f"unknown subjects: {', '.join(unknown)}")
    robots_wanted = [r.strip() for r in (args.robots or "").split(",") if r.strip()]

    t_start = time.monotonic()
    load0 = loadavg()
    say(f"ybgc compose benchmark, {mode} mode; load average {load0}")
    mw.require_yarp()
    mw.require_ros2()
    tools = h.build_tools(args.build_dir / "tools")
    h.cmake_build(BENCH / "rcl", args.build_dir / "rcl", target="stamp_sink",
                  options=(f"-DYBGC_ROS2_PYTHON_ENV={mw.VENV}", "-DBENCH_COMPOSE=ON"))
    tmp = mw.TmpDir("ybg-bench-compose-")
    ctx = {"producer": str(tools["producer"]), "sink": str(args.build_dir / "rcl" / "stamp_sink"),
           "tmp": str(tmp.path)}
    command = "python bench/compose.py" + (" --quick" if args.quick else "")
    if args.subjects != "cpp":
        command += f" --subjects {args.subjects}"
    data = {
        "date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": bench_run.machine(),
        "command": command,
        "mode": mode,
        "seconds": args.seconds,
        "alone_seconds": args.alone_seconds,
        "restarts": args.restarts,
        "rate": RATE,
        "width": WIDTH,
        "load_before": load0,
        "results_path": os.path.relpath(json_path, ROOT) if json_path.is_absolute() else str(json_path),
        "source": bench_run.source_state(),
        "backends": backends,
        "robots": {},
        "alone": {},
    }
    build_s = 0.0
    for backend in backends:
        robots = robots_wanted or (["icub12"] if args.quick or backend == "ros2" else ["icub12", "icub24"])
        data["robots"][backend] = {}
        for robot in robots:
            try:
                data["robots"][backend][robot] = robot_stage(
                    ctx, args, robot, ("icub",) if robot == "icub12" else ("icub", "icub2"), backend)
                build_s += data["robots"][backend][robot]["build_s"]
            except (BenchError, OSError, mw.subprocess.TimeoutExpired) as e:
                say(f"  {robot} ({backend}) not measured: {str(e).strip().splitlines()[0] if str(e).strip() else e}")
                data["robots"][backend][robot] = {"error": str(e).strip()[-3000:]}
        try:
            data["alone"][backend] = alone_stage(ctx, args, backend)
        except (BenchError, OSError, mw.subprocess.TimeoutExpired) as e:
            say(f"  alone ({backend}) not measured: {str(e).strip().splitlines()[0] if str(e).strip() else e}")
            data["alone"][backend] = {}
    t_end = time.monotonic()
    data["load_after"] = loadavg()
    data["durations_s"] = {"total": round(t_end - t_start, 1), "build": round(build_s, 1)}
    json_path.parent.mkdir(parents=True, exist_ok=True)
    json_path.write_text(json.dumps(data, indent=1) + "\n")
    for backend in backends:
        for robot, q, c, s, r in figures(data, backend):
            say(f"{backend} {robot}: {q}: composed {num(c)}, other {num(s)}, ratio {num(r, 2)}")
    say(f"written: {json_path} ({t_end - t_start:.0f} s in all)")
    if write_docs:
        write_section(section(data), SECTION, args.docs_file)
        say(f"written: {args.docs_file} (section {SECTION!r})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
