"""The figures of the camera image benchmark (bench/images.py): the targets
from the figures of one run, the lines it prints, and its section of
docs/benchmarks.md ("Camera images"), with what was not measured.
"""
from __future__ import annotations

from typing import Optional

import blocks as h
from images_rigs import DESCRIPTION, MMAP_THRESHOLD, RATE_STEPS, SUBJECTS, SUSTAINED, WORKLOADS, say
from report import fmt_load

SECTION = "## Camera images"


# --------------------------------------------------------------------------
# figures


def quant(values: list, q: float) -> Optional[float]:
    return h.quantile(sorted(values), q) if values else None


def fmt_us(v) -> str:
    return "-" if v is None else f"{v:,.0f} us"


def fmt_ms(v) -> str:
    return "-" if v is None else f"{v * 1e3:.2f} ms"


def fmt_hz(v) -> str:
    return "-" if v is None else f"{v:.1f} Hz"


def mb(kb) -> str:
    return "-" if kb is None else f"{kb / 1024:.1f}"


def fmt_mb(kb) -> str:
    return "-" if kb is None else f"{kb / 1024:+.2f}"


def downsample(series: list, n: int) -> list:
    if len(series) <= n:
        return [list(x) for x in series]
    step = len(series) / n
    return [list(series[int(i * step)]) for i in range(n)] + [list(series[-1])]


def ratio(a, b) -> Optional[float]:
    return a / b if a is not None and b else None


def targets(data: dict) -> list:
    """The targets, from figures of the same run."""
    out = []

    def lat(wl, s):
        for e in data["latency"]:
            if e["workload"] == wl and e["subject"] == s and "error" not in e:
                return e
        return None

    for wl in WORKLOADS:
        relay, cpp, ros2 = lat(wl.name, "relay"), lat(wl.name, "cpp"), lat(wl.name, "ros2")
        label = wl.label
        if relay and cpp:
            for what, key in (("median", "median_us"), ("p99", "p99_us")):
                r = ratio(cpp[key], relay[key])
                out.append({"target": f"native {what} latency <= 1.1 x relay", "workload": label,
                            "measured": f"{cpp[key] / 1e3:.2f} / {relay[key] / 1e3:.2f} ms", "value": r,
                            "limit": 1.1, "met": r is not None and r <= 1.1})
            cc, rc = cpp["cpu_pct"].get("bridge"), relay["cpu_pct"].get("bridge")
            r = ratio(cc, rc)
            out.append({"target": "native CPU <= 1.1 x relay", "workload": label,
                        "measured": f"{cc:.1f} / {rc:.1f} %" if cc is not None and rc is not None else "-",
                        "value": r, "limit": 1.1, "met": r is not None and r <= 1.1})
            out.append({"target": "native: no loss", "workload": label,
                        "measured": f"{cpp['delivered']}/{cpp['sent']} delivered", "value": cpp["lost"],
                        "limit": 0, "met": cpp["lost"] == 0 and cpp["bad"] == 0,
                        "note": f"relay {relay['delivered']}/{relay['sent']}"})
        else:
            out.append({"target": "native / relay", "workload": label, "measured": "not measured",
                        "value": None, "limit": None, "met": None})
        if ros2 and cpp:
            r = ratio(ros2["median_us"], cpp["median_us"])
            out.append({"target": "ros2 median latency <= 2 x native", "workload": label,
                        "measured": f"{ros2['median_us'] / 1e3:.2f} / {cpp['median_us'] / 1e3:.2f} ms",
                        "value": r, "limit": 2.0, "met": r is not None and r <= 2.0,
                        "note": f"p99 {ratio(ros2['p99_us'], cpp['p99_us']):.2f} x"
                        if ros2["p99_us"] and cpp["p99_us"] else ""})
            rc, cc = ros2["cpu_pct"].get("bridge"), cpp["cpu_pct"].get("bridge")
            r = ratio(rc, cc)
            out.append({"target": "ros2 CPU <= 2 x native", "workload": label,
                        "measured": f"{rc:.1f} / {cc:.1f} %" if rc is not None and cc is not None else "-",
                        "value": r, "limit": 2.0, "met": r is not None and r <= 2.0})
            out.append({"target": "ros2: no loss at 30 Hz", "workload": label,
                        "measured": f"{ros2['delivered']}/{ros2['sent']} delivered", "value": ros2["lost"],
                        "limit": 0, "met": ros2["lost"] == 0 and ros2["bad"] == 0})
        else:
            err = next((e.get("error") for e in data["latency"]
                        if e["workload"] == wl.name and e["subject"] == "ros2" and "error" in e), None)
            out.append({"target": "ros2 / native", "workload": label, "measured": "not measured",
                        "value": None, "limit": 2.0, "met": None,
                        "note": short(err) if err else ""})
    rates = {e["subject"]: e for e in data.get("rate", []) if "error" not in e}
    if "relay" in rates and "cpp" in rates:
        rr, cr = rates["relay"]["highest_sustained_hz"], rates["cpp"]["highest_sustained_hz"]
        out.append({"target": "native highest rate without loss / relay's", "workload": "1280x720 rgb8",
                    "measured": f"{highest(rates['cpp'])} / {highest(rates['relay'])}", "value": ratio(cr, rr), "limit": None, "met": None,
                    "note": f"steps {', '.join(str(r) for r in RATE_STEPS)} Hz, "
                            f"{rates['relay']['step_s']:g} s each"})
    for e in data.get("stall", []):
        if e["subject"] != "cpp":
            continue
        if "error" in e and e.get("growth_kb") is None:
            out.append({"target": "native RSS growth < 10 MB, sink stopped", "workload": "1280x720 rgb8 30 Hz",
                        "measured": "not measured", "value": None, "limit": 10, "met": None,
                        "note": short(e["error"])})
            continue
        g = max(e["growth_kb"], e["peak_growth_kb"]) / 1024
        out.append({"target": "native RSS growth < 10 MB, sink stopped",
                    "workload": f"1280x720 rgb8 30 Hz, {e['duration_s']:.0f} s",
                    "measured": f"{mb(e['rss_before_kb'])} -> {mb(e['rss_end_kb'])} MB (peak "
                                f"{mb(e['rss_peak_kb'])})", "value": g, "limit": 10, "met": g < 10,
                    "note": "growth: the peak or the end, the larger, over the RSS before the stall"})
    return out


def short(text: Optional[str]) -> str:
    return ((text or "").strip().splitlines() or [""])[0].replace("|", "/")[:160]


def print_figures(data: dict) -> None:
    say("")
    say("Camera images: latency (receive time - header.stamp), CPU (user + sys / wall), loss")
    say(f"{'workload':24s} {'subject':9s} {'delivered':>11s} {'median':>10s} {'p99':>10s} "
        f"{'max':>10s} {'CPU %':>6s} {'sink %':>7s}")
    for e in data["latency"]:
        if "error" in e:
            say(f"{e['label']:24s} {e['subject']:9s} not measured: {short(e['error'])}")
            continue
        cpu = e["cpu_pct"].get("bridge")
        say(f"{e['label']:24s} {e['subject']:9s} {e['delivered']:>5d}/{e['sent']:<5d} "
            f"{e['median_us'] / 1e3 if e['median_us'] else float('nan'):8.2f}ms "
            f"{e['p99_us'] / 1e3 if e['p99_us'] else float('nan'):8.2f}ms "
            f"{e['max_us'] / 1e3 if e['max_us'] else float('nan'):8.2f}ms "
            f"{'' if cpu is None else f'{cpu:6.1f}':>6s} {e['cpu_pct'].get('sink', float('nan')):7.1f}")
    for e in data.get("rate", []):
        if "error" in e:
            say(f"rate {e['subject']}: not measured: {short(e['error'])}")
            continue
        say(f"rate {e['subject']:8s} highest sustained {highest(e)}: " + ", ".join(
            f"{st['rate']} Hz {st.get('delivered', '?')}/{st.get('sent', '?')}" for st in e["steps"]))
    for e in data.get("stall", []):
        if e.get("growth_kb") is None:
            say(f"stall {e['subject']}: not measured: {short(e.get('error'))}")
            continue
        say(f"stall {e['subject']:8s} RSS {mb(e['rss_before_kb'])} -> {mb(e['rss_end_kb'])} MB, peak "
            f"{mb(e['rss_peak_kb'])} MB, growth {fmt_mb(e['growth_kb'])} MB over {e['duration_s']:.0f} s")
    for e in data.get("defaults", []):
        if "error" in e:
            say(f"defaults {e['subject']}: {short(e['error'])}")
        else:
            say(f"defaults {e['subject']:8s} {e['delivered']}/{e['sent']} delivered with Fast DDS's default "
                f"transports")
    say("")
    say("Targets:")
    for t in data["targets"]:
        v = t["value"]
        res = "met" if t["met"] else ("MISSED" if t["met"] is False else "-")
        say(f"  {t['target']:45s} {t['workload']:28s} {t['measured']:28s} "
            f"{'' if v is None else f'{v:.2f}':>6s} {res}  {t.get('note', '')}")
    say("")
    say("Full-frame copies between the YARP socket and rcl_publish: " + ", ".join(
        f"{c['subject']} {c['copies'] if c['copies'] is not None else '?'}" for c in data["copies"]))


# --------------------------------------------------------------------------
# the docs section


def section(data: dict) -> str:
    L = []
    add = L.append
    full = data["mode"] == "full"
    add(SECTION)
    add("")
    add(f"Written by `bench/images.py` from the figures of one run (raw numbers: "
        f"`{data['results_path']}`). A YARP camera port to a ROS 2 `sensor_msgs/Image`: the "
        f"generated modules against a hand-written relay, on the same workloads in the same run. "
        f"Benchmarks here measure and report; the targets are not asserted by the tests. "
        f"`bench/run.py` writes this page anew: `bench/images.py --report-only` puts this section "
        f"back from its JSON.")
    add("")
    add("| run | |")
    add("|---|---|")
    add(f"| date | {data['date']} |")
    add(f"| machine | {data['machine']} |")
    add(f"| command | `{data['command']}` ({data['durations_s']['total']:.0f} s) |")
    add(f"| load average (1, 5, 15 min) | before {fmt_load(data['load_before'])}, after "
        f"{fmt_load(data['load_after'])} |")
    add(f"| measured | commit {data['source']['commit']}; files of ybg/ modified in the working tree: "
        f"{', '.join(data['source']['modified']) or 'none'} |")
    add("")
    if data.get("duration_note"):
        add(data["duration_note"])
        add("")
    add("Each frame is written by a C++ producer on a `BufferedPort<FlexImage>` "
        "(bench/tools/image_producer.cpp, rows packed), its envelope (seq, send time) set; the "
        "bridges copy the envelope into `header.stamp`, and the sink, C++ on rcl "
        "(bench/rcl/image_sink.cpp: an rclpy sink would add its own copy and interpreter to every "
        "figure), records receive time − `header.stamp`, both CLOCK_MONOTONIC, checks each frame's "
        "size, encoding and the stamps the producer put in its first and last bytes, and counts "
        "the frames (lost = sent − received). The sink subscribes best effort, keep last 20; the "
        "relay and the modules publish best effort, keep last 5 (the sensor-data QoS, the modules' "
        "default for an Image); the relay reads strictly, as the module does with its default "
        "`queue` (64). Each subject has its own yarpserver and ROS 2 domain; the rigs of a workload "
        "are up at once and measured in turn, "
        f"{data['rounds']} round(s) of {data['seconds'] / data['rounds']:.0f} s each "
        f"({data['seconds']:.0f} s a subject and workload). "
        "CPU: user + system time of the process over the wall time of its runs (100 % = one core).")
    add("")
    add("Fast DDS ran with a profile of a 32 MB shared-memory segment and 4 MB UDP buffers on "
        "127.0.0.1 (`FASTDDS_DEFAULT_PROFILES_FILE`, written by bench/images.py): with Fast DDS's "
        "default 512 kB segment, best-effort frames of 0.9 to 2.8 MB are lost on this machine even "
        "from a bare rcl publisher to an rcl subscriber (below, \"Fast DDS's default transports\"), "
        "and every subject would measure that buffer rather than the bridge.")
    add("")
    add("| subject | what |")
    add("|---|---|")
    for s in SUBJECTS:
        add(f"| `{s}` | {DESCRIPTION[s]} |")
    add("")
    add("### Targets")
    add("")
    add("| target | workload | measured | value | limit | result | note |")
    add("|---|---|---|---|---|---|---|")
    for t in data["targets"]:
        v = t["value"]
        res = "met" if t["met"] else ("**missed**" if t["met"] is False else "–")
        add(f"| {t['target']} | {t['workload']} | {t['measured']} | {'–' if v is None else f'{v:.2f}'} | "
            f"{'–' if t['limit'] is None else t['limit']} | {res} | {t.get('note', '')} |")
    add("")
    add("### Latency, CPU and loss at 30 Hz")
    add("")
    add("| workload | subject | delivered / sent | bad | median ms | p99 ms | max ms | CPU % | "
        "sink CPU % | producer late |")
    add("|---|---|---|---|---|---|---|---|---|---|")
    for e in data["latency"]:
        if "error" in e:
            add(f"| {e['label']} | `{e['subject']}` | not measured: {short(e['error'])} | | | | | | | |")
            continue
        cpu = e["cpu_pct"].get("bridge")
        add(f"| {e['label']} | `{e['subject']}` | {e['delivered']} / {e['sent']} | {e['bad']} | "
            f"{ms(e['median_us'])} | {ms(e['p99_us'])} | {ms(e['max_us'])} | "
            f"{'–' if cpu is None else f'{cpu:.1f}'} | {e['cpu_pct'].get('sink', 0):.1f} | "
            f"{e['producer_late']} |")
    add("")
    add("`yarp-hop` + `rcl-hop` is the least two hops cost without a bridge; the relay adds its "
        "one copy and the two middlewares' threads to that.")
    add("")
    add("### Highest rate without loss, 1280x720 rgb8")
    add("")
    rates = [e for e in data.get("rate", []) if "error" not in e]
    if rates:
        add(f"The rate stepped up, {rates[0]['step_s']:g} s a step, the same rig throughout; a rate is "
            f"sustained when nothing is lost and frames are sent and received at >= "
            f"{SUSTAINED * 100:.0f} % of it (the producer writes strictly: a bridge that reads slowly "
            f"slows it down). Latency median / p99 in ms.")
        add("")
        add("| subject | " + " | ".join(f"{r} Hz" for r in RATE_STEPS) + " | highest sustained |")
        add("|---|" + "---|" * len(RATE_STEPS) + "---|")
        for e in rates:
            cells = []
            for r in RATE_STEPS:
                st = next((x for x in e["steps"] if x["rate"] == r), None)
                if st is None or "error" in st:
                    cells.append("–")
                    continue
                cells.append(f"{st['delivered']}/{st['sent']}, recv {st['received_hz'] or 0:.0f} Hz, "
                             f"{ms(st['median_us'])} / {ms(st['p99_us'])}"
                             + ("" if st["sustained"] else " ✗"))
            add(f"| `{e['subject']}` | " + " | ".join(cells) + f" | {highest(e)} |")
    for e in data.get("rate", []):
        if "error" in e:
            add(f"\n`{e['subject']}`: not measured: {short(e['error'])}")
    for e in rates:
        t = e.get("bridge_totals") or {}
        if "received" in t:
            add("")
            add(f"`{e['subject']}`'s own totals over the steps (warm-up included): received "
                f"{t['received']}, published {t.get('published')}, unused {t.get('unused', 0)}, dropped "
                f"{t.get('dropped', 0)}: a frame left unused is one its input's queue (`queue`, 64 frames by "
                f"default) gave up, the oldest, when the module fell behind; the relay's strict "
                f"BufferedPort has no bound, so it loses nothing there and lags instead (its latency).")
    add("")
    add("### Memory under a stopped subscriber")
    add("")
    add("The sink SIGSTOPped while the producer goes on at 30 Hz 1280x720 rgb8; the bridge's RSS "
        "sampled every second. Beside the module, at once, each with its own producer and stopped "
        "sink: the relay, for reference, and `cpp+mmap`, the same module with glibc's mmap threshold "
        f"fixed (`MALLOC_MMAP_THRESHOLD_={MMAP_THRESHOLD}`: a frame freed goes back to the system at "
        "once), which tells the frames the module holds from those its allocator keeps after they "
        "were freed. Growth: RSS at "
        "the end − RSS just before the stall (the sink reading); peak: the highest sample; anonymous: "
        "the process's own memory (RssAnon), apart from the pages of DDS's shared-memory segment "
        "(RssShmem), which count in the RSS too.")
    add("")
    add("| subject | duration s | RSS before MB | at end MB | peak MB | growth MB | peak − before MB | "
        "anonymous before → end MB | peak at s | CPU % | alive |")
    add("|---|---|---|---|---|---|---|---|---|---|---|")
    for e in data.get("stall", []):
        if e.get("growth_kb") is None:
            add(f"| `{e['subject']}` | not measured: {short(e.get('error'))} | | | | | | | | | |")
            continue
        add(f"| `{e['subject']}` | {e['duration_s']:.0f} | {mb(e['rss_before_kb'])} | {mb(e['rss_end_kb'])} | "
            f"{mb(e['rss_peak_kb'])} | {fmt_mb(e['growth_kb'])} | {fmt_mb(e['peak_growth_kb'])} | "
            f"{mb(e.get('anon_before_kb'))} → {mb(e.get('anon_end_kb'))} | "
            f"{secs(e.get('peak_at_s'))} | "
            f"{pct(e['cpu_pct'])} | {'yes' if e['alive'] else 'no'} |")
    if data.get("stall_note"):
        add("")
        add(data["stall_note"])
    add("")
    add("### Fast DDS's default transports")
    add("")
    add("1280x720 rgb8 at 30 Hz without the profile above (Fast DDS's built-in transports: "
        "a 512 kB shared-memory segment):")
    add("")
    add("| subject | delivered / sent | median ms | p99 ms |")
    add("|---|---|---|---|")
    for e in data.get("defaults", []):
        if "error" in e:
            add(f"| `{e['subject']}` | not measured: {short(e['error'])} | | |")
        else:
            add(f"| `{e['subject']}` | {e['delivered']} / {e['sent']} | {ms(e['median_us'])} | "
                f"{ms(e['p99_us'])} |")
    add("")
    add("### Full-frame copies")
    add("")
    add("Between the YARP socket and `rcl_publish`, counted from the code: every subject reads the "
        "frame off the socket into an image, and rmw serializes the message into DDS's buffers, "
        "so neither is counted.")
    add("")
    add("| subject | copies | where |")
    add("|---|---|---|")
    for c in data["copies"]:
        add(f"| `{c['subject']}` | {'?' if c['copies'] is None else c['copies']} | {c['where']} |")
    add("")
    if data.get("notes"):
        add("### Not measured")
        add("")
        for n in data["notes"]:
            add(f"- {n}")
        add("")
    if not full:
        add(f"These are the figures of a `--{data['mode']}` run.")
        add("")
    return "\n".join(L).rstrip() + "\n"


def highest(e: dict) -> str:
    """The highest rate sustained, "≥" when it is the highest step."""
    best = e["highest_sustained_hz"]
    if best == 0:
        return f"none (< {RATE_STEPS[0]} Hz)"
    return f"≥ {best} Hz (the highest step)" if best == RATE_STEPS[-1] else f"{best} Hz"


def ms(v) -> str:
    return "–" if v is None else f"{v / 1e3:.2f}"


def secs(v) -> str:
    return "–" if v is None else f"{v:.0f}"


def pct(v) -> str:
    return "–" if v is None else f"{v:.1f}"


def notes(data: dict) -> list:
    out = []
    for s, info in data["subjects"].items():
        if not info["available"]:
            out.append(f"`{s}`: not built: {short(info['error'])}")
    for e in data["latency"]:
        if "error" in e:
            out.append(f"`{e['subject']}` on {e['label']}: {short(e['error'])}")
    out.append("CameraInfo: the configs publish no [camera_info] (the relay publishes none); a "
               "CameraInfo beside each image is one small message more.")
    out.append("The rclpy node (`ros2`) in the rate and stall stages: only the C++ module is held to "
               "the relay's highest rate and to the RSS target; the node's memory at the end of each "
               "workload is in the JSON (bridge_memory_kb).")
    out.append("Reliable QoS: every bridge publishes best effort (the modules' default for an Image); "
               "a config with `reliability = reliable` was not measured.")
    out.append("ROS 2 -> YARP images (examples/ros2_camera_to_yarp.ini): not in this benchmark.")
    return out
