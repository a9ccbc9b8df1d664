"""Benchmark of the bridge modules that ybgc generates, against the floor.

    .venv/bin/python bench/run.py            full run, about 19 minutes: writes
                                             docs/benchmarks.md, docs/bench_*.png,
                                             bench/results/bridges.json
    .venv/bin/python bench/run.py --quick    under a minute once built (the first
                                             run builds the C++ peers and modules;
                                             2 x 15 at 1 kHz only, memory for 20 s):
                                             bench/results/quick/
    .venv/bin/python bench/run.py --smoke    the floors only (direct, relay,
                                             relay-strict, a few hundred
                                             messages), for the tests

Everything runs on 127.0.0.1 with its own yarpserver and ROS 2 domain (the test
suite's helpers, tests/harness/). The producer and the consumer are C++
programs against YARP 3.5 (bench/tools/), built once with CMake like a
generated module; the ROS 2 peers are rclpy (bench/peers/).

Subjects, on the same workloads in the same run:
  direct   producer -> consumer (one hop)
  relay    the hand-written C++ relay, bench/relay/relay.cpp (two hops: the floor)
  relay-strict  the hand-written C++ relay that reads as strictly as the C++
           module, bench/relay/strict_relay.cpp (the floor of the same work)
  cpp      the generated C++ module         (ybgc CONFIG --backend cpp)
  py       the generated Python module      (ybgc CONFIG --backend py)
  ros2     the generated ROS 2 node, YARP in, ROS 2 out (--backend ros2)
  cpp-ros2 the generated C++ module, YARP in, ROS 2 out through rcl (--backend cpp)
  rclpy    a bare rclpy publisher -> rclpy subscriber hop, for reference
  rcl      a bare rcl publisher (bench/rcl/rcl_source.cpp) -> rclpy subscriber:
           the "C rcl hop", the floor of cpp-ros2's ROS 2 side
  rcl-relay  the hand-written YARP -> ROS 2 relay (bench/rcl/rcl_relay.cpp):
           the floor of cpp-ros2's whole chain (producer -> relay -> rclpy sink)
Stages: latency (event-driven), fixed rate, memory under a stalling consumer.
The shapes, the subjects and their rigs: bench/bridge_rigs.py.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import threading
import time
from dataclasses import dataclass
from datetime import datetime, timezone
from pathlib import Path
from typing import Optional

sys.path.insert(0, str(Path(__file__).resolve().parent))

import blocks as h  # noqa: E402
from blocks import BenchError, mw  # noqa: E402
from bridge_rigs import (DESCRIPTION, FLOORS, GENERATED, MEMORY_SUBJECTS, MODULES, ROS2_OUT,  # noqa: E402
                         SHAPES, STALL_EVERY, STALL_FOR, SUBJECTS, Isolated, Rig, start_rigs, stop_rigs)
from report import loadavg  # noqa: E402

ROOT = h.ROOT
BENCH = h.BENCH
CONFIGS = BENCH / "configs"


@dataclass
class Mode:
    name: str
    latency: list          # (workload, shape, rate Hz, seconds)
    fixed: list            # (shape, rate Hz, seconds)
    memory_s: float
    subjects: tuple
    warmup_ticks: int
    rounds: int            # latency runs are split in rounds, subjects in turn


MODES = {
    "full": Mode("full",
                 [("joints_100hz", "joints", 100, 10.0), ("joints_1khz", "joints", 1000, 10.0),
                  ("wide_1khz", "wide", 1000, 10.0)],
                 [("joints", 100, 10.0), ("joints", 1000, 10.0), ("wide", 1000, 10.0)],
                 600.0, SUBJECTS, 200, 5),
    "quick": Mode("quick",
                  [("joints_1khz", "joints", 1000, 1.0)],
                  [("joints", 1000, 1.0)],
                  20.0, SUBJECTS, 50, 2),
    "smoke": Mode("smoke", [("joints_500hz", "joints", 500, 0.6)], [], 0.0, FLOORS, 20, 1),
}


def say(text: str) -> None:
    print(text, flush=True)


class Progress:
    def __init__(self, total: int):
        self.total, self.done, self.t0 = total, 0, time.monotonic()

    def step(self, text: str) -> None:
        self.done += 1
        say(f"[{self.done:2d}/{self.total}  {time.monotonic() - self.t0:5.0f} s] {text}")


# --------------------------------------------------------------------------
# preparing the subjects


def prepare(build_root: Path, subjects: tuple, shapes: list) -> dict:
    """Build the peers and every subject's module; returns
    {"tools": {...}, "subjects": {name: {"ok", "error", shape: launch info}}}."""
    say("building the C++ producer, consumer and reference relay (bench/tools, bench/relay)")
    tools = h.build_tools(build_root)
    out = {"tools": tools, "subjects": {}}
    for s in subjects:
        info = {"ok": True, "error": None}
        try:
            for shape in shapes:
                sh = SHAPES[shape]
                gen = build_root / "gen" / s / shape
                if s == "cpp":
                    say(f"generating and building the C++ module of {sh.config}")
                    info[shape] = h.build_generated_cpp(CONFIGS / sh.config, gen)
                elif s == "py":
                    info[shape] = h.generated_python(CONFIGS / sh.config, "py", gen)
                elif s == "ros2":
                    info[shape] = h.generated_python(CONFIGS / sh.ros2_config, "ros2", gen)
                elif s == "cpp-ros2":
                    say(f"generating and building the C++ module of {sh.ros2_config} (rcl)")
                    info[shape] = h.build_generated_cpp(CONFIGS / sh.ros2_config, gen, ros2=True)
                elif s == "rcl":
                    info[shape] = h.build_rcl_source(build_root)
                elif s == "rcl-relay":
                    info[shape] = h.build_rcl_source(build_root).with_name("rcl_relay")
        except (BenchError, OSError, mw.subprocess.TimeoutExpired) as e:
            info = {"ok": False, "error": str(e).strip()}
            say(f"  {s}: not available: {info['error'].splitlines()[0]}")
        out["subjects"][s] = info
    return out


# --------------------------------------------------------------------------
# stages


def available(ctx: dict, subject: str) -> Optional[str]:
    """None when the subject can run, else why not."""
    if subject.split("+")[0] in ROS2_OUT and not ctx.get("ros2_ok"):
        return ctx.get("ros2_error") or "ROS 2 not available"
    if subject in FLOORS or subject == "rclpy":
        return None
    info = ctx["subjects"].get(subject, {})
    return None if info.get("ok") else (info.get("error") or "not available")


def latency_stage(ctx: dict, mode: Mode, progress: Progress) -> list:
    """Event-driven runs: every subject, every latency workload. Per shape,
    every subject's rig is started once, each with its own name server (and
    ROS 2 domain), and all stay up; each workload is then run in
    ``mode.rounds`` rounds, every subject in turn (the order rotates from
    round to round), so that a change in the machine's load during the stage
    falls on every subject alike."""
    results = []
    by_shape: dict = {}
    for wl, shape, rate, secs in mode.latency:
        by_shape.setdefault(shape, []).append((wl, rate, secs))
    tmp = Path(mw.tmp_root())
    for shape, runs in by_shape.items():
        sh = SHAPES[shape]
        rigs: dict = {}
        isos: dict = {}
        crashes: dict = {}   # subject -> the error that made its rig restart
        errors: dict = {}
        for s in mode.subjects:
            why = available(ctx, s)
            if why:
                errors[s] = why
        say(f"latency, {sh.label}: starting {', '.join(s for s in mode.subjects if s not in errors)}")
        try:
            started = start_rigs(ctx, [s for s in mode.subjects if s not in errors], sh,
                                 tag=f"_{shape}")
            for s, got in started.items():
                if isinstance(got, tuple):
                    isos[s] = got[0]
                    rigs[s] = got[1]
                else:
                    errors[s] = got
                    say(f"  {s}: cannot start: {got.splitlines()[0]}")

            def restart(s: str, err: str) -> bool:
                """A process of the rig died: note why, start the rig again
                (once per subject and shape); False if it cannot be."""
                if s in crashes:
                    return False
                crashes[s] = err
                say(f"  {s}: {err.splitlines()[0][:150]}; restarting its processes")
                old = rigs[s]
                stop_rigs({s: old})
                isos.pop(s).stop()
                got = start_rigs(ctx, [s], sh, tag=f"_{shape}_again")[s]
                if not isinstance(got, tuple):
                    crashes[s] += f"; restart failed: {got.splitlines()[0]}"
                    return False
                isos[s], rigs[s] = got
                rigs[s].ticks_total, rigs[s].received_total = old.ticks_total, old.received_total
                return True

            def warm_up(s: str, rate: int) -> None:
                rig = rigs[s]
                warm = rig.source.run(min(mode.warmup_ticks, max(10, rate // 4)), rate)
                rig.ticks_total += warm["ticks"]
                rig.sink.settle(warm["ticks"] * (sh.ports if rig.per_block else 1))

            for wl, rate, secs in runs:
                chunks = {s: [] for s in rigs}
                cpu = {s: [0.0, 0.0] for s in rigs}    # CPU s, wall s of the module
                peer_cpu = {s: [0.0, 0.0] for s in rigs}  # CPU s of the source, of the sink
                late = {s: 0 for s in rigs}
                failed: dict = {}
                per_round = max(1, int(round(secs * rate / mode.rounds)))
                for s in list(rigs):
                    if s in errors:
                        continue
                    try:
                        warm_up(s, rate)
                    except (BenchError, OSError) as e:
                        try:
                            if not restart(s, str(e).strip()):
                                raise
                            warm_up(s, rate)
                        except (BenchError, OSError) as e2:
                            failed[s] = str(e2).strip()

                def measure_round(s: str, rig: Rig) -> None:
                    rig.received_total += rig.sink.count()[0]
                    rig.sink.reset()
                    pid = rig.module.pid if rig.module else None
                    c0, t0 = (h.cpu_seconds(pid) if pid else None), time.monotonic()
                    p0 = (h.cpu_seconds(rig.source.pid), h.cpu_seconds(rig.sink.pid))
                    run = rig.source.run(per_round, rate)
                    # the CPU % is over the time the source ran: the CPU the
                    # module spends after it (the last messages) counts, the
                    # wait for messages that never come (a relay that lost
                    # some waits the sink's quiet time) does not
                    ran = time.monotonic() - t0
                    rig.ticks_total += run["ticks"]
                    expected = run["ticks"] * (sh.ports if rig.per_block else 1)
                    rig.sink.settle(expected)
                    if pid and c0 is not None:
                        cpu[s][0] += (h.cpu_seconds(pid) or c0) - c0
                    cpu[s][1] += ran
                    p1 = (h.cpu_seconds(rig.source.pid), h.cpu_seconds(rig.sink.pid))
                    for k in (0, 1):
                        if p0[k] is not None and p1[k] is not None:
                            peer_cpu[s][k] += p1[k] - p0[k]
                    rig.check_alive()
                    recs = rig.sink.dump(tmp / f"lat_{wl}_{s}.bin")
                    chunks[s].append(h.analyse_latency(recs, run["first"], run["ticks"],
                                                       sh.ports, rig.per_block))
                    late[s] += run["late"]

                order = list(rigs)
                for r in range(mode.rounds):
                    turn = order[r % len(order):] + order[:r % len(order)] if order else []
                    for s in turn:
                        for attempt in (1, 2):
                            if s in failed or s in errors:
                                break
                            rig = rigs[s]
                            try:
                                measure_round(s, rig)
                                break
                            except (BenchError, OSError) as e:
                                err = str(e).strip()
                                try:
                                    if attempt == 2 or not restart(s, err):
                                        failed[s] = err
                                    else:
                                        warm_up(s, rate)
                                except (BenchError, OSError) as e2:
                                    failed[s] = str(e2).strip()
                    if mode.rounds > 1:
                        say(f"  {wl}: round {r + 1}/{mode.rounds} done")
                for s in mode.subjects:
                    entry = {"workload": wl, "shape": shape, "rate": rate, "subject": s}
                    if s in crashes:
                        entry["restarted_after"] = crashes[s]
                    err = errors.get(s) or failed.get(s)
                    if err or not chunks.get(s):
                        entry["error"] = err or "no data"
                        progress.step(f"latency {wl:13s} {s:6s} "
                                      f"{'not available' if s in errors else 'FAILED'}: "
                                      f"{entry['error'].splitlines()[0][:100]}")
                        results.append(entry)
                        continue
                    rig = rigs[s]
                    entry.update(h.merge_latency(chunks[s]))
                    wall = cpu[s][1]
                    entry["cpu_pct"] = 100.0 * cpu[s][0] / wall if wall and rig.module else None
                    entry["source_cpu_pct"] = 100.0 * peer_cpu[s][0] / wall if wall else None
                    entry["sink_cpu_pct"] = 100.0 * peer_cpu[s][1] / wall if wall else None
                    if rig.module is not None:
                        mem = h.memory_kb(rig.module.pid)
                        entry["rss_kb"] = mem.get("VmRSS")
                        entry["rss_peak_kb"] = mem.get("VmHWM")
                    entry["source_late_ticks"] = late[s]
                    results.append(entry)
                    progress.step(f"latency {wl:13s} {s:6s} median {fmt_us(entry['median_us'])} "
                                  f"p99 {fmt_us(entry['p99_us'])} max {fmt_us(entry['max_us'])} "
                                  f"delivered {entry['delivered']}/{entry['sent']} "
                                  f"cpu {fmt_pct(entry.get('cpu_pct'))}")
        finally:
            for rig in rigs.values():
                try:
                    rig.received_total += rig.sink.count()[0]
                except (BenchError, OSError):
                    pass
            statuses = stop_rigs(rigs)
            for s, rig in rigs.items():
                if rig.module is not None:
                    # where ticks were lost over the rig's whole life (every
                    # workload of this shape, warm-ups included): at the
                    # module's inputs (overwritten before read) or between
                    # its output and the consumer
                    account = dict(rig.totals(), ticks_sent=rig.ticks_total,
                                   consumer_received=rig.received_total)
                    for e in results:
                        if e["shape"] == shape and e["subject"] == s:
                            e["exit_status"] = statuses[s]
                            e["life_totals"] = account
            for iso in isos.values():
                iso.stop()
    return results


def fixed_stage(ctx: dict, mode: Mode, progress: Progress) -> list:
    results = []
    for shape, rate, secs in mode.fixed:
        sh = SHAPES[shape]
        for s in MODULES:
            if s not in mode.subjects:
                continue
            entry = {"shape": shape, "rate": rate, "subject": s}
            why = available(ctx, s)
            if why:
                entry["error"] = why
                results.append(entry)
                progress.step(f"fixed   {shape:6s} {rate:5d} Hz {s:6s} not available")
                continue
            rig = None
            iso = Isolated(ctx, s, tag=f"_fixed_{s}")
            try:
                rig = Rig(iso.start(), s, sh, rate).start()
                ticks = int(round((secs + 0.7) * rate))
                cpu = h.CpuWindow(rig.module.pid)
                t0 = time.monotonic()
                run = rig.source.run(ticks, rate)
                t1 = time.monotonic()
                entry["cpu_pct"] = cpu.percent()
                rig.check_alive()
                recs = rig.sink.dump(Path(mw.tmp_root()) / f"fix_{shape}_{rate}_{s}.bin")
                start = t0 + 0.5
                entry.update(h.analyse_rate(recs, start, min(t1 - 0.1, start + secs), rate))
                entry["source_late_ticks"] = run["late"]
                progress.step(f"fixed   {shape:6s} {rate:5d} Hz {s:6s} achieved "
                              f"{fmt_hz(entry.get('achieved_hz'))} ({fmt_signed(entry.get('error_pct'))} %), "
                              f"gaps {entry.get('gaps')}, cpu {fmt_pct(entry['cpu_pct'])}")
            except (BenchError, OSError, RuntimeError, TimeoutError) as e:
                entry["error"] = str(e).strip()
                progress.step(f"fixed   {shape:6s} {rate:5d} Hz {s:6s} FAILED: "
                              f"{entry['error'].splitlines()[0]}")
            finally:
                if rig is not None:
                    entry["exit_status"] = rig.stop()
                    entry.update(rig.totals())
                iso.stop()
            results.append(entry)
    return results


def memory_stage(ctx: dict, mode: Mode, progress: Progress) -> list:
    """Every module at once, each with its own yarpserver (and ROS 2 domain),
    producer at 1 kHz, and a consumer that stalls STALL_FOR s every
    STALL_EVERY s. RSS of each module sampled every second."""
    sh = SHAPES["joints"]
    rate = 1000
    subjects = [s for s in MEMORY_SUBJECTS if s in mode.subjects and not available(ctx, s)]
    results = []
    for s in MEMORY_SUBJECTS:
        if s in mode.subjects and s not in subjects:
            results.append({"subject": s, "error": available(ctx, s)})
    if not subjects:
        return results
    isos, rigs = [], {}
    try:
        for s, got in start_rigs(ctx, subjects, sh, stall=True, record=False, tag="_mem").items():
            if isinstance(got, tuple):
                isos.append(got[0])
                rigs[s] = got[1]
            else:
                results.append({"subject": s, "error": got})
        ticks = int(mode.memory_s * rate)
        say(f"memory: {', '.join(subjects)} at once, {mode.memory_s:.0f} s at {rate} Hz, consumer "
            f"stalling {STALL_FOR:g} s every {STALL_EVERY:g} s")
        done = {}

        def drive(s, rig):
            try:
                done[s] = rig.source.run(ticks, rate)
            except BaseException as e:  # reported below
                done[s] = {"error": str(e)}

        threads = [threading.Thread(target=drive, args=(s, r), daemon=True) for s, r in rigs.items()]
        t0 = time.monotonic()
        for t in threads:
            t.start()
        samples = {s: [] for s in rigs}
        next_report = t0 + max(5.0, mode.memory_s / 10)
        while any(t.is_alive() for t in threads):
            now = time.monotonic()
            for s, rig in rigs.items():
                if rig.module.alive:
                    samples[s].append((round(now - t0, 2), h.memory_kb(rig.module.pid).get("VmRSS")))
            if now >= next_report:
                next_report += max(5.0, mode.memory_s / 10)
                say(f"  memory {now - t0:5.0f}/{mode.memory_s:.0f} s  " + "  ".join(
                    f"{s} {samples[s][-1][1] / 1024:.1f} MB" if samples[s] else f"{s} -"
                    for s in rigs))
            time.sleep(1.0)
        # what libpython's pages cost each module at the end: the ROS 2 wheels' librcl
        # loads it (a ROS 2 install from its own packages does not)
        mapped = {s: h.mapped_rss_kb(rig.module.pid, ("libpython",)) for s, rig in rigs.items()
                  if rig.module.alive}
        for s, rig in rigs.items():
            series = [(t, kb) for t, kb in samples[s] if kb]
            entry = {"subject": s, "duration_s": mode.memory_s, "rate": rate,
                     "stall_every_s": STALL_EVERY, "stall_for_s": STALL_FOR}
            if "error" in done.get(s, {}) or not series:
                entry["error"] = done.get(s, {}).get("error") or "no samples"
                if not rig.module.alive:
                    entry["error"] += f"; module exited: {rig.module.log_text()[-1500:]}"
            else:
                warm = next((kb for t, kb in series if t >= 2.0), series[0][1])
                entry.update(
                    rss_start_kb=warm, rss_end_kb=series[-1][1],
                    rss_peak_kb=max(kb for _, kb in series),
                    growth_kb=series[-1][1] - warm,
                    peak_growth_kb=max(kb for _, kb in series) - warm,
                    samples=downsample(series, 300),
                    sent=done[s]["ticks"],
                    rss_mapped_total_kb=mapped.get(s, {}).get("total"),
                    rss_libpython_kb=mapped.get(s, {}).get("libpython"),
                    received=rig.sink.count()[0],
                    alive=rig.module.alive)
            results.append(entry)
            progress.step(f"memory  {s:6s} " + (
                f"RSS {entry['rss_start_kb'] / 1024:.1f} -> {entry['rss_end_kb'] / 1024:.1f} MB "
                f"(peak {entry['rss_peak_kb'] / 1024:.1f} MB), growth "
                f"{entry['growth_kb'] / 1024:+.2f} MB, delivered {entry['received']}/{entry['sent']}"
                if "error" not in entry else f"FAILED: {entry['error'].splitlines()[0]}"))
    finally:
        statuses = stop_rigs(rigs)
        for s, rig in rigs.items():
            for e in results:
                if e["subject"] == s:
                    e["exit_status"] = statuses[s]
                    e.update(rig.totals())
        for iso in isos:
            iso.stop()
    return results


def downsample(series: list, n: int) -> list:
    if len(series) <= n:
        return [list(x) for x in series]
    step = len(series) / n
    return [list(series[int(i * step)]) for i in range(n)] + [list(series[-1])]


# --------------------------------------------------------------------------
# formatting helpers (progress lines)


def fmt_us(v) -> str:
    return "-" if v is None else f"{v:7.0f} us"


def fmt_pct(v) -> str:
    return "-" if v is None else f"{v:.0f} %"


def fmt_hz(v) -> str:
    return "-" if v is None else f"{v:.2f} Hz"


def fmt_signed(v) -> str:
    return "-" if v is None else f"{v:+.2f}"


def source_state() -> dict:
    """The commit measured, and the backend files that differ from it (the
    modules are generated from the working tree)."""
    def git(*args):
        r = h.run_cmd(["git", *args], cwd=ROOT, timeout=30)
        return r.stdout.rstrip("\n") if r.returncode == 0 else None
    changed = git("status", "--porcelain", "--", "ybg")
    return {"commit": git("rev-parse", "--short", "HEAD"),
            "modified": [line[3:] for line in (changed or "").splitlines()]}


def machine() -> str:
    cpu = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    mem = ""
    try:
        kb = int(Path("/proc/meminfo").read_text().split()[1])
        mem = f", {kb / 1024 / 1024:.0f} GiB"
    except (OSError, ValueError, IndexError):
        pass
    return (f"{cpu or platform.machine()}, {os.cpu_count()} cores{mem}; {platform.system()} "
            f"{platform.release()}; CPython {platform.python_version()}; YARP 3.5 (PyPI build)")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description="Benchmark of the generated bridge modules "
                                             "(latency, rate, CPU, memory) against the floor.")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--quick", action="store_true", help="short runs (under a minute once built)")
    g.add_argument("--smoke", action="store_true", help="floors only (direct, relay, "
                   "relay-strict), a few hundred messages; no report unless --docs is given")
    ap.add_argument("--subjects", help="comma-separated subset of " + ",".join(SUBJECTS))
    ap.add_argument("--skip-memory", action="store_true", help="leave out the memory stage")
    ap.add_argument("--skip-fixed", action="store_true", help="leave out the fixed-rate stage")
    ap.add_argument("--skip-latency", action="store_true", help="leave out the latency stage")
    ap.add_argument("--results", type=Path, help="folder of the JSON results (default "
                    "bench/results, bench/results/quick with --quick)")
    ap.add_argument("--docs", type=Path, help="folder of the report and plots (default docs/, "
                    "bench/results/quick with --quick)")
    ap.add_argument("--build-dir", type=Path, default=BENCH / "build",
                    help="where the peers and modules are built (default bench/build)")
    ap.add_argument("--report-only", action="store_true",
                    help="write the report from the existing JSON results, run nothing")
    args = ap.parse_args(argv)

    mode = MODES["smoke" if args.smoke else "quick" if args.quick else "full"]
    results_dir = args.results or (BENCH / "results" / ("quick" if mode.name == "quick" else ""))
    results_dir = Path(results_dir)
    docs_dir = args.docs or (None if mode.name == "smoke" else
                             BENCH / "results" / "quick" if mode.name == "quick" else ROOT / "docs")
    json_path = results_dir / ("smoke.json" if mode.name == "smoke" else "bridges.json")

    if args.report_only:
        import report
        data = json.loads(json_path.read_text())
        report.write(data, docs_dir, json_path)
        say(f"written: {docs_dir / 'benchmarks.md'}")
        return 0

    subjects = mode.subjects
    if args.subjects:
        wanted = [s.strip() for s in args.subjects.split(",") if s.strip()]
        unknown = [s for s in wanted if s not in SUBJECTS]
        if unknown:
            ap.error(f"unknown subjects: {', '.join(unknown)}")
        subjects = tuple(s for s in SUBJECTS if s in wanted)
    mode = Mode(mode.name, [] if args.skip_latency else mode.latency,
                [] if args.skip_fixed else mode.fixed,
                0.0 if args.skip_memory else mode.memory_s, subjects, mode.warmup_ticks, mode.rounds)

    t_start = time.monotonic()
    load0 = loadavg()
    command = "python bench/run.py" + ("" if mode.name == "full" else f" --{mode.name}")
    say(f"ybgc bridge benchmark, {mode.name} mode; load average {load0}")
    mw.require_yarp()
    shapes = sorted({w[1] for w in mode.latency} | {f[0] for f in mode.fixed}
                    | ({"joints"} if mode.memory_s else set()))
    built = prepare(args.build_dir, tuple(s for s in subjects if s in GENERATED), shapes)
    t_built = time.monotonic()

    ros2_error = None
    if any(s in subjects for s in ROS2_OUT):
        err = mw._python_imports(str(mw.VENV_PYTHON), "rclpy, sensor_msgs.msg")
        if err:
            ros2_error = f"rclpy not usable: {err}"
            say(f"ROS 2 not usable: {err}")

    n_lat = len(mode.latency) * len(subjects)
    n_fix = len(mode.fixed) * len([s for s in MODULES if s in subjects])
    n_mem = len([s for s in MEMORY_SUBJECTS if s in subjects]) if mode.memory_s else 0
    progress = Progress(n_lat + n_fix + n_mem)
    data = {
        "date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": machine(),
        "command": command,
        "mode": mode.name,
        "load_before": load0,
        "peers": "C++ producer and consumer against YARP 3.5 (bench/tools/); rclpy source "
                 "and sink for ROS 2 (bench/peers/)",
        "shapes": {k: {"label": v.label, "ports": v.ports, "width": v.width, "config": v.config,
                       "ros2_config": v.ros2_config} for k, v in SHAPES.items() if k in shapes},
        "subjects": {s: {"description": DESCRIPTION[s],
                         "available": built["subjects"].get(s, {"ok": True}).get("ok", True)
                         and not (s in ROS2_OUT and ros2_error),
                         "error": built["subjects"].get(s, {}).get("error")
                         or (ros2_error if s in ROS2_OUT else None)} for s in subjects},
        "stall": {"every_s": STALL_EVERY, "for_s": STALL_FOR},
        "source": source_state(),
        # the latency stage's CPU % is over the time the producer ran (latency_stage)
        "cpu_window": "source",
    }
    ctx = {"tools": built["tools"], "subjects": built["subjects"], "ros2_ok": ros2_error is None,
           "ros2_error": ros2_error}
    say(f"latency: {len(mode.latency)} workloads x {len(subjects)} subjects, "
        f"{mode.rounds} round(s) each")
    data["latency"] = latency_stage(ctx, mode, progress)
    t_lat = time.monotonic()
    data["fixed_rate"] = fixed_stage(ctx, mode, progress) if mode.fixed else []
    t_fix = time.monotonic()
    data["memory"] = memory_stage(ctx, mode, progress) if mode.memory_s else []
    t_end = time.monotonic()
    data["load_after"] = loadavg()
    data["durations_s"] = {"build": round(t_built - t_start, 1), "latency": round(t_lat - t_built, 1),
                           "fixed_rate": round(t_fix - t_lat, 1), "memory": round(t_end - t_fix, 1),
                           "total": round(t_end - t_start, 1)}
    results_dir.mkdir(parents=True, exist_ok=True)
    json_path.write_text(json.dumps(data, indent=1) + "\n")
    say(f"written: {json_path} ({t_end - t_start:.0f} s in all, build {t_built - t_start:.0f} s)")
    if docs_dir is not None:
        import report
        report.write(data, docs_dir, json_path)
        say(f"written: {docs_dir / 'benchmarks.md'} and its plots")
    failed = [e for e in data["latency"] if "error" in e and data["subjects"].get(
        e["subject"], {}).get("available", True)]
    return 1 if mode.name == "smoke" and failed else 0


if __name__ == "__main__":
    sys.exit(main())
