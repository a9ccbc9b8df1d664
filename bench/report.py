"""docs/benchmarks.md and its plots from the JSON results of bench/run.py.

    .venv/bin/python bench/run.py --report-only     (the full run's results)

The targets are evaluated here, from figures of the same run. The analysis of
what limits a missed target is written by hand in bench/findings.md (after
profiling) and included as it is.
"""
from __future__ import annotations

import json
import os
import re
from pathlib import Path
from typing import Optional

BENCH = Path(__file__).resolve().parent
ROOT = BENCH.parent
ORDER = ("direct", "relay", "relay-strict", "cpp", "py", "ros2", "cpp-ros2", "rclpy", "rcl", "rcl-relay")
COLORS = {"direct": "#555555", "relay": "#000000", "relay-strict": "#8c564b", "cpp": "#1f77b4",
          "py": "#ff7f0e", "ros2": "#2ca02c", "cpp-ros2": "#17becf", "rclpy": "#9467bd",
          "rcl": "#bcbd22", "rcl-relay": "#7f7f7f"}
WORKLOAD_TEXT = {
    "joints_100hz": "2 ports x 15 float64 at 100 Hz, event-driven",
    "joints_1khz": "2 ports x 15 float64 at 1 kHz, event-driven",
    "wide_1khz": "4 ports x 50 float64 at 1 kHz, event-driven",
    "joints_500hz": "2 ports x 15 float64 at 500 Hz, event-driven (smoke)",
}


def us(v) -> str:
    return "–" if v is None else (f"{v:,.0f}" if v >= 100 else f"{v:.1f}")


def pct(v) -> str:
    return "–" if v is None else f"{v:.0f}"


def mb(kb) -> str:
    return "–" if kb is None else f"{kb / 1024:.1f}"


def rel(path: Path, start: Path) -> str:
    return os.path.relpath(path, start).replace(os.sep, "/")


def entries(data: dict, stage: str, **match) -> list:
    return [e for e in data.get(stage, []) if all(e.get(k) == v for k, v in match.items())]


def one(data: dict, stage: str, **match) -> Optional[dict]:
    found = [e for e in entries(data, stage, **match) if "error" not in e]
    return found[0] if found else None


# --------------------------------------------------------------------------
# targets


def life(e: dict) -> str:
    """Where the module lost ticks over its whole life (every workload of the
    shape, warm-ups included): at its inputs, or between output and consumer."""
    t = e.get("life_totals") or {}
    if "module_published" not in t:
        return ""
    rec = t.get("module_inputs_received") or []
    return (f"over all its runs: {t['ticks_sent']} ticks sent, inputs received "
            f"{'/'.join(str(r) for r in rec)}, published {t['module_published']}, "
            f"consumer got {t['consumer_received']}")


def targets(data: dict) -> list:
    """Rows: target, workload, measured, limit, ratio (or value), met (True,
    False, None when not measurable), note."""
    rows = []
    workloads = []
    for e in data.get("latency", []):
        if e["workload"] not in workloads:
            workloads.append(e["workload"])

    def row(target, workload, measured, limit, ratio, met, note=""):
        rows.append({"target": target, "workload": workload, "measured": measured,
                     "limit": limit, "ratio": ratio, "met": met, "note": note})

    def against(target, workload, a, b, key, limit):
        """A row of ``a``'s figure over ``b``'s (``key``: median_us or
        cpu_pct), when both have it."""
        if not (a.get(key) and b.get(key)):
            return
        r = a[key] / b[key]
        shown = (f"{us(a[key])} / {us(b[key])} us" if key == "median_us"
                 else f"{pct(a[key])} / {pct(b[key])} %")
        row(target, workload, shown, f"{limit:g}", r, r <= limit)

    def missing(*names):
        return ", ".join(n for n in names if not get.get(n)) + " not measured"

    get: dict = {}
    for wl in workloads:
        get = {s: one(data, "latency", workload=wl, subject=s) for s in ORDER}
        relay, cpp, py, ros2 = get["relay"], get["cpp"], get["py"], get["ros2"]
        direct, rclpy, strict = get["direct"], get["rclpy"], get["relay-strict"]
        if relay and cpp:
            r = cpp["median_us"] / relay["median_us"]
            row("C++ median <= 1.15 x relay", wl, f"{us(cpp['median_us'])} / {us(relay['median_us'])} us",
                "1.15", r, r <= 1.15)
            r = cpp["p99_us"] / relay["p99_us"]
            row("C++ p99 <= 1.5 x relay", wl, f"{us(cpp['p99_us'])} / {us(relay['p99_us'])} us",
                "1.5", r, r <= 1.5)
        else:
            row("C++ median <= 1.15 x relay", wl, "–", "1.15", None, None, missing("cpp", "relay"))
        if "1khz" in wl:
            if cpp:
                notes = [f"relay: {relay['lost']} lost"] if relay else []
                notes.append(life(cpp))
                row("C++ no loss at 1 kHz", wl, f"{cpp['delivered']}/{cpp['sent']} delivered",
                    "0 lost", cpp["lost"], cpp["lost"] == 0, "; ".join(n for n in notes if n))
            else:
                row("C++ no loss at 1 kHz", wl, "–", "0 lost", None, None, missing("cpp"))
            # the same necessary work, written by hand: what the module spends
            # beyond it is the cost of its own code
            if cpp and strict and cpp.get("cpu_pct") and strict.get("cpu_pct"):
                r = cpp["cpu_pct"] / strict["cpu_pct"]
                note = (f"relay {pct(relay['cpu_pct'])} % (C++ {cpp['cpu_pct'] / relay['cpu_pct']:.2f} x)"
                        if relay and relay.get("cpu_pct") else "")
                row("C++ CPU <= 1.2 x strict relay", wl,
                    f"{pct(cpp['cpu_pct'])} / {pct(strict['cpu_pct'])} %", "1.2", r, r <= 1.2, note)
            else:
                row("C++ CPU <= 1.2 x strict relay", wl, "–", "1.2", None, None,
                    missing("cpp", "relay-strict") if not (cpp and strict) else "CPU not measured")
        if cpp and py:
            r = py["median_us"] / cpp["median_us"]
            row("Python median <= 2 x C++", wl, f"{us(py['median_us'])} / {us(cpp['median_us'])} us",
                "2", r, r <= 2.0)
        else:
            row("Python median <= 2 x C++", wl, "–", "2", None, None, missing("py", "cpp"))
        # the stream path's cost against the same work done by hand (issue of
        # the Python module's CPU doubling unseen): the stricter targets
        if "1khz" in wl and cpp and strict:
            against("C++ median <= 1.05 x strict relay", wl, cpp, strict, "median_us", 1.05)
            against("C++ CPU <= 1.05 x strict relay", wl, cpp, strict, "cpu_pct", 1.05)
        if wl == "joints_1khz" and cpp and py:
            against("Python median <= 1.5 x C++ (2 x 15 at 1 kHz)", wl, py, cpp, "median_us", 1.5)
            against("Python CPU <= 2 x C++ (2 x 15 at 1 kHz)", wl, py, cpp, "cpu_pct", 2.0)
        if get["cpp-ros2"] and get["rcl-relay"]:
            against("native ROS 2 median <= 1.05 x the rcl relay", wl, get["cpp-ros2"], get["rcl-relay"],
                    "median_us", 1.05)
        if wl == "joints_1khz":
            if py:
                row("Python no loss at 1 kHz (2 x 15)", wl, f"{py['delivered']}/{py['sent']} delivered",
                    "0 lost", py["lost"], py["lost"] == 0, life(py))
            else:
                row("Python no loss at 1 kHz (2 x 15)", wl, "–", "0 lost", None, None, missing("py"))
        if ros2 and direct and rclpy:
            base = direct["median_us"] + rclpy["median_us"]
            r = ros2["median_us"] / base
            row("ROS 2 median <= 1.5 x (YARP hop + rclpy hop)", wl,
                f"{us(ros2['median_us'])} / ({us(direct['median_us'])} + {us(rclpy['median_us'])}) us",
                "1.5", r, r <= 1.5)
        else:
            row("ROS 2 median <= 1.5 x (YARP hop + rclpy hop)", wl, "–", "1.5", None, None,
                missing("ros2", "direct", "rclpy"))
        native, rcl, floor = get["cpp-ros2"], get["rcl"], get["rcl-relay"]
        if native and direct and rcl:
            base = direct["median_us"] + rcl["median_us"]
            r = native["median_us"] / base
            notes = []
            if floor:
                # the same chain of processes with a hand-written relay: what
                # the chain costs beyond the sum of its hops measured apart
                notes.append(f"hand-written rcl relay {us(floor['median_us'])} us "
                             f"({floor['median_us'] / base:.2f} x; native {native['median_us'] / floor['median_us']:.2f} x it)")
            if ros2:
                notes.append(f"ROS 2 node {ros2['median_us'] / native['median_us']:.2f} x native")
            note = "; ".join(notes)
            row("native ROS 2 median <= 1.2 x (YARP hop + C rcl hop)", wl,
                f"{us(native['median_us'])} / ({us(direct['median_us'])} + {us(rcl['median_us'])}) us",
                "1.2", r, r <= 1.2, note)
        else:
            row("native ROS 2 median <= 1.2 x (YARP hop + C rcl hop)", wl, "–", "1.2", None, None,
                missing("cpp-ros2", "direct", "rcl"))
        if "1khz" in wl:
            if native:
                notes = [life(native)]
                if native.get("cpu_pct") and ros2 and ros2.get("cpu_pct"):
                    notes.insert(0, f"CPU {pct(native['cpu_pct'])} % against the ROS 2 node's "
                                    f"{pct(ros2['cpu_pct'])} %")
                row("native ROS 2 no loss at 1 kHz", wl, f"{native['delivered']}/{native['sent']} delivered",
                    "0 lost", native["lost"], native["lost"] == 0, "; ".join(n for n in notes if n))
            else:
                row("native ROS 2 no loss at 1 kHz", wl, "–", "0 lost", None, None, missing("cpp-ros2"))
    for e in data.get("fixed_rate", []):
        if e["subject"] == "relay":
            continue
        name = f"fixed rate within 1 % ({e['subject']})"
        wl = f"{e['shape']} {e['rate']} Hz"
        if "error" in e or e.get("error_pct") is None:
            row(name, wl, "–", "1 %", None, None, (e.get("error") or "no data").splitlines()[0][:80])
            continue
        relay = one(data, "fixed_rate", shape=e["shape"], rate=e["rate"], subject="relay")
        notes = []
        if e.get("module_skipped_cycles") is not None:
            notes.append(f"module: {e['module_published']} published, "
                         f"{e['module_skipped_cycles']} cycles skipped")
        if relay and relay.get("error_pct") is not None:
            notes.append(f"relay {relay['error_pct']:+.2f} %")
        row(name, wl, f"{e['achieved_hz']:.2f} Hz received", "1 %", abs(e["error_pct"]),
            abs(e["error_pct"]) <= 1.0, "; ".join(notes))
    floor_mem = one(data, "memory", subject="rcl-relay")
    for e in data.get("memory", []):
        if e["subject"] in ("relay", "rcl-relay"):
            continue
        if e["subject"] == "cpp-ros2" and "error" not in e:
            peak = e["rss_peak_kb"] / 1024
            note = (f"hand-written rcl relay: peak {mb(floor_mem['rss_peak_kb'])} MB"
                    if floor_mem and "error" not in floor_mem else "")
            if e.get("rss_libpython_kb") and e.get("rss_mapped_total_kb"):
                # the wheels' quirk: librcl loads libpython; a ROS 2 install does not
                note += (f"{'; ' if note else ''}at the end {mb(e['rss_mapped_total_kb'])} MB, of which "
                         f"libpython {mb(e['rss_libpython_kb'])} MB (loaded by the wheels' librcl only): "
                         f"{mb(e['rss_mapped_total_kb'] - e['rss_libpython_kb'])} MB without it")
            row("native ROS 2 RSS <= 30 MB", f"joints 1 kHz, {e.get('duration_s', 0):.0f} s",
                f"peak {mb(e['rss_peak_kb'])} MB", "30 MB", peak, peak <= 30, note)
        name = f"RSS growth < 10 MB, stalling consumer ({e['subject']})"
        wl = f"joints 1 kHz, {e.get('duration_s', 0):.0f} s"
        if "error" in e:
            row(name, wl, "–", "10 MB", None, None, e["error"].splitlines()[0][:80])
            continue
        g = e["growth_kb"] / 1024
        row(name, wl, f"{mb(e['rss_start_kb'])} -> {mb(e['rss_end_kb'])} MB", "10 MB", g,
            g < 10 and e["peak_growth_kb"] / 1024 < 10, f"peak {mb(e['rss_peak_kb'])} MB")
    return rows


# --------------------------------------------------------------------------
# plots


def plot_cdf(data: dict, workload: str, path: Path) -> bool:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    fig, ax = plt.subplots(figsize=(7.5, 4.2), dpi=110)
    drawn = False
    for s in ORDER:
        e = one(data, "latency", workload=workload, subject=s)
        if not e or not e.get("cdf_us"):
            continue
        pts = e["cdf_us"]
        ys = [i / (len(pts) - 1) for i in range(len(pts))]
        ax.step(pts, ys, where="post", color=COLORS[s], lw=1.6,
                label=f"{s} (median {us(e['median_us'])} us)")
        drawn = True
    if not drawn:
        plt.close(fig)
        return False
    ax.set_xscale("log")
    ax.set_xlabel("latency, send -> receive (us, log scale)")
    ax.set_ylabel("fraction of messages")
    ax.set_ylim(0, 1.0)
    ax.grid(True, which="both", alpha=0.3)
    ax.set_title(f"Latency CDF: {WORKLOAD_TEXT.get(workload, workload)}", fontsize=10)
    ax.legend(loc="lower right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return True


def plot_memory(data: dict, path: Path) -> bool:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return False
    series = [e for e in data.get("memory", []) if e.get("samples")]
    if not series:
        return False
    fig, ax = plt.subplots(figsize=(7.5, 3.6), dpi=110)
    for e in series:
        ts = [t for t, _ in e["samples"]]
        ax.plot(ts, [kb / 1024 for _, kb in e["samples"]], color=COLORS.get(e["subject"]),
                lw=1.4, label=e["subject"])
    ax.set_xlabel("time (s)")
    ax.set_ylabel("RSS (MB)")
    ax.set_ylim(bottom=0)
    ax.grid(True, alpha=0.3)
    st = data.get("stall", {})
    ax.set_title(f"RSS at 1 kHz, consumer stalling {st.get('for_s', '?')} s every "
                 f"{st.get('every_s', '?')} s", fontsize=10)
    ax.legend(loc="center right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return True


# --------------------------------------------------------------------------
# the page


def mark(met) -> str:
    return {True: "met", False: "**missed**", None: "not measured"}[met]


def write(data: dict, docs: Path, json_path: Path) -> Path:
    docs = Path(docs)
    docs.mkdir(parents=True, exist_ok=True)
    out = docs / "benchmarks.md"
    before = out.read_text() if out.exists() else ""
    L = []
    add = L.append
    mode = data.get("mode", "full")
    cmd = ".venv/bin/python bench/run.py" + ("" if mode == "full" else f" --{mode}")
    add("# Benchmarks of the generated bridge modules")
    add("")
    add("This page is written by the benchmark harness, `bench/run.py`, from the figures of one "
        "run (raw numbers: `" + rel(json_path, ROOT) + "`); the analysis of missed targets comes "
        "from `bench/findings.md`. Run it again with")
    add("")
    add("```")
    add(".venv/bin/python bench/run.py            # full run (about 19 minutes): this page")
    add(".venv/bin/python bench/run.py --quick    # under a minute once built: bench/results/quick/")
    add(".venv/bin/python bench/run.py --smoke    # the floors only, a few seconds (tests/test_bench.py)")
    add("```")
    add("")
    add("The full run: latency (3 workloads x 10 subjects, 5 interleaved rounds, about 5 "
        "minutes), fixed rate (3 workloads x 5 modules, 10 s each, about 3 minutes), memory "
        "(10 minutes). `--quick` runs 2 x 15 at 1 kHz only (2 rounds of 0.5 s), one fixed-rate "
        "workload for 1 s and the memory stage for 20 s; its figures are for development, not "
        "for this page. The first run also builds the C++ peers, the reference relays and the "
        "generated C++ modules (about 30 s, under `bench/build/`); every run regenerates the "
        "modules from `bench/configs/` with the working tree's ybgc. `--subjects cpp,relay`, "
        "`--skip-latency`, `--skip-fixed`, `--skip-memory` run a part; `--report-only` rewrites "
        "this page from the JSON; `bench/profile.py SUBJECT` profiles one module while it works "
        "(`--callgrind`: the instructions a C++ module runs a tick), `bench/compare.py` runs builds of "
        "other commits in the same rounds, and tests/test_cost.py counts what a message costs each "
        "module (below, \"What a message costs\"). "
        "The Python packages it needs are the `bench` extra (`pip install -e '.[bench]'`, "
        "installed by `scripts/setup.sh`): matplotlib for the plots, py-spy for profiling; "
        "CPU and memory are read from /proc.")
    add("")
    add("| run | |")
    add("|---|---|")
    add(f"| date | {data['date']} |")
    add(f"| machine | {data['machine']} |")
    add(f"| command | `{cmd}` ({data.get('durations_s', {}).get('total', '?')} s: build "
        f"{data.get('durations_s', {}).get('build', '?')} s, latency "
        f"{data.get('durations_s', {}).get('latency', '?')} s, fixed rate "
        f"{data.get('durations_s', {}).get('fixed_rate', '?')} s, memory "
        f"{data.get('durations_s', {}).get('memory', '?')} s) |")
    add(f"| load average (1, 5, 15 min) | before {fmt_load(data.get('load_before'))}, after "
        f"{fmt_load(data.get('load_after'))} |")
    add(f"| peers | {data.get('peers', '')} |")
    src = data.get("source") or {}
    if src:
        mod = ", ".join(src.get("modified") or []) or "none"
        add(f"| measured | commit {src.get('commit')}; files of ybg/ modified in the working tree: {mod} |")
        note = kept_note(before, src.get("commit"))
        if note:
            add(note)
    add("")
    add("The machine has 2 cores, shared with other work: every process of a subject (producer, "
        "module, consumer, name server) competes for them, so the tails (p99, max) move from run "
        "to run by a factor of two or more when anything else runs; medians move by some tens of "
        "percent. The load average above says how quiet this run was.")
    add("")

    # --- targets
    add("## Targets")
    add("")
    add("Ratios from figures of the same run; reported, not asserted by the tests.")
    add("")
    add("| target | workload | measured | value | limit | result | note |")
    add("|---|---|---|---|---|---|---|")
    for t in targets(data):
        v = t["ratio"]
        val = "–" if v is None else (f"{v:.2f}" if isinstance(v, float) else str(v))
        add(f"| {t['target']} | {t['workload']} | {t['measured']} | {val} | {t['limit']} | "
            f"{mark(t['met'])} | {t['note']} |")
    add("")

    # --- method
    add("## What is measured")
    add("")
    add("| subject | what |")
    add("|---|---|")
    for s, info in data.get("subjects", {}).items():
        avail = "" if info.get("available", True) else \
            f" (not available: {(info.get('error') or '').splitlines()[0][:100]})"
        add(f"| `{s}` | {info['description']}{avail} |")
    add("")
    add("| workload | config |")
    add("|---|---|")
    for k, v in data.get("shapes", {}).items():
        add(f"| {k}: {v['label']} | `bench/configs/{v['config']}` (YARP port out), "
            f"`bench/configs/{v['ros2_config']}` (ROS 2 `sensor_msgs/JointState` out) |")
    add("")
    add("- **Latency**: the producer writes one Bottle on each of its ports per tick (strict "
        "writes, absolute deadlines), each holding its sequence number and its send time "
        "(CLOCK_MONOTONIC, taken just before the write); the envelope carries the sequence "
        "number and the tick's time, one acquisition stamp for all ports of a tick, as a robot's "
        "state ports do. Every subject "
        "converts it all with `deg_to_rad`, so the consumer divides by pi/180 to read them back. "
        "Latency = receive time − the newest send time in the output (the tick's last port, whose "
        "arrival completes the set). `direct` measures each Bottle of each port. The consumer is a "
        "`yarp::os::Port` whose reader runs in the connection thread (nothing queued); the ROS 2 "
        "consumer is an rclpy subscription (reliable, depth 100) whose callback appends one tuple.")
    add("- **Delivered / sent**: distinct ticks that came out (a tick is identified by its first "
        "port's sequence number); a tick that never comes out is lost. The generated modules "
        "read their inputs strictly and match the Bottles of a tick by envelope stamp "
        "(docs/runtime.md), and so does `relay-strict`; `relay` keeps only each input's newest "
        "Bottle, as YARP does by default, so it loses a Bottle that a newer one replaces before "
        "its callback runs. *mixed*: outputs combining Bottles of different ticks; they count as "
        "delivered. The consumer checks every value of every output.")
    add("- **Two floors**, hand-written C++ relays (two YARP hops, like the modules): `relay` "
        "(`bench/relay/relay.cpp`) does the least a bridge must do: it takes each input's newest "
        "Bottle and concatenates its float64 values, converted, with no checks. `relay-strict` "
        "(`bench/relay/strict_relay.cpp`) does, plainly, the work a generated C++ module must do "
        "for each Bottle: a strict port with a callback (every Bottle, at most 64 unread), the "
        "layout checked (count and number types, as the module checks them), the envelope stamp "
        "read, a queue of at most 64 Bottles per input, the Bottles of one tick matched by stamp, "
        "a freshness check, `deg_to_rad`, and one flat Bottle of float64 written once the "
        "previous write is out (50 ms at most), as the module's output is on the wire. It keeps "
        "no statistics and prints nothing. The C++ module's CPU at 1 kHz is set against it "
        "(targets): what the module spends beyond it is the cost of its own code, not of "
        "reading strictly. `relay-strict` runs in the latency stage only (it is event-driven).")
    if data.get("cpu_window") == "source":
        add("- **CPU %** of the module process (user + system, all threads, 100 % = one core) over "
            "the time the producer ran: its CPU until its last message counts, not the wait for "
            "messages a subject lost (a relay that lost some would look cheaper); **RSS** from /proc "
            "(VmRSS; peak = VmHWM).")
    else:
        add("- **CPU %** of the module process over the measured run (user + system, all threads, "
            "100 % = one core); **RSS** from /proc (VmRSS; peak = VmHWM).")
    add("- Before each measured run a warm-up run (discarded) lets connections and buffers "
        "settle.")
    add("")

    # --- latency tables
    add("## Latency, event-driven")
    add("")
    for wl in unique(e["workload"] for e in data.get("latency", [])):
        add(f"### {WORKLOAD_TEXT.get(wl, wl)}")
        add("")
        add("| subject | median us | rounds' medians us | p99 us | max us | delivered / sent | "
            "output rate Hz | CPU % | RSS MB (peak) | source / sink CPU % |")
        add("|---|---|---|---|---|---|---|---|---|---|")
        for s in ORDER:
            for e in entries(data, "latency", workload=wl, subject=s):
                if "error" in e:
                    add(f"| `{s}` | {short_err(e['error'])} | | | | | | | | |")
                    continue
                extra = []
                if e.get("mismatched"):
                    extra.append(f"{e['mismatched']} mixed")
                if e.get("bad"):
                    extra.append(f"{e['bad']} bad")
                if e.get("restarted_after"):
                    extra.append("restarted once after: "
                                 + e["restarted_after"].splitlines()[0].replace("|", "/")[:80])
                deliv = f"{e['delivered']} / {e['sent']}" + (f" ({', '.join(extra)})" if extra else "")
                rate = "–" if e.get("rate_hz") is None else f"{e['rate_hz']:.1f}"
                rm = [x for x in e.get("run_medians_us") or [] if x is not None]
                spread = f"{us(min(rm))}–{us(max(rm))}" if len(rm) > 1 else "–"
                add(f"| `{s}` | {us(e['median_us'])} | {spread} | {us(e['p99_us'])} | {us(e['max_us'])} | "
                    f"{deliv} | {rate} | {pct(e.get('cpu_pct'))} | {mb(e.get('rss_peak_kb'))} | "
                    f"{pct(e.get('source_cpu_pct'))} / {pct(e.get('sink_cpu_pct'))} |")
        png = docs / f"bench_latency_{wl}.png"
        if plot_cdf(data, wl, png):
            add("")
            add(f"![latency CDF, {wl}]({rel(png, docs)})")
        add("")

    # --- fixed rate
    if data.get("fixed_rate"):
        add("## Fixed rate")
        add("")
        add("The module runs with `--rate HZ` (the ROS 2 node with `-p rate:=HZ`), fed by the "
            "producer at the same rate; the rate is counted on the consumer's receive times over "
            "a window inside the producer's run (from 0.5 s after its start). *first / last "
            "third*: the rate over the first and the last third of the window (drift shows as a "
            "difference); *skipped*: the cycles the module itself reports skipped at exit (its "
            "whole run); *gaps*: intervals longer than 1.5 periods between received messages, "
            "counted in periods (a late delivery makes a gap and a burst, without a lost cycle); "
            "*jitter*: |interval − period| as received (it includes both hops).")
        add("")
        add("| workload | subject | achieved Hz | error % | first / last third Hz | skipped | gaps | "
            "jitter p99 us | CPU % |")
        add("|---|---|---|---|---|---|---|---|---|")
        for e in data["fixed_rate"]:
            wl = f"{e['shape']} {e['rate']} Hz"
            if "error" in e or e.get("achieved_hz") is None:
                add(f"| {wl} | `{e['subject']}` | {short_err(e.get('error') or 'no data')} | | | | | | |")
                continue
            thirds = (f"{e['first_third_hz']:.2f} / {e['last_third_hz']:.2f}"
                      if e.get("first_third_hz") else "–")
            skipped = e.get("module_skipped_cycles")
            add(f"| {wl} | `{e['subject']}` | {e['achieved_hz']:.2f} | {e['error_pct']:+.2f} | "
                f"{thirds} | {'–' if skipped is None else skipped} | {e['gaps']} | "
                f"{us(e['jitter_p99_us'])} | {pct(e.get('cpu_pct'))} |")
        add("")

    # --- memory
    if data.get("memory"):
        st = data.get("stall", {})
        add("## Memory under a stalling consumer")
        add("")
        add(f"Every module at once (each with its own name server, producer and consumer; "
            f"ROS 2 in its own domain), event-driven, fed at 1 kHz with the 2 x 15 workload, "
            f"its consumer stopping reading for {st.get('for_s')} s every {st.get('every_s')} s "
            f"(the YARP consumer's reader sleeps in the connection thread, so the socket fills "
            f"and the module's writes back up; the rclpy one sleeps in its callback). RSS sampled "
            f"every second; growth = last sample − the sample at 2 s. libpython's pages: the RSS "
            f"of its mappings at the end (/proc/PID/smaps); the ROS 2 wheels' librcl loads it into "
            f"the native modules too, which a ROS 2 install from its own packages does not.")
        add("")
        add("| subject | duration s | RSS at 2 s MB | RSS at end MB | peak MB | growth MB | "
            "delivered / sent | libpython's pages at end MB |")
        add("|---|---|---|---|---|---|---|---|")
        for e in data["memory"]:
            if "error" in e:
                add(f"| `{e['subject']}` | {short_err(e['error'])} | | | | | | |")
                continue
            add(f"| `{e['subject']}` | {e['duration_s']:.0f} | {mb(e['rss_start_kb'])} | "
                f"{mb(e['rss_end_kb'])} | {mb(e['rss_peak_kb'])} | {e['growth_kb'] / 1024:+.2f} | "
                f"{e['received']} / {e['sent']} | "
                f"{mb(e['rss_libpython_kb']) if e.get('rss_libpython_kb') is not None else '–'} |")
        png = docs / "bench_memory.png"
        if plot_memory(data, png):
            add("")
            add(f"![RSS over time]({rel(png, docs)})")
        add("")

    # --- findings
    findings = BENCH / "findings.md"
    if findings.exists():
        add(findings.read_text().rstrip())
        add("")

    # --- compiler
    comp = ROOT / "bench" / "results" / "compiler.json"
    if comp.exists():
        c = json.loads(comp.read_text())
        add("## The compiler itself")
        add("")
        add(f"From `bench/compiler.py` (`{c.get('command')}`, {c.get('date')}, {c.get('machine')}; "
            f"raw: `bench/results/compiler.json`).")
        add("")
        add("| figure | value |")
        add("|---|---|")
        add(f"| `ybgc check` of {c['check_files']} configs, one process | "
            f"{c['check_s'] * 1000:.0f} ms ({c['check_over_bare']:.1f} x a bare `python -c pass`, "
            f"{c['bare_python_s'] * 1000:.0f} ms) |")
        add(f"| synthetic config, 1,000 muxes x 8 ports, 2,000 fields ({c['mux1000_lines']} lines) | "
            f"{c['mux1000_wall_s'] * 1000:.0f} ms wall |")
        for g in c.get("growth", []):
            add(f"| {g['fields']:,} fields, {g['muxes']} muxes, in process | "
                f"{g['seconds'] * 1000:.1f} ms ({g['us_per_field']:.0f} us per field) |")
        add(f"| time per field, largest / smallest | "
            f"{c['growth_per_field_ratio_largest_to_smallest']:.2f} (1.0 = linear) |")
        add("")
    text = "\n".join(L).rstrip() + "\n"
    # the sections other benches wrote (images, compose, services: each
    # puts its own back with --report-only), kept as they are
    own = set(re.findall(r"^## .*$", text, re.M))
    for title, section in sections(before):
        if title not in own:
            text = text.rstrip() + "\n\n" + section.rstrip() + "\n"
    out.write_text(text)
    return out


def sections(page: str) -> list:
    """[(its "## " line, its text)] of each section of a page."""
    starts = [m.start() for m in re.finditer(r"^## ", page, re.M)] + [len(page)]
    return [(page[a:b].splitlines()[0], page[a:b]) for a, b in zip(starts, starts[1:])]


def kept_note(page: str, commit) -> str:
    """The row of the page's run table that says why the runtime's changes
    since the run were not measured (tests/test_benchmarks_page.py), when
    the page is written again from the same run (--report-only); a new run
    leaves it out."""
    head = page.split("\n## ", 1)[0]
    measured = re.search(r"^\| measured \| commit (\S+?);", head, re.M)
    note = re.search(r"^\| not rerun for \|.*\|$", head, re.M)
    if commit and measured and note and measured.group(1) == commit:
        return note.group(0)
    return ""


def unique(items) -> list:
    seen = []
    for x in items:
        if x not in seen:
            seen.append(x)
    return seen


def short_err(err: str) -> str:
    line = (err or "").strip().splitlines()[0] if err else ""
    return "failed: " + line.replace("|", "/")[:120]


def fmt_load(load) -> str:
    return ", ".join(f"{x:.2f}" for x in load) if load else "?"


def loadavg() -> list:
    """The load average (1, 5, 15 min), or [] where /proc has none."""
    try:
        return [float(x) for x in Path("/proc/loadavg").read_text().split()[:3]]
    except OSError:
        return []


def write_section(text: str, section: str, path: Path) -> None:
    """Puts ``text``, the section headed ``section`` (a ``## `` line), in
    place of the one the page has, else at its end."""
    page = path.read_text() if path.exists() else ""
    start = page.find("\n" + section + "\n")
    if start >= 0:
        nxt = page.find("\n## ", start + 1 + len(section))
        page = page[:start + 1] + text + ("\n" + page[nxt + 1:] if nxt >= 0 else "")
    else:
        page = page.rstrip() + "\n\n" + text
    path.write_text(page)


if __name__ == "__main__":
    import sys
    path = Path(sys.argv[1]) if len(sys.argv) > 1 else BENCH / "results" / "bridges.json"
    write(json.loads(path.read_text()), ROOT / "docs", path)
