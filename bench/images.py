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
`CONFIG` below: examples/icub_left_eye_ros2.ini without its calibration),
one for rgb8 and one for 32FC1.

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
written under the build folder: DDS_PROFILE below) of a 32 MB shared-memory
segment and 4 MB UDP buffers on 127.0.0.1. With Fast DDS's default 512 kB
segment, best-effort images of 0.9 to 2.8 MB lose most frames on this machine,
even from a bare rcl publisher to an rcl subscriber (the "defaults" stage
measures it): what every subject would then measure is Fast DDS's buffer, not
the bridge.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import signal
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
from report import fmt_load, loadavg, write_section  # noqa: E402

ROOT = h.ROOT
BENCH = h.BENCH
DOCS = ROOT / "docs" / "benchmarks.md"
SECTION = "## Camera images"

SUBJECTS = ("relay", "yarp-hop", "rcl-hop", "cpp", "ros2")
BRIDGES = ("relay", "cpp", "ros2")          # a process between the peers: its CPU is measured
DESCRIPTION = {
    "relay": "hand-written C++ relay (bench/rcl/image_relay.cpp): BufferedPort<FlexImage> read, "
             "rows copied once into a sensor_msgs/Image, rcl_publish: the floor",
    "yarp-hop": "YARP image producer -> YARP image consumer (bench/tools/image_consumer.cpp), one YARP hop",
    "rcl-hop": "rcl Image publisher (bench/rcl/image_source.cpp) -> rcl sink, one ROS 2 hop",
    "cpp": "generated C++ module (--backend cpp), rcl",
    "ros2": "generated rclpy node (--backend ros2)",
}
CAM_PORT = "/bench/cam:o"
TOPIC = "/bench/image_raw"

# the module's config: examples/icub_left_eye_ros2.ini without the calibration
CONFIG = """\
# bench/images.py: a camera's YARP port to a ROS 2 sensor_msgs/Image
# (examples/icub_left_eye_ros2.ini without its [camera_info])
[module]
name = {name}

[mux cam]
ports = {port} (image {pixel})

[output]
via = ros2
topic = {topic}
type = sensor_msgs/Image

[message]
header.frame_id = "bench_camera"
data = cam
"""
MODULE_NAMES = {"rgb8": "bench_camera_rgb", "32FC1": "bench_camera_depth"}

DDS_PROFILE = """\
<?xml version="1.0" encoding="UTF-8" ?>
<!-- bench/images.py: Fast DDS for camera images on one machine: a 32 MB
     shared-memory segment (the default, 512 kB, holds less than one frame of
     640x480 rgb8, and best-effort frames are then lost) and 4 MB UDP buffers,
     on 127.0.0.1 only -->
<dds xmlns="http://www.eprosima.com">
  <profiles>
    <transport_descriptors>
      <transport_descriptor>
        <transport_id>bench_shm</transport_id>
        <type>SHM</type>
        <segment_size>33554432</segment_size>
      </transport_descriptor>
      <transport_descriptor>
        <transport_id>bench_udp</transport_id>
        <type>UDPv4</type>
        <sendBufferSize>4194304</sendBufferSize>
        <receiveBufferSize>4194304</receiveBufferSize>
        <interfaceWhiteList><address>127.0.0.1</address></interfaceWhiteList>
      </transport_descriptor>
    </transport_descriptors>
    <participant profile_name="bench_images" is_default_profile="true">
      <rtps>
        <userTransports>
          <transport_id>bench_shm</transport_id>
          <transport_id>bench_udp</transport_id>
        </userTransports>
        <useBuiltinTransports>false</useBuiltinTransports>
      </rtps>
    </participant>
  </profiles>
</dds>
"""


@dataclass(frozen=True)
class Workload:
    name: str
    width: int
    height: int
    pixel: str
    rate: float

    @property
    def label(self) -> str:
        return f"{self.width}x{self.height} {self.pixel} at {self.rate:g} Hz"

    @property
    def frame_mb(self) -> float:
        return self.width * self.height * (4 if self.pixel == "32FC1" else 3) / 1e6


WORKLOADS = (Workload("vga_rgb8", 640, 480, "rgb8", 30.0),
             Workload("hd_rgb8", 1280, 720, "rgb8", 30.0),
             Workload("vga_32fc1", 640, 480, "32FC1", 30.0))
HD = WORKLOADS[1]
RATE_STEPS = (30, 60, 120, 240, 480)
RATE_SUBJECTS = ("relay", "cpp", "rcl-hop")
# cpp+mmap: the module with glibc's mmap threshold fixed (MALLOC_MMAP_THRESHOLD_): a
# freed frame goes back to the system at once, which tells the frames a process
# still holds from those its allocator keeps after it freed them
STALL_SUBJECTS = ("cpp", "cpp+mmap", "relay")
MMAP_THRESHOLD = 131072
DEFAULTS_SUBJECTS = ("rcl-hop", "relay", "cpp")
SUSTAINED = 0.97   # a rate is sustained: nothing lost, sent and received at >= 97 % of it


def say(text: str) -> None:
    print(text, flush=True)


# --------------------------------------------------------------------------
# building


def build(build_root: Path, want: tuple) -> dict:
    """The C++ programs and the generated modules; {"tools": {...}, "subjects":
    {subject: {"ok", "error", pixel: binary or script}}}."""
    say("building the image peers and the relay (bench/tools, bench/rcl; -DBENCH_IMAGES=ON)")
    h.cmake_build(BENCH / "tools", build_root / "tools", options=("-DBENCH_IMAGES=ON",))
    h.cmake_build(BENCH / "rcl", build_root / "rcl",
                  options=(f"-DYBGC_ROS2_PYTHON_ENV={mw.VENV}", "-DBENCH_IMAGES=ON"))
    tools = {"producer": build_root / "tools" / "bench_image_producer",
             "consumer": build_root / "tools" / "bench_image_consumer",
             "source": build_root / "rcl" / "image_source",
             "sink": build_root / "rcl" / "image_sink",
             "relay": build_root / "rcl" / "image_relay"}
    profile = build_root / "fastdds_images.xml"
    profile.write_text(DDS_PROFILE)
    tools["dds_profile"] = profile
    configs = build_root / "configs"
    configs.mkdir(parents=True, exist_ok=True)
    subjects = {}
    for s in want:
        info = {"ok": True, "error": None}
        if s in ("cpp", "ros2"):
            try:
                for pixel, name in MODULE_NAMES.items():
                    cfg = configs / f"{name}.ini"
                    cfg.write_text(CONFIG.format(name=name, port=CAM_PORT, pixel=pixel, topic=TOPIC))
                    out = build_root / "gen" / s / name
                    if s == "cpp":
                        say(f"generating and building the C++ module of {cfg.name}")
                        info[pixel] = str(h.build_generated_cpp(cfg, out, ros2=True))
                    else:
                        info[pixel] = str(h.generated_python(cfg, "ros2", out))
            except (BenchError, OSError, mw.subprocess.TimeoutExpired) as e:
                info = {"ok": False, "error": str(e).strip()}
                say(f"  {s}: not available: {info['error'].splitlines()[0]}")
        subjects[s] = info
    return {"tools": {k: str(v) for k, v in tools.items()}, "subjects": subjects}


# --------------------------------------------------------------------------
# one subject wired up


class Rig:
    """The processes of one subject on one workload, with a name server and a
    ROS 2 domain of its own: source -> [bridge] -> sink."""

    def __init__(self, ctx: dict, subject: str, wl: Workload, profile: bool = True, strict_warm_up: bool = True):
        self.ctx, self.subject, self.wl, self.profile = ctx, subject, wl, profile
        self.strict_warm_up = strict_warm_up
        self.server: Optional[mw.YarpServer] = None
        self.domain: Optional[mw.Ros2Domain] = None
        self.source: Optional[h.Source] = None
        self.sink: Optional[h.Sink] = None
        self.bridge: Optional[mw.Proc] = None
        self.tag = f"{subject.replace('+', '_')}_{wl.name}{'' if profile else '_defaults'}"

    def start(self) -> "Rig":
        s, wl, tools = self.subject.split("+")[0], self.wl, self.ctx["tools"]
        size = ["--width", wl.width, "--height", wl.height, "--pixel", wl.pixel]
        try:
            env = None
            if s != "rcl-hop":
                self.server = mw.YarpServer().start()
                env = dict(self.server.env)
            if s != "yarp-hop":
                self.domain = mw.Ros2Domain().start()
                renv = dict(self.domain.env)
                if self.server is not None:
                    renv.update(self.server.env)
                renv.update(self.domain.ros_env)
                if self.profile:
                    renv["FASTDDS_DEFAULT_PROFILES_FILE"] = tools["dds_profile"]
                env = renv
            if s == "rcl-hop":
                self.source = h.Source([tools["source"], "--topic", TOPIC, *size], env=env,
                                       name=f"image_source_{self.tag}").start()
            else:
                self.source = h.Source([tools["producer"], "--port", CAM_PORT, *size], env=env,
                                       name=f"image_producer_{self.tag}").start()
            if s == "yarp-hop":
                self.sink = h.Sink([tools["consumer"], "--port", "/bench/image_sink:i", "--source", CAM_PORT,
                                    *size], env=env, name=f"image_consumer_{self.tag}").start()
            else:
                self.sink = h.Sink([tools["sink"], "--topic", TOPIC, *size], env=env,
                                   name=f"image_sink_{self.tag}").start()
            if s == "relay":
                self.bridge = mw.Proc([tools["relay"], "--input", CAM_PORT, "--prefix", "/bench/image_relay",
                                       "--topic", TOPIC, "--strict"], env=env, name=f"image_relay_{self.tag}",
                                      die_with_parent=True)
            elif s == "cpp":
                menv = dict(env)
                if self.subject == "cpp+mmap":  # glibc gives every freed frame back to the system
                    menv["MALLOC_MMAP_THRESHOLD_"] = str(MMAP_THRESHOLD)
                self.bridge = mw.Proc([self.ctx["subjects"]["cpp"][wl.pixel], "--prefix", "/bench/cpp"], env=menv,
                                      name=f"cpp_module_{self.tag}", die_with_parent=True)
            elif s == "ros2":
                self.bridge = mw.Proc([h.PYTHON, self.ctx["subjects"]["ros2"][wl.pixel], "--ros-args",
                                       "-p", "prefix:=/bench/ros2"], env=env, name=f"ros2_node_{self.tag}",
                                      die_with_parent=True)
            if self.bridge is not None:
                self.bridge.start()
            self.sink.wait_connected(timeout=60, proc=self.bridge)
            self.source.wait_outputs(1, timeout=60, proc=self.bridge)
            self.warm_up()
        except BaseException:
            self.stop()
            raise
        return self

    def warm_up(self, batch: int = 15, tries: int = 20) -> None:
        """Frames until a batch arrives whole (the ROS 2 side matches after
        the sink saw the publisher, and a module's first frame sizes its
        buffers); not strict: a second of frames, then a pause."""
        if not self.strict_warm_up:
            self.source.run(int(self.wl.rate), self.wl.rate)
            time.sleep(1.0)
            return
        for _ in range(tries):
            self.check_alive()
            self.sink.reset()
            self.source.run(batch, self.wl.rate)
            if self.sink.settle(batch, quiet=0.5, limit=3.0) >= batch:
                return
        raise BenchError(f"{self.tag}: no batch of {batch} frames arrived whole in {tries} tries; "
                         f"{self.logs()}")

    def pids(self) -> dict:
        out = {"source": self.source.pid, "sink": self.sink.pid}
        if self.bridge is not None:
            out["bridge"] = self.bridge.pid
        return out

    def check_alive(self) -> None:
        if self.bridge is not None and not self.bridge.alive:
            raise BenchError(f"{self.bridge.name} exited (status {self.bridge.returncode}); log:\n"
                             f"{self.bridge.log_text()[-3000:]}")

    def logs(self) -> str:
        return "\n".join(f"log of {p.name}:\n{p.log_text()[-1500:]}"
                         for p in (self.bridge, self.sink, self.source) if p is not None)

    def measure(self, count: int, rate: float) -> dict:
        """One run of ``count`` frames at ``rate``: the latency figures of
        blocks.analyse_latency and each process's CPU seconds over the run."""
        self.check_alive()
        self.sink.reset()
        pids = self.pids()
        c0 = {k: h.cpu_seconds(p) for k, p in pids.items()}
        t0 = time.monotonic()
        run = self.source.run(count, rate)
        wall = time.monotonic() - t0
        cpu = {k: (h.cpu_seconds(p) - c0[k]) if c0[k] is not None and h.cpu_seconds(p) is not None else None
               for k, p in pids.items()}
        self.sink.settle(count, quiet=0.5, limit=5.0)
        path = Path(self.ctx["tmp"]) / f"{self.tag}.bin"
        records = self.sink.dump(path)
        path.unlink(missing_ok=True)
        chunk = h.analyse_latency(records, run["first"], run["ticks"], 1, per_block=False)
        chunk.update(cpu_s=cpu, wall_s=wall, late=run["late"], elapsed_s=run["elapsed"])
        chunk["sent_hz"] = run["ticks"] / run["elapsed"] if run["elapsed"] > 0 else None
        return chunk

    def stop(self) -> Optional[int]:
        status = None
        if self.sink is not None and self.sink.pid:
            try:
                os.kill(self.sink.pid, signal.SIGCONT)
            except OSError:
                pass
        if self.source is not None:
            self.source.quit()
        if self.bridge is not None:
            status = self.bridge.stop(timeout=10)
        if self.sink is not None:
            self.sink.quit()
        if self.server is not None:
            self.server.stop()
        if self.domain is not None:
            self.domain.stop()
        return status

    def bridge_log(self) -> str:
        return self.bridge.log_text() if self.bridge is not None else ""


def summarize(chunks: list) -> dict:
    """One subject on one workload over its rounds."""
    m = h.merge_latency(chunks)
    m.pop("cdf_us", None)
    m["producer_late"] = sum(c["late"] for c in chunks)
    m["sent_hz"] = (sum(c["sent"] for c in chunks) / sum(c["elapsed_s"] for c in chunks)
                    if chunks and sum(c["elapsed_s"] for c in chunks) > 0 else None)
    wall = sum(c["wall_s"] for c in chunks)
    cpu = {}
    for k in ("bridge", "sink", "source"):
        vals = [c["cpu_s"].get(k) for c in chunks]
        if vals and all(v is not None for v in vals) and wall > 0:
            cpu[k] = 100.0 * sum(vals) / wall
    m["cpu_pct"] = cpu
    return m


def module_totals(text: str) -> dict:
    """The totals a generated module prints at exit (docs/runtime.md), as far
    as they are found."""
    out = {}
    m = re.search(r"published (\d+) messages, skipped (\d+) cycles", text)
    if m:
        out["published"], out["skipped"] = int(m.group(1)), int(m.group(2))
    for key in ("received", "dropped", "stale", "unused", "refused"):
        found = re.findall(rf"\b{key} (\d+)", text)
        if found:
            out[key] = int(found[-1])
    return out


def status_kb(pid: Optional[int]) -> dict:
    """VmRSS, VmHWM (peak), RssAnon and RssShmem (DDS's shared-memory
    segments are mapped: their pages count in VmRSS) of a process, kB."""
    out = {}
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                key = line.split(":")[0]
                if key in ("VmRSS", "VmHWM", "RssAnon", "RssShmem"):
                    out[key] = int(line.split()[1])
    except (OSError, TypeError):
        pass
    return out


def tail(text: str, n: int = 1500) -> str:
    return text[-n:] if text else ""


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


if __name__ == "__main__":
    sys.exit(main())
