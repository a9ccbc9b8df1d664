"""What the camera image benchmark (bench/images.py) runs: its subjects and
workloads, the config of the generated modules and Fast DDS's profile, the
build of the peers and the modules, and one subject wired up (Rig: source ->
[bridge] -> sink, with a name server and a ROS 2 domain of its own) with
the figures of its runs (summarize, module_totals, status_kb).
"""
from __future__ import annotations

import os
import re
import signal
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Optional

import blocks as h
from blocks import BenchError, mw

BENCH = h.BENCH

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
