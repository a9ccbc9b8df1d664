"""What one message costs each backend's module, counted in units that do
not depend on how loaded the machine is: the cost guard (tests/test_cost.py)
and its budgets (tests/cost_budget.json).

The workload is the benchmark's (bench/configs/joints_2x15.ini, and
joints_2x15_ros2.ini for the modules that publish to ROS 2: the native
module through rcl, the rclpy node): a tick is one Bottle of 15 float64 on
each of two ports, one envelope stamp for both, and the module's one message
of it. A driver (tests/peers/cost_driver.py) writes a tick only once the
message of the one before has reached its reader, so that each tick is
handled alone: what a module does for it is then the same on a quiet and on
a busy machine, and counted over a few hundred ticks, with no timing.
For a module of commands (examples/home_arm_trigger.ini, the services
benchmark's), a tick is one call of its ROS 2 service, made once the one
before was answered (tests/peers/service_client.py), answered by a YARP RPC
server (tests/peers/rpc_server.py).

Units, per tick:
    threads woken     the module's threads that had to wake for it (their
                      voluntary switches, /proc/PID/task/*/status, read
                      after each tick): a thread hand-over added to the
                      message path is one more, however the machine's timing
                      makes the others wait
    voluntary switches  the times a thread of the module gave up the CPU to
                      wait, in all: the interpreter lock and mutexes that
                      another thread held add some, by the machine's timing
                      (its budget is loose)
    python calls      the Python calls on the module's message path (every
                      Python function and every C function called from
                      Python), counted by the runtime itself when the
                      environment asks it at start (core.COUNT_CALLS), in a
                      run of its own (the profile hook slows the module)
    yarp calls        of those, the calls into YARP's bindings: each lets the
                      interpreter lock go, and another thread may take it
    system calls      of the C++ module (strace -c -f on it, for a second
                      run of the ticks: traced threads switch at every call)
    allocations       of the C++ module: malloc, calloc, realloc, aligned
                      (a preloaded counter, harness/count_allocations.c)

    SUBJECTS            {name: Subject}: the modules measured and their units
    load_budgets(), BUDGET_FILE
    Measured(subject, ticks, counts)     .per_tick, .text(), .cpu_us (reported, never compared)
    measure(subject, workdir, ticks=..., ros2_env=None, launch=None) -> Measured
    problems(measured, budgets) -> [text]: a unit over its budget, or (for the
                        units counted exactly) well under it: the budget then
                        says less than it could, and is lowered on purpose
"""
from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Optional

from harness.build import build_cpp, cmake_build, ros2_wheels_option
from harness.env import ROOT, VENV_PYTHON, active_yarp, fail
from harness.generated import ybgc
from harness.procs import Peer, Proc, wait_until
from harness.yarp import YarpServer

BUDGET_FILE = ROOT / "tests" / "cost_budget.json"
SHIM_SOURCE = Path(__file__).with_name("count_allocations.c")

#: ticks before the count (connections settle, first messages said) and counted
WARM_TICKS = 30
TICKS = 300

#: the units counted exactly: the same code gives the same count, so a count
#: well under the budget means the budget no longer guards (it is lowered)
EXACT = ("python calls", "yarp calls", "allocations")
#: how far under the budget an exact count may be before the budget is stale
SLACK = 0.15


@dataclass(frozen=True)
class Subject:
    """A module of the workload: its backend, config, the ports and topic the
    driver uses, and the units counted."""
    name: str
    backend: str
    config: str                    # relative to the repository
    units: tuple
    output: Optional[str] = None   # the YARP port it writes
    topic: Optional[str] = None    # the ROS 2 topic it publishes
    service: Optional[str] = None  # the ROS 2 service it serves (a module of commands)
    rpc: Optional[str] = None      # the YARP RPC port its service calls
    sources: tuple = ("/bench/src0:o", "/bench/src1:o")
    width: int = 15


#: the C++ module's units
NATIVE = ("threads woken", "voluntary switches", "system calls", "allocations")

SUBJECTS = {
    "cpp": Subject("cpp", "cpp", "bench/configs/joints_2x15.ini", NATIVE, output="/bench_joints/out:o"),
    "cpp-ros2": Subject("cpp-ros2", "cpp", "bench/configs/joints_2x15_ros2.ini", NATIVE,
                        topic="/bench/joint_states"),
    "py": Subject("py", "py", "bench/configs/joints_2x15.ini",
                  ("threads woken", "voluntary switches", "python calls", "yarp calls"), output="/bench_joints/out:o"),
    "ros2": Subject("ros2", "ros2", "bench/configs/joints_2x15_ros2.ini",
                    ("threads woken", "voluntary switches", "python calls", "yarp calls"), topic="/bench/joint_states"),
    # a call of a ROS 2 service, answered by a YARP RPC port: its hand-overs
    "cpp-commands": Subject("cpp-commands", "cpp", "examples/home_arm_trigger.ini",
                            ("threads woken", "voluntary switches"), service="/icub/left_arm/home",
                            rpc="/icub/left_arm/homing/rpc:i"),
}


def load_budgets() -> dict:
    """{subject: {unit: {"budget": per tick, "measured": per tick when set}}}."""
    return json.loads(BUDGET_FILE.read_text(encoding="utf-8"))["budgets"]


@dataclass
class Measured:
    subject: Subject
    ticks: int
    counts: dict = field(default_factory=dict)  # unit -> count over the ticks
    cpu_us: float = 0.0  # the module's CPU time per tick (for the reader; never compared)

    @property
    def per_tick(self) -> dict:
        return {unit: n / self.ticks for unit, n in self.counts.items()}

    def text(self) -> str:
        return ", ".join(f"{u} {v:.1f}" for u, v in self.per_tick.items()) + f" (CPU {self.cpu_us:.0f} us)"


def problems(measured: Measured, budgets: dict) -> list[str]:
    """What is wrong with the counts against the subject's budgets: a unit
    over its budget (the count before, the budget's measure, and now), an
    exact unit far under it (the budget is to be lowered), a unit without
    a budget."""
    out = []
    mine = budgets.get(measured.subject.name, {})
    for unit, now in measured.per_tick.items():
        if unit not in mine:
            out.append(f"{measured.subject.name}: {unit}: {now:.1f} per tick, and no budget in {BUDGET_FILE.name}")
            continue
        budget, before = mine[unit]["budget"], mine[unit]["measured"]
        if now > budget:
            out.append(f"{measured.subject.name}: {unit} per tick: {now:.1f}, over the budget of {budget} "
                       f"(measured {before} when it was set): the message path costs more than it did; "
                       f"if that is meant, say why and raise the budget in {BUDGET_FILE.name}")
        elif unit in EXACT and now < before * (1 - SLACK):
            out.append(f"{measured.subject.name}: {unit} per tick: {now:.1f}, far under the {before} measured "
                       f"when the budget ({budget}) was set: lower it in {BUDGET_FILE.name}, so that it "
                       f"still guards")
    return out


# --------------------------------------------------------------------------
# counting


def switches(pid: int) -> dict[str, int]:
    """{thread: its voluntary context switches so far}, of every thread of ``pid``."""
    out = {}
    for status in Path(f"/proc/{pid}/task").glob("*/status"):
        try:
            text = status.read_text()
        except OSError:  # a thread that ended meanwhile
            continue
        m = re.search(r"^voluntary_ctxt_switches:\s+(\d+)", text, re.M)
        out[status.parent.name] = int(m.group(1)) if m else 0
    return out


def cpu_ns(pid: int) -> int:
    """The CPU time of every thread of ``pid`` so far, in nanoseconds
    (/proc/PID/task/*/schedstat): reported beside the counts, never
    compared (it depends on the machine and its load)."""
    total = 0
    for stat in Path(f"/proc/{pid}/task").glob("*/schedstat"):
        try:
            total += int(stat.read_text().split()[0])
        except (OSError, ValueError, IndexError):
            continue
    return total


def read_counter(path: Path, fields: int) -> list[int]:
    """The int64 counters in a file a module keeps (little-endian)."""
    data = path.read_bytes() if path.exists() else b""
    if len(data) < 8 * fields:
        return [0] * fields
    return [int.from_bytes(data[8 * k:8 * k + 8], "little") for k in range(fields)]


class Strace:
    """``strace -c -f`` attached to a running process (every thread) until
    stopped: its count of system calls."""

    def __init__(self, pid: int, out: Path):
        exe = shutil.which("strace")
        if exe is None:
            fail("strace is not installed (the cost guard counts the C++ module's system calls with it): "
                 "scripts/setup.sh installs it (apt-get install strace)")
        self.out = out
        self.err = out.with_suffix(".err")
        self.proc = subprocess.Popen([exe, "-c", "-f", "-p", str(pid), "-o", str(out)],
                                     stderr=open(self.err, "wb"))
        # attached once it says so ("Process N attached with M threads")
        wait_until(lambda: "attached" in self.err.read_text(errors="replace") or self.proc.poll() is not None,
                   timeout=30, what="strace attached to the module")
        if self.proc.poll() is not None:
            fail(f"strace cannot attach to the module: {self.err.read_text(errors='replace')[-1000:]}")

    def stop(self) -> int:
        self.proc.send_signal(signal.SIGINT)
        self.proc.wait(timeout=30)
        text = self.out.read_text(errors="replace")
        m = re.search(r"^-+.*\n\s*[\d.]+\s+[\d.]+\s+\d+\s+(\d+)(?:\s+\d+)?\s+total\s*$", text, re.M)
        assert m, text
        return int(m.group(1))


def shim(folder: Path) -> Path:
    """The allocation counter (harness/count_allocations.c), built once in ``folder``."""
    lib = folder / "libcount_allocations.so"
    if not lib.exists():
        cc = shutil.which("cc") or shutil.which("gcc")
        assert cc, "no C compiler to build the allocation counter"
        r = subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(lib), str(SHIM_SOURCE)],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr
    return lib


# --------------------------------------------------------------------------
# the module and the driver


class Driver(Peer):
    script = "cost_driver.py"

    def run(self, ticks: int) -> dict:
        since = len(self.events)
        self.send(cmd="run", ticks=ticks)
        return self.wait_event("ran", since=since, timeout=60 + ticks * 0.1)


def module_argv(subject: Subject, workdir: Path) -> list:
    """The command that starts the subject's module, generated (and, for
    cpp, built) from its config into ``workdir``."""
    out = workdir / f"{subject.name}_module"
    if not out.exists():
        r = ybgc(ROOT / subject.config, "--backend", subject.backend, "-o", out)
        assert r.returncode == 0, r.stdout + r.stderr
    if subject.backend == "cpp" and (subject.topic or subject.service):
        # through rcl: built against the ROS 2 wheels of the venv
        r = cmake_build(out, out / "build", active_yarp(), options=(ros2_wheels_option(),))
        assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
        return [_executable(out / "build")]
    if subject.backend == "cpp":
        return [build_cpp(out, active_yarp())]
    (script,) = [p for p in out.glob("*.py")]
    return [VENV_PYTHON, script]


def _executable(build: Path) -> Path:
    (exe,) = [p for p in build.iterdir() if p.is_file() and os.access(p, os.X_OK)]
    return exe


def measure(subject: Subject, workdir: Path, ticks: int = TICKS, ros2_env: Optional[dict] = None,
            launch: Optional[Callable[[list], list]] = None) -> Measured:
    """The subject's module driven for ``ticks`` ticks after a warm-up, its
    units counted over them. ``ros2_env``: the ROS 2 domain's variables (a
    subject that publishes to ROS 2); ``launch``: changes the command that
    starts the module (a variant of it).

    The module runs as it always does for the switches (and CPU time),
    then, for the C++ module, for a second time the same ticks under strace
    (a thread stopped at each of its system calls switches more); a Python
    module runs a second time, counting its calls (the profile hook slows
    it, and a slower module's threads overlap more)."""
    workdir.mkdir(parents=True, exist_ok=True)
    argv = module_argv(subject, workdir)
    if launch is not None:
        argv = launch(argv)
    measured = Measured(subject, ticks)
    if subject.service:
        _run_commands(subject, argv, ticks, ros2_env, measured)
        return measured
    _run(subject, argv, workdir, ticks, ros2_env, measured, count_calls=False)
    if "python calls" in subject.units:
        _run(subject, argv, workdir, ticks, ros2_env, measured, count_calls=True)
    measured.counts = {unit: measured.counts[unit] for unit in subject.units}
    return measured


def count_switches(pid: int, ticks: int, tick: Callable[[], None]) -> tuple[int, int]:
    """The threads of ``pid`` woken and their voluntary switches over
    ``ticks`` calls of ``tick`` (which returns once the module has handled
    it). A tick at a time, the threads' switches read after each: a thread
    that had to wake for the tick switched at least once in it, however
    many more times it waited (for the interpreter lock, a mutex another
    thread held: the machine's timing)."""
    before = switches(pid)
    woken = switched = 0
    for _ in range(ticks):
        tick()
        after = switches(pid)
        delta = [n - before.get(t, 0) for t, n in after.items()]
        woken += sum(1 for d in delta if d > 0)
        switched += sum(d for d in delta if d > 0)
        before = after
    return woken, switched


def _run_commands(subject: Subject, argv: list, ticks: int, ros2_env: Optional[dict], measured: Measured) -> None:
    """A module of commands: ``ticks`` calls of its service, one after another."""
    from harness.services import RpcServer, ServiceClient

    with YarpServer() as server:
        env = dict(server.env, **(ros2_env or {}))
        with RpcServer(env, subject.rpc, [{"match": "", "reply": ["ok"]}]) as rpc, \
                Proc(argv, env=env, name=f"cost_{subject.name}") as module, \
                ServiceClient(env, {subject.service: "std_srvs/srv/Trigger"}, name="cost_client") as client:
            client.wait_service(subject.service, timeout=60)

            def call():
                r = client.call(subject.service, timeout=30)
                assert r.response is not None and r.response["success"], \
                    f"a call was not answered: {r}; log:\n{module.log_text()[-3000:]}"
            for _ in range(WARM_TICKS):
                call()
            pid = module.pid
            cpu0 = cpu_ns(pid)
            woken, switched = count_switches(pid, ticks, call)
            measured.cpu_us = (cpu_ns(pid) - cpu0) / 1000 / ticks
            measured.counts = {"threads woken": woken, "voluntary switches": switched}
            assert module.alive, module.log_text()[-3000:]
            assert len(rpc.commands) == WARM_TICKS + ticks


def _run(subject: Subject, argv: list, workdir: Path, ticks: int, ros2_env: Optional[dict],
         measured: Measured, count_calls: bool) -> None:
    """One run of the module: its counts added to ``measured``."""
    calls = workdir / f"{subject.name}.calls"
    allocations = workdir / f"{subject.name}.allocations"
    for path in (calls, allocations):
        path.unlink(missing_ok=True)
    with YarpServer() as server:
        env = dict(server.env)
        if ros2_env:
            env.update(ros2_env)
        module_env = dict(env)
        if count_calls:
            module_env["YBGC_COUNT_CALLS"] = str(calls)
        elif "allocations" in subject.units:
            module_env["LD_PRELOAD"] = str(shim(workdir))
            module_env["YBGC_ALLOC_COUNTS"] = str(allocations)
        config = {"sources": list(subject.sources), "width": subject.width, "output": subject.output,
                  "topic": subject.topic, "reader": "/cost/reader:i"}
        with Proc(argv, env=module_env, name=f"cost_{subject.name}") as module, \
                Driver(env, config, name=f"cost_driver_{subject.name}") as driver:
            driver.wait_event("connected", timeout=60)
            warm = driver.run(WARM_TICKS)
            assert warm["lost"] < WARM_TICKS, f"no message of the warm-up came out; log:\n{module.log_text()[-3000:]}"
            pid = module.pid
            calls0, cpu0, allocations0 = read_counter(calls, 3), cpu_ns(pid), read_counter(allocations, 1)

            def tick():
                ran = driver.run(1)
                assert ran["lost"] == 0, f"a tick gave no message; log:\n{module.log_text()[-3000:]}"
            woken, switched = count_switches(pid, ticks, tick)
            calls1, cpu1, allocations1 = read_counter(calls, 3), cpu_ns(pid), read_counter(allocations, 1)
            if count_calls:
                measured.counts["python calls"] = calls1[0] - calls0[0]
                measured.counts["yarp calls"] = calls1[1] - calls0[1]
            else:
                measured.counts["threads woken"] = woken
                measured.counts["voluntary switches"] = switched
                measured.counts["allocations"] = allocations1[0] - allocations0[0]
                measured.cpu_us = (cpu1 - cpu0) / 1000 / ticks
                if "system calls" in subject.units:
                    strace = Strace(pid, workdir / f"{subject.name}.strace")
                    try:
                        traced = driver.run(ticks)
                    finally:
                        measured.counts["system calls"] = strace.stop()
                    assert traced["lost"] == 0, f"{traced['lost']} of {ticks} traced ticks gave no message"
            assert module.alive, module.log_text()[-3000:]
