"""Building blocks of the bridge benchmark (bench/run.py drives them).

Processes are started with the test suite's real-middleware helpers
(tests/harness/, under the name tests/middleware.py gives them: YarpServer,
Ros2Domain, Proc), each in its own process
group, stopped on exit. The peers are bench/tools/producer.cpp and
consumer.cpp (C++ against YARP 3.5) and bench/peers/ros2_*.py (rclpy); they
take commands on stdin and answer one line each.

Time base: every process stamps with CLOCK_MONOTONIC (C++ clock_gettime,
Python time.monotonic), so latencies compare clocks of one machine.
"""
from __future__ import annotations

import array
import math
import os
import queue
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Optional

ROOT = Path(__file__).resolve().parents[1]
BENCH = ROOT / "bench"
sys.path.insert(0, str(ROOT / "tests"))

import middleware as mw  # noqa: E402  (tests/middleware.py: the helpers of tests/harness/)

REC_FIELDS = 11          # recv, blocks, bad, (seq, t) x 4: see consumer.cpp
CLK_TCK = os.sysconf("SC_CLK_TCK")
YBGC = mw.VENV / "bin" / "ybgc"
PYTHON = str(mw.VENV_PYTHON)


class BenchError(RuntimeError):
    pass


# --------------------------------------------------------------------------
# building


def run_cmd(argv, cwd=None, env=None, timeout=900) -> subprocess.CompletedProcess:
    return subprocess.run([str(a) for a in argv], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=timeout)


def cmake_build(src: Path, build: Path, target: Optional[str] = None, options: tuple = ()) -> None:
    """Configure (once) and build a CMake project against the venv's YARP."""
    build.mkdir(parents=True, exist_ok=True)
    if not (build / "CMakeCache.txt").exists():
        r = run_cmd(["cmake", "-S", src, "-B", build, "-DCMAKE_BUILD_TYPE=Release",
                     f"-DCMAKE_PREFIX_PATH={mw.cmake_prefix_path()}", *options])
        if r.returncode:
            raise BenchError(f"cmake configure of {src} failed:\n{(r.stdout + r.stderr)[-3000:]}")
    argv = ["cmake", "--build", build, "-j", "2"]
    if target:
        argv += ["--target", target]
    r = run_cmd(argv)
    if r.returncode:
        raise BenchError(f"build of {src} failed:\n{(r.stdout + r.stderr)[-3000:]}")


def build_tools(build_root: Path) -> dict:
    """bench_producer, bench_consumer and the reference relays; returns their paths."""
    cmake_build(BENCH / "tools", build_root / "tools")
    cmake_build(BENCH / "relay", build_root / "relay")
    return {"producer": build_root / "tools" / "bench_producer",
            "consumer": build_root / "tools" / "bench_consumer",
            "relay": build_root / "relay" / "relay",
            "relay-strict": build_root / "relay" / "strict_relay"}


def generate(config: Path, backend: str, out: Path) -> Path:
    """``ybgc CONFIG --backend B -o OUT``; returns OUT."""
    out.mkdir(parents=True, exist_ok=True)
    r = run_cmd([YBGC, config, "--backend", backend, "-o", out], timeout=120)
    if r.returncode:
        raise BenchError(f"ybgc {config.name} --backend {backend} failed (exit {r.returncode}):\n"
                         f"{(r.stdout + r.stderr)[-3000:]}")
    return out


def build_generated_cpp(config: Path, out: Path, ros2: bool = False) -> Path:
    """Generate and build the C++ module of ``config``; returns the binary
    (``ros2``: it publishes to ROS 2, built against the venv's ROS 2 wheels)."""
    generate(config, "cpp", out / "src")
    cmake_build(out / "src", out / "build", options=(f"-DYBGC_ROS2_PYTHON_ENV={mw.VENV}",) if ros2 else ())
    exes = [p for p in (out / "build").iterdir() if p.is_file() and os.access(p, os.X_OK)]
    if len(exes) != 1:
        raise BenchError(f"expected one executable in {out / 'build'}, found {exes}")
    return exes[0]


def build_rcl_source(build_root: Path) -> Path:
    """bench/rcl (rcl_source and rcl_relay), against the venv's ROS 2 wheels (and YARP); returns
    rcl_source, beside which rcl_relay is."""
    cmake_build(BENCH / "rcl", build_root / "rcl", options=(f"-DYBGC_ROS2_PYTHON_ENV={mw.VENV}",))
    return build_root / "rcl" / "rcl_source"


def generated_python(config: Path, backend: str, out: Path) -> Path:
    """Generate the Python module (py) or node (ros2); returns the script."""
    generate(config, backend, out)
    scripts = sorted(out.glob("*.py"))
    if len(scripts) != 1:
        raise BenchError(f"expected one .py file in {out}, found {[p.name for p in scripts]}")
    return scripts[0]


# --------------------------------------------------------------------------
# processes


class LinePeer(mw.Proc):
    """A peer that takes one command a line on stdin and answers one line on
    stdout, starting with "@" (other lines are the middleware's own messages);
    "@connected" lines are noted on the side (``.connected``)."""

    def __init__(self, argv, env: dict, name: str):
        super().__init__(argv, env=env, name=name, pipe_stdout=True, pipe_stdin=True,
                         die_with_parent=True)
        self.answers: "queue.Queue[str]" = queue.Queue()
        self.connected = threading.Event()

    def start(self, timeout: float = 30.0) -> "LinePeer":
        super().start()
        threading.Thread(target=self._pump, daemon=True).start()
        first = self._next(timeout, "ready")
        if first != "ready":
            raise BenchError(f"{self.name}: expected 'ready', got {first!r}")
        return self

    def _pump(self) -> None:
        for raw in iter(self.popen.stdout.readline, b""):
            line = raw.decode(errors="replace").strip()
            if not line.startswith("@"):
                continue  # the middleware's own messages
            line = line[1:]
            if line == "connected":
                self.connected.set()
            elif line:
                self.answers.put(line)
        self.answers.put("")  # EOF

    def _next(self, timeout: float, what: str) -> str:
        try:
            line = self.answers.get(timeout=timeout)
        except queue.Empty:
            raise BenchError(f"{self.name}: no answer to {what!r} in {timeout} s; log:\n"
                             f"{self.log_text()[-2000:]}") from None
        if line == "":
            raise BenchError(f"{self.name} exited (status {self.popen.poll()}) during {what!r}; "
                             f"log:\n{self.log_text()[-2000:]}")
        return line

    def ask(self, cmd: str, timeout: float = 30.0) -> str:
        if not self.alive:
            raise BenchError(f"{self.name} is not running (exit status {self.returncode}); log:\n"
                             f"{self.log_text()[-2000:]}")
        self.popen.stdin.write((cmd + "\n").encode())
        self.popen.stdin.flush()
        return self._next(timeout, cmd)

    def wait_connected(self, timeout: float = 20.0, proc: Optional[mw.Proc] = None) -> None:
        end = time.monotonic() + timeout
        while not self.connected.wait(0.1):
            if proc is not None and not proc.alive:
                raise BenchError(f"{proc.name} exited (status {proc.returncode}); log:\n"
                                 f"{proc.log_text()[-3000:]}")
            if not self.alive:
                raise BenchError(f"{self.name} exited; log:\n{self.log_text()[-2000:]}")
            if time.monotonic() > end:
                tail = f"\nlog of {proc.name}:\n{proc.log_text()[-3000:]}" if proc else ""
                raise BenchError(f"{self.name}: not connected after {timeout} s{tail}")

    def quit(self) -> None:
        if self.alive:
            try:
                self.popen.stdin.write(b"quit\n")
                self.popen.stdin.flush()
            except OSError:
                pass
            try:
                self.popen.wait(3)
            except subprocess.TimeoutExpired:
                pass
        self.stop()


class Source(LinePeer):
    """bench_producer or ros2_source.py: ``wait``, ``run``."""

    def wait_outputs(self, n: int, timeout: float = 20.0, proc: Optional[mw.Proc] = None) -> None:
        end = time.monotonic() + timeout
        while True:
            ans = self.ask(f"wait {n} 0.5", timeout=10)
            if ans.startswith("ok"):
                return
            if proc is not None and not proc.alive:
                raise BenchError(f"{proc.name} exited (status {proc.returncode}); log:\n"
                                 f"{proc.log_text()[-3000:]}")
            if time.monotonic() > end:
                tail = f"\nlog of {proc.name}:\n{proc.log_text()[-3000:]}" if proc else ""
                raise BenchError(f"{self.name}: {ans} output connections after {timeout} s, "
                                 f"wanted {n}{tail}")

    def run(self, count: int, rate: float) -> dict:
        ans = self.ask(f"run {count} {rate}", timeout=count / rate * 3 + 30)
        parts = ans.split()
        if parts[0] != "done":
            raise BenchError(f"{self.name}: run answered {ans!r}")
        return {"first": int(parts[1]), "ticks": int(parts[2]), "late": int(parts[3]),
                "elapsed": float(parts[4])}


class Sink(LinePeer):
    """bench_consumer or ros2_sink.py: ``count``, ``reset``, ``dump``."""

    def count(self) -> tuple:
        parts = self.ask("count").split()
        return int(parts[1]), int(parts[2])

    def reset(self) -> None:
        self.ask("reset")

    def dump(self, path: Path) -> list:
        ans = self.ask(f"dump {path}", timeout=60)
        if not ans.startswith("dumped"):
            raise BenchError(f"{self.name}: dump answered {ans!r}")
        data = array.array("d")
        with open(path, "rb") as f:
            data.frombytes(f.read())
        return [data[i:i + REC_FIELDS] for i in range(0, len(data), REC_FIELDS)]

    def settle(self, expected: int, quiet: float = 0.3, limit: float = 5.0) -> int:
        """Wait until ``expected`` records arrived, or none for ``quiet`` s."""
        end = time.monotonic() + limit
        last, since = -1, time.monotonic()
        while time.monotonic() < end:
            n, _ = self.count()
            if n >= expected:
                return n
            if n != last:
                last, since = n, time.monotonic()
            elif time.monotonic() - since > quiet:
                return n
            time.sleep(0.03)
        return last


# --------------------------------------------------------------------------
# process figures from /proc


def cpu_seconds(pid: int) -> Optional[float]:
    """User + system CPU time of a process (all its threads), seconds."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            rest = f.read().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(rest[11]) + int(rest[12])) / CLK_TCK


def memory_kb(pid: int) -> dict:
    """VmRSS and VmHWM (peak RSS) of a process, kB."""
    out = {}
    try:
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith(("VmRSS:", "VmHWM:")):
                    out[line.split(":")[0]] = int(line.split()[1])
    except OSError:
        pass
    return out


def mapped_rss_kb(pid: int, prefixes: tuple) -> dict:
    """The RSS (kB) of the file mappings of a process whose file name starts
    with each of ``prefixes`` (/proc/<pid>/smaps), and "total": what the
    process's pages of one library cost it."""
    out = {p: 0 for p in prefixes}
    out["total"] = 0
    name = None
    try:
        with open(f"/proc/{pid}/smaps") as f:
            for line in f:
                head = line.split(None, 6)
                if len(head) >= 5 and "-" in head[0] and ":" not in head[0]:
                    name = head[5].strip().rsplit("/", 1)[-1] if len(head) > 5 else ""
                elif line.startswith("Rss:"):
                    kb = int(line.split()[1])
                    out["total"] += kb
                    for p in prefixes:
                        if name and name.startswith(p):
                            out[p] += kb
    except OSError:
        return {}
    return out


class CpuWindow:
    """CPU % of a process over a window (100 % = one core)."""

    def __init__(self, pid: Optional[int]):
        self.pid = pid
        self.c0 = cpu_seconds(pid) if pid else None
        self.t0 = time.monotonic()

    def percent(self) -> Optional[float]:
        if not self.pid or self.c0 is None:
            return None
        c1 = cpu_seconds(self.pid)
        if c1 is None:
            return None
        return 100.0 * (c1 - self.c0) / max(1e-9, time.monotonic() - self.t0)


# --------------------------------------------------------------------------
# figures


def quantile(sorted_values: list, q: float) -> float:
    """Nearest-rank quantile (q in [0, 1]) of sorted values."""
    if not sorted_values:
        return float("nan")
    k = max(0, min(len(sorted_values) - 1, math.ceil(q * len(sorted_values)) - 1))
    return sorted_values[k]


def cdf_points(sorted_values: list, n: int = 1001) -> list:
    """n quantiles (0 .. 1) of the latencies in us, for the CDF plot."""
    if not sorted_values:
        return []
    return [round(quantile(sorted_values, i / (n - 1)) * 1e6, 2) for i in range(n)]


def analyse_latency(records: list, first: int, ticks: int, blocks: int, per_block: bool) -> dict:
    """Figures of one event-driven run (see merge_latency for the summary).
    ``per_block``: each record carries one block (direct subject: the
    consumer reads the producer's ports); otherwise each record is one bridge
    output of ``blocks`` blocks, all of the same tick (a record mixing ticks
    is counted as mismatched)."""
    last = first + ticks - 1
    lat, recv, seen = [], [], set()
    mismatched = bad = foreign = late = 0
    for r in records:
        n = int(r[1])
        bad += int(r[2])
        stored = min(n, 4)
        seqs = [int(r[3 + 2 * k]) for k in range(stored)]
        times = [r[4 + 2 * k] for k in range(stored)]
        if not seqs or max(seqs) > last:
            foreign += 1
            continue
        if min(seqs) < first:
            late += 1  # (partly) an earlier run's tick, the warm-up's, delivered after this run began
            continue
        if not per_block:  # one output of every port's block, all of one tick
            if n != blocks or len(set(seqs)) != 1:
                mismatched += 1
            if seqs[0] in seen:
                continue  # the same data published again
            seen.add(seqs[0])
        lat.append(r[0] - max(times))
        recv.append(r[0])
    expected = ticks * (blocks if per_block else 1)
    span = (max(recv) - min(recv)) if len(recv) > 1 else 0.0
    return {"sent": expected, "delivered": len(lat), "mismatched": mismatched, "bad": bad,
            "foreign": foreign, "late": late, "lat": lat, "span": span,
            "outputs": (len(recv) - 1) / (blocks if per_block else 1) if len(recv) > 1 else 0}


def merge_latency(chunks: list) -> dict:
    """The summary of several runs of one subject on one workload."""
    lat = sorted(x for c in chunks for x in c["lat"])
    sent = sum(c["sent"] for c in chunks)
    delivered = sum(c["delivered"] for c in chunks)
    span = sum(c["span"] for c in chunks)
    return {
        "runs": len(chunks),
        "sent": sent,
        "delivered": delivered,
        "lost": max(0, sent - delivered),
        "mismatched": sum(c["mismatched"] for c in chunks),
        "bad": sum(c["bad"] for c in chunks),
        "foreign": sum(c["foreign"] for c in chunks),
        "late": sum(c.get("late", 0) for c in chunks),
        "median_us": quantile(lat, 0.5) * 1e6 if lat else None,
        "p99_us": quantile(lat, 0.99) * 1e6 if lat else None,
        "max_us": lat[-1] * 1e6 if lat else None,
        "mean_us": sum(lat) / len(lat) * 1e6 if lat else None,
        # output messages per second while running (direct: ticks per second)
        "rate_hz": sum(c["outputs"] for c in chunks) / span if span > 0 else None,
        "run_medians_us": [quantile(sorted(c["lat"]), 0.5) * 1e6 if c["lat"] else None
                           for c in chunks],
        "cdf_us": cdf_points(lat),
    }


def analyse_rate(records: list, t_start: float, t_end: float, rate: float) -> dict:
    """Figures of one fixed-rate run: the output rate measured on receive
    times inside [t_start, t_end] (well inside the producer's run)."""
    recv = sorted(r[0] for r in records if t_start <= r[0] <= t_end)
    out = {"configured_hz": rate, "window_s": t_end - t_start, "messages": len(recv)}
    if len(recv) < 3:
        out.update(achieved_hz=None, error_pct=None)
        return out
    achieved = (len(recv) - 1) / (recv[-1] - recv[0])
    period = 1.0 / rate
    gaps = [b - a for a, b in zip(recv, recv[1:])]
    jitter = sorted(abs(g - period) for g in gaps)
    # drift: rate of the first and the last third of the window
    third = len(recv) // 3
    first_rate = (third - 1) / (recv[third - 1] - recv[0]) if third > 2 else None
    last_rate = (third - 1) / (recv[-1] - recv[-third]) if third > 2 else None
    out.update(
        achieved_hz=achieved,
        error_pct=100.0 * (achieved - rate) / rate,
        gaps=sum(int(round(g / period)) - 1 for g in gaps if g > 1.5 * period),
        jitter_p99_us=quantile(jitter, 0.99) * 1e6,
        jitter_max_us=jitter[-1] * 1e6,
        first_third_hz=first_rate,
        last_third_hz=last_rate,
    )
    ages = sorted(r[0] - max(r[4 + 2 * k] for k in range(min(4, max(1, int(r[1])))))
                  for r in records if t_start <= r[0] <= t_end and int(r[1]) > 0)
    out["age_median_us"] = quantile(ages, 0.5) * 1e6 if ages else None
    return out
