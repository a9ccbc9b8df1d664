"""Benchmark of camera images: a YARP image port to a ROS 2 sensor_msgs/Image,
the generated modules against a hand-written relay (the floor).

    .venv/bin/python bench/images.py                  full run: --seconds 60 a subject
                                                      and workload, --stall-seconds 600;
                                                      writes bench/results/images.json and
                                                      the "Camera images" section of
                                                      docs/benchmarks.md
    .venv/bin/python bench/images.py --seconds 30 --stall-seconds 120
    .venv/bin/python bench/images.py --quick          5 s each, the stall 20 s:
                                                      bench/results/quick/images.json only
    .venv/bin/python bench/images.py --report-only [--results FILE]
                                                      the docs section from a JSON

Everything runs on 127.0.0.1, each subject with its own yarpserver and ROS 2
domain (the test suite's helpers, tests/harness/, through bench/blocks.py).
The C++ programs are built once with CMake (-DBENCH_IMAGES=ON) under
bench/build/images/: bench/tools/image_{producer,consumer}.cpp against YARP,
bench/rcl/image_{source,sink,relay}.cpp against the venv's ROS 2 wheels (and
YARP, for the relay), as bench/run.py builds bench/rcl; the modules are
generated from the working tree's ybgc on two configs written here (the
`CONFIG` of bench/images_rigs.py: examples/icub_left_eye_ros2.ini without
its calibration), one for rgb8 and one for 32FC1.

Subjects, on the same workloads in the same run:
  relay     producer -> bench/rcl/image_relay.cpp -> rcl sink: the hand-written
            relay (BufferedPort<FlexImage> read, rows copied once into a
            sensor_msgs/Image, rcl_publish): the floor
  yarp-hop  producer -> YARP image consumer (bench/tools/image_consumer.cpp)
  rcl-hop   rcl Image publisher (bench/rcl/image_source.cpp) -> rcl sink
  cpp       producer -> the generated C++ module (--backend cpp) -> rcl sink
  ros2      producer -> the generated rclpy node (--backend ros2) -> rcl sink
The producer (bench/tools/image_producer.cpp) writes each frame on a
BufferedPort<FlexImage> with its envelope (seq, send time, CLOCK_MONOTONIC);
the bridges copy the envelope into header.stamp and the sink
(bench/rcl/image_sink.cpp, C++ on rcl: it keeps up at 1280x720 30 Hz, an
rclpy sink would itself cost a copy and the interpreter) records receive
time - header.stamp, checks every frame's size, encoding and the stamps the
producer put in its first and last bytes, and counts the frames (lost =
sent - received).

Stages:
  latency   3 workloads (640x480 rgb8, 1280x720 rgb8, 640x480 32FC1, 30 Hz) x 5
            subjects, --seconds each, in rounds (the subjects in turn, every
            rig up at once); CPU (user + sys / wall) of the relay and the
            modules, of the sinks and producers too
  rate      1280x720 rgb8 at 30, 60, 120, 240, 480 Hz, 5 s each (2 s --quick):
            relay, cpp (and the rcl hop, the ROS 2 side's own limit)
  stall     the cpp module at 30 Hz 1280x720 with its sink SIGSTOPped for
            --stall-seconds, RSS sampled every second; beside it, at once, the
            relay and the module with glibc's mmap threshold fixed (cpp+mmap:
            what the allocator keeps apart from what the module holds)
  defaults  1280x720 rgb8 at 30 Hz with Fast DDS's default transports (rcl-hop,
            relay, cpp): what a camera loses without the large-data profile

Fast DDS: every ROS 2 process runs with a profile (FASTDDS_DEFAULT_PROFILES_FILE,
written under the build folder: DDS_PROFILE of bench/images_rigs.py) of a
32 MB shared-memory segment and 4 MB UDP buffers on 127.0.0.1. With Fast
DDS's default 512 kB segment, best-effort images of 0.9 to 2.8 MB lose most
frames on this machine, even from a bare rcl publisher to an rcl subscriber
(the "defaults" stage measures it): what every subject would then measure is
Fast DDS's buffer, not the bridge.

The subjects, the workloads, their build and rigs: bench/images_rigs.py; the
targets, the figures printed and the docs section: bench/images_report.py.
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import sys
import threading
import time
from datetime import datetime, timezone
from pathlib import Path
from typing import Optional

sys.path.insert(0, str(Path(__file__).resolve().parent))

import blocks as h  # noqa: E402
from blocks import BenchError, mw  # noqa: E402
from images_report import (SECTION, downsample, fmt_hz, fmt_mb, fmt_ms, fmt_us, mb, notes,  # noqa: E402
                           print_figures, quant, section, short, targets)
from images_rigs import (BRIDGES, CAM_PORT, CONFIG, DDS_PROFILE, DEFAULTS_SUBJECTS, DESCRIPTION, HD,  # noqa: E402
                         MODULE_NAMES, RATE_STEPS, RATE_SUBJECTS, STALL_SUBJECTS, SUBJECTS, SUSTAINED, TOPIC,
                         WORKLOADS, Rig, Workload, build, module_totals, say, status_kb, summarize, tail)
from report import loadavg, write_section  # noqa: E402

ROOT = h.ROOT
BENCH = h.BENCH
DOCS = ROOT / "docs" / "benchmarks.md"


# --------------------------------------------------------------------------
# stages


def available(ctx: dict, s: str) -> Optional[str]:
    info = ctx["subjects"].get(s.split("+")[0])
    if info is None or info.get("ok"):
        return None
    return info.get("error") or "not available"


def start_rig(ctx: dict, s: str, wl: Workload, profile: bool = True):
    err = available(ctx, s)
    if err:
        return None, err
    try:
        return Rig(ctx, s, wl, profile=profile).start(), None
    except (BenchError, OSError, RuntimeError, TimeoutError) as e:
        return None, str(e).strip() or type(e).__name__


def latency_stage(ctx: dict, args, subjects: tuple) -> list:
    results = []
    for wl in WORKLOADS:
        say(f"latency: {wl.label}, {len(subjects)} subjects, {args.rounds} round(s) of "
            f"{args.seconds / args.rounds:.1f} s each")
        rigs, errors = {}, {}
        for s in subjects:
            rig, err = start_rig(ctx, s, wl)
            if rig is None:
                errors[s] = err
                say(f"  {s:8s} not run: {err.splitlines()[0]}")
            else:
                rigs[s] = rig
        chunks = {s: [] for s in rigs}
        count = max(1, int(round(wl.rate * args.seconds / args.rounds)))
        try:
            for k in range(args.rounds):
                for s, rig in list(rigs.items()):
                    try:
                        c = rig.measure(count, wl.rate)
                    except (BenchError, OSError) as e:
                        errors[s] = str(e).strip()
                        say(f"  {s:8s} failed: {errors[s].splitlines()[0]}")
                        rigs.pop(s).stop()
                        continue
                    chunks[s].append(c)
                    say(f"  round {k + 1}/{args.rounds} {s:8s} delivered {c['delivered']}/{c['sent']}  "
                        f"median {fmt_ms(quant(c['lat'], 0.5))}  bad {c['bad']}")
        finally:
            memory = {s: status_kb(rig.bridge.pid) for s, rig in rigs.items() if rig.bridge is not None}
            statuses = {s: rig.stop() for s, rig in rigs.items()}
        for s in subjects:
            entry = {"workload": wl.name, "label": wl.label, "subject": s}
            if s in memory:
                entry["bridge_memory_kb"] = memory[s]
            if s in errors and not chunks.get(s):
                entry["error"] = errors[s]
            else:
                entry.update(summarize(chunks[s]))
                if s in errors:
                    entry["error_after"] = errors[s]
                if s in rigs:
                    entry["exit_status"] = statuses.get(s)
                    if s in BRIDGES:
                        log = rigs[s].bridge_log()
                        entry["bridge_totals"] = module_totals(log)
                        entry["bridge_log_tail"] = tail(log, 800)
            results.append(entry)
            if "error" not in entry:
                cpu = entry["cpu_pct"].get("bridge")
                say(f"  {s:8s} {entry['delivered']}/{entry['sent']} delivered, median "
                    f"{fmt_us(entry['median_us'])}, p99 {fmt_us(entry['p99_us'])}"
                    + (f", CPU {cpu:.1f} %" if cpu is not None and s in BRIDGES else ""))
    return results


def rate_stage(ctx: dict, args, subjects: tuple) -> list:
    results = []
    wl = HD
    for s in subjects:
        rig, err = start_rig(ctx, s, wl)
        if rig is None:
            results.append({"subject": s, "error": err})
            say(f"rate: {s} not run: {err.splitlines()[0]}")
            continue
        steps = []
        try:
            for rate in RATE_STEPS:
                count = int(rate * args.step_seconds)
                try:
                    c = rig.measure(count, rate)
                except (BenchError, OSError) as e:
                    steps.append({"rate": rate, "error": str(e).strip()})
                    say(f"rate: {s} at {rate} Hz failed: {str(e).splitlines()[0]}")
                    break
                m = summarize([c])
                recv_hz = m.get("rate_hz")
                ok = (m["lost"] == 0 and m["bad"] == 0 and (m["sent_hz"] or 0) >= SUSTAINED * rate
                      and (recv_hz or 0) >= SUSTAINED * rate)
                step = {"rate": rate, "sent": m["sent"], "delivered": m["delivered"], "lost": m["lost"],
                        "bad": m["bad"], "sent_hz": m["sent_hz"], "received_hz": recv_hz,
                        "median_us": m["median_us"], "p99_us": m["p99_us"],
                        "cpu_pct": m["cpu_pct"], "producer_late": m["producer_late"], "sustained": ok}
                steps.append(step)
                say(f"rate: {s:8s} {rate:3d} Hz: {m['delivered']}/{m['sent']} delivered, sent at "
                    f"{fmt_hz(m['sent_hz'])}, received at {fmt_hz(recv_hz)}, median {fmt_us(m['median_us'])}"
                    f"{'' if ok else '  (not sustained)'}")
        finally:
            status = rig.stop()
        best = 0
        for st in steps:
            if st.get("sustained"):
                best = st["rate"]
            else:
                break
        entry = {"subject": s, "workload": wl.name, "label": f"{wl.width}x{wl.height} {wl.pixel}",
                 "step_s": args.step_seconds, "steps": steps, "highest_sustained_hz": best,
                 "exit_status": status}
        if s in BRIDGES:
            entry["bridge_totals"] = module_totals(rig.bridge_log())
        results.append(entry)
    return results


def stall_stage(ctx: dict, args, subjects: tuple) -> list:
    """Each subject's sink SIGSTOPped while the producer goes on at 30 Hz
    1280x720; the bridges' RSS sampled every second (every subject at once)."""
    wl = HD
    rigs, results = {}, []
    for s in subjects:
        rig, err = start_rig(ctx, s, wl)
        if rig is None:
            results.append({"subject": s, "error": err})
            say(f"stall: {s} not run: {err.splitlines()[0]}")
        else:
            rigs[s] = rig
    if not rigs:
        return results
    try:
        before = {}
        for s, rig in rigs.items():
            rig.measure(int(wl.rate * 2), wl.rate)   # running, the sink reading
            before[s] = status_kb(rig.bridge.pid)
        for rig in rigs.values():
            os.kill(rig.sink.pid, signal.SIGSTOP)
        count = int(wl.rate * args.stall_seconds)
        say(f"stall: {', '.join(rigs)} at once, {args.stall_seconds:.0f} s at {wl.rate:g} Hz "
            f"{wl.width}x{wl.height}, the sinks stopped (SIGSTOP)")
        runs, errors = {}, {}

        def drive(s, rig):
            try:
                runs[s] = rig.source.run(count, wl.rate)
            except (BenchError, OSError) as e:
                errors[s] = str(e).strip()

        cpu0 = {s: h.cpu_seconds(rig.bridge.pid) for s, rig in rigs.items()}
        threads = {s: threading.Thread(target=drive, args=(s, r), daemon=True) for s, r in rigs.items()}
        t0 = time.monotonic()
        for t in threads.values():
            t.start()
        samples = {s: [] for s in rigs}
        next_report = t0 + max(5.0, args.stall_seconds / 6)
        while any(t.is_alive() for t in threads.values()):
            now = time.monotonic()
            for s, rig in rigs.items():
                st = status_kb(rig.bridge.pid)
                samples[s].append((round(now - t0, 2), st.get("VmRSS"), st.get("RssAnon"), st.get("RssShmem")))
            if now >= next_report:
                next_report += max(5.0, args.stall_seconds / 6)
                say(f"  stall {now - t0:5.0f}/{args.stall_seconds:.0f} s  " + "  ".join(
                    f"{s} {samples[s][-1][1] / 1024:.1f} MB" for s in rigs if samples[s][-1][1]))
            time.sleep(1.0)
        wall = time.monotonic() - t0
        cpu = {s: h.cpu_seconds(rig.bridge.pid) for s, rig in rigs.items()}
        for rig in rigs.values():
            os.kill(rig.sink.pid, signal.SIGCONT)
        for s, rig in rigs.items():
            series = [x[1] for x in samples[s] if x[1] is not None]
            at2 = next((x[1] for x in samples[s] if x[0] >= 2.0 and x[1] is not None),
                       series[0] if series else None)
            end = series[-1] if series else None
            last = samples[s][-1] if samples[s] else (None, None, None, None)
            b = before.get(s, {})
            rss0 = b.get("VmRSS")
            got = rig.sink.count()[0] if rig.sink.alive else None
            entry = {"subject": s, "workload": wl.name, "duration_s": args.stall_seconds, "rate": wl.rate,
                     "rss_before_kb": rss0, "rss_at_2s_kb": at2, "rss_end_kb": end,
                     "rss_peak_kb": max(series) if series else None,
                     "growth_kb": (end - rss0) if end is not None and rss0 else None,
                     "peak_growth_kb": (max(series) - rss0) if series and rss0 else None,
                     "growth_after_2s_kb": (end - at2) if end is not None and at2 is not None else None,
                     "anon_before_kb": b.get("RssAnon"), "anon_end_kb": last[2],
                     "shmem_before_kb": b.get("RssShmem"), "shmem_end_kb": last[3],
                     "peak_at_s": next((x[0] for x in samples[s] if x[1] == max(series)), None)
                     if series else None,
                     "sent": runs.get(s, {}).get("ticks"), "producer_late": runs.get(s, {}).get("late"),
                     "sink_received_after_cont": got, "alive": rig.bridge.alive,
                     "cpu_pct": (100.0 * (cpu[s] - cpu0[s]) / wall
                                 if cpu.get(s) is not None and cpu0.get(s) is not None else None),
                     "samples": downsample(samples[s], 120)}
            if s in errors:
                entry["error"] = errors[s]
            results.append(entry)
            say(f"stall: {s:8s} RSS {mb(rss0)} MB before, {mb(end)} MB at the end, peak "
                f"{mb(entry['rss_peak_kb'])} MB: growth {fmt_mb(entry['growth_kb'])} MB")
    finally:
        statuses = {s: rig.stop() for s, rig in rigs.items()}
    for e in results:
        if e["subject"] in rigs:
            e["exit_status"] = statuses[e["subject"]]
            log = rigs[e["subject"]].bridge_log()
            e["bridge_totals"] = module_totals(log)
            e["bridge_log_tail"] = tail(log, 800)
    return results


def defaults_stage(ctx: dict, args, subjects: tuple) -> list:
    """1280x720 rgb8 at 30 Hz with Fast DDS's own transports (no profile);
    the warm-up is a second of frames, whatever arrives."""
    results = []
    wl = HD
    for s in subjects:
        err = available(ctx, s)
        if err is not None:
            results.append({"subject": s, "error": err})
            continue
        rig = Rig(ctx, s, wl, profile=False, strict_warm_up=False)
        try:
            rig.start()
            c = rig.measure(int(wl.rate * args.defaults_seconds), wl.rate)
            m = summarize([c])
            results.append({"subject": s, "workload": wl.name, "seconds": args.defaults_seconds,
                            "sent": m["sent"], "delivered": m["delivered"], "lost": m["lost"], "bad": m["bad"],
                            "median_us": m["median_us"], "p99_us": m["p99_us"]})
            say(f"defaults: {s:8s} {m['delivered']}/{m['sent']} delivered (Fast DDS's default transports)")
        except (BenchError, OSError, RuntimeError, TimeoutError) as e:
            results.append({"subject": s, "error": str(e).strip()})
            say(f"defaults: {s} failed: {short(str(e))}")
        finally:
            rig.stop()
    return results


# --------------------------------------------------------------------------
# full-frame copies on each path, counted from the code


def copies() -> list:
    """The full-frame copies between the YARP socket and rcl_publish (both
    excluded: every subject reads the socket and rmw serializes), counted from
    the code and written down here; the lines quoted are checked to be there."""
    cpp = ROOT / "ybg" / "runtime" / "cpp" / "ybgc_images.cpp"
    py = ROOT / "ybg" / "runtime" / "images.py"
    rows = [
        {"subject": "relay", "copies": 1, "where": "bench/rcl/image_relay.cpp, Relay::onRead: one memcpy "
         "of the frame's rows into the Image's data (kept from frame to frame)"},
    ]
    text = cpp.read_text() if cpp.exists() else ""
    found_swap = "image->swap(in.image)" in text
    found_copy = "copyRows(msg.data.data, row, frame->getRawImage()" in text
    rows.append({"subject": "cpp", "copies": 1 if found_swap and found_copy else None,
                 "where": "ybg/runtime/cpp/ybgc_images.cpp: FramePortOf::onRead swaps the port's "
                          "FlexImage with one of a pool (no copy); the frame goes through the input's "
                          "queue as a shared_ptr (no copy); setImage copies its rows once into the "
                          "message's data (copyRows: one memcpy without row padding; the data sized "
                          "again only when the frame's size changes)",
                 "checked": found_swap and found_copy})
    rows.append(python_copies(py))
    return rows


def python_copies(py: Path) -> dict:
    """The Python node's copies, counted from ybg/runtime/images.py and
    ros2_io.py (PY_COPIES); None when the lines counted are no longer there."""
    entry = {"subject": "ros2", "copies": None, "checked": False,
             "where": "ybg/runtime/images.py: not counted (the file is not there)"}
    if not py.exists():
        return entry
    entry.update(PY_COPIES)
    text = py.read_text() + (py.parent / "ros2_io.py").read_text()
    entry["checked"] = all(s in text for s in PY_COPIES_EVIDENCE)
    if not entry["checked"]:
        entry["copies"] = None
        entry["where"] = ("ybg/runtime/images.py or ros2_io.py changed since the copies were counted: "
                          "count them again (bench/images.py, PY_COPIES)")
    return entry


# counted from ybg/runtime/images.py and ros2_io.py (docs/runtime.md, "Images", says the same)
PY_COPIES = {"copies": 2, "where": (
    "ybg/runtime/images.py: ImageInput reads each frame into a new yarp.FlexImage and gives a view of "
    "its pixels (yarp_frame: ctypes, no copy); ros2_io.fill_image copies the rows once into the "
    "message's own data, an array('B') (append_rows: one frombytes of the whole buffer when no row "
    "is padded): 1 in the node's code; rclpy then copies data into the C message at publish: 1 more "
    "(rclpy's conversion, which the C++ module has not)")}
PY_COPIES_EVIDENCE = ("out.frombytes(view[:n])", "append_rows(data, frame.data, frame.step, row, frame.height)",
                      "raw = (ctypes.c_ubyte * n).from_address(int(image.getRawImage()))")


def main(argv=None) -> int:
    import run as bench_run  # bench/run.py: machine(), source_state()

    ap = argparse.ArgumentParser(description="Benchmark of camera images: YARP image port -> "
                                             "ROS 2 sensor_msgs/Image, the modules against the floor.")
    ap.add_argument("--quick", action="store_true", help="5 s each, the stall 20 s (a smoke run)")
    ap.add_argument("--seconds", type=float, help="seconds of each subject on each workload (default 60)")
    ap.add_argument("--stall-seconds", type=float, help="seconds of the stalled sink (default 600)")
    ap.add_argument("--subjects", help="comma-separated subset of " + ",".join(SUBJECTS))
    ap.add_argument("--skip", default="", help="stages to leave out: latency,rate,stall,defaults")
    ap.add_argument("--results", type=Path, help="the JSON (default bench/results/images.json, "
                    "bench/results/quick/images.json with --quick)")
    ap.add_argument("--docs", action="store_true", help="write the docs section from this run "
                    "(the default of a full run; --quick writes none unless given)")
    ap.add_argument("--docs-file", type=Path, default=DOCS, help="the page of the section (default "
                    "docs/benchmarks.md)")
    ap.add_argument("--build-dir", type=Path, default=BENCH / "build" / "images")
    ap.add_argument("--report-only", action="store_true", help="the docs section from the JSON, run nothing")
    args = ap.parse_args(argv)

    mode = "quick" if args.quick else "full"
    args.seconds = args.seconds or (5.0 if args.quick else 60.0)
    args.stall_seconds = args.stall_seconds or (20.0 if args.quick else 600.0)
    args.rounds = 1 if args.quick else 3
    args.step_seconds = 2.0 if args.quick else 5.0
    args.defaults_seconds = min(args.seconds, 3.0 if args.quick else 10.0)
    json_path = args.results or (BENCH / "results" / ("quick" if args.quick else "") / "images.json")
    write_docs = args.docs or mode == "full"

    if args.report_only:
        data = json.loads(json_path.read_text())
        data["targets"] = targets(data)
        write_section(section(data), SECTION, args.docs_file)
        say(f"written: {args.docs_file} (section {SECTION!r})")
        return 0

    subjects = SUBJECTS
    if args.subjects:
        wanted = [s.strip() for s in args.subjects.split(",") if s.strip()]
        unknown = [s for s in wanted if s not in SUBJECTS]
        if unknown:
            ap.error(f"unknown subjects: {', '.join(unknown)}")
        subjects = tuple(s for s in SUBJECTS if s in wanted)
    skip = {s.strip() for s in args.skip.split(",") if s.strip()}

    t_start = time.monotonic()
    load0 = loadavg()
    say(f"ybgc camera image benchmark, {mode} mode ({args.seconds:g} s a subject and workload, stall "
        f"{args.stall_seconds:g} s); load average {load0}")
    mw.require_yarp()
    mw.require_ros2()
    built = build(args.build_dir, subjects)
    t_built = time.monotonic()
    tmp = mw.TmpDir("ybg-bench-images-") if hasattr(mw, "TmpDir") else None
    ctx = {"tools": built["tools"], "subjects": built["subjects"],
           "tmp": str(tmp.path) if tmp is not None else str(args.build_dir)}
    command = "python bench/images.py" + (" --quick" if args.quick else "")
    if args.seconds != (5.0 if args.quick else 60.0):
        command += f" --seconds {args.seconds:g}"
    if args.stall_seconds != (20.0 if args.quick else 600.0):
        command += f" --stall-seconds {args.stall_seconds:g}"
    data = {
        "date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": bench_run.machine(),
        "command": command,
        "mode": mode,
        "seconds": args.seconds,
        "rounds": args.rounds,
        "stall_seconds": args.stall_seconds,
        "load_before": load0,
        "results_path": os.path.relpath(json_path, ROOT) if json_path.is_absolute() else str(json_path),
        "workloads": {w.name: {"label": w.label, "width": w.width, "height": w.height, "pixel": w.pixel,
                               "rate": w.rate, "frame_mb": round(w.frame_mb, 3)} for w in WORKLOADS},
        "subjects": {s: {"description": DESCRIPTION[s], "available": built["subjects"].get(s, {}).get("ok", True),
                         "error": built["subjects"].get(s, {}).get("error")} for s in subjects},
        "config": CONFIG.format(name=MODULE_NAMES["rgb8"], port=CAM_PORT, pixel="rgb8", topic=TOPIC),
        "dds_profile": DDS_PROFILE,
        "source": bench_run.source_state(),
    }
    try:
        data["latency"] = [] if "latency" in skip else latency_stage(ctx, args, subjects)
        t_lat = time.monotonic()
        data["rate"] = [] if "rate" in skip else rate_stage(
            ctx, args, tuple(s for s in RATE_SUBJECTS if s in subjects))
        t_rate = time.monotonic()
        data["stall"] = [] if "stall" in skip else stall_stage(
            ctx, args, tuple(s for s in STALL_SUBJECTS if s.split("+")[0] in subjects))
        t_stall = time.monotonic()
        data["defaults"] = [] if "defaults" in skip else defaults_stage(
            ctx, args, tuple(s for s in DEFAULTS_SUBJECTS if s in subjects))
        t_end = time.monotonic()
    finally:
        if tmp is not None:
            tmp.remove()
    data["load_after"] = loadavg()
    data["durations_s"] = {"build": round(t_built - t_start, 1), "latency": round(t_lat - t_built, 1),
                           "rate": round(t_rate - t_lat, 1), "stall": round(t_stall - t_rate, 1),
                           "defaults": round(t_end - t_stall, 1), "total": round(t_end - t_start, 1)}
    data["copies"] = copies()
    data["targets"] = targets(data)
    data["notes"] = notes(data)
    if mode == "full" and (args.seconds < 60 or args.stall_seconds < 600):
        data["duration_note"] = (
            f"This run: {args.seconds:g} s a subject and workload and a {args.stall_seconds:g} s stall, "
            f"shorter than the targets' 60 s and 10 minutes, because of this machine's time (2 cores "
            f"shared with other work).")
    json_path.parent.mkdir(parents=True, exist_ok=True)
    json_path.write_text(json.dumps(data, indent=1) + "\n")
    print_figures(data)
    say(f"written: {json_path} ({t_end - t_start:.0f} s in all, build {t_built - t_start:.0f} s)")
    if write_docs:
        write_section(section(data), SECTION, args.docs_file)
        say(f"written: {args.docs_file} (section {SECTION!r})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
