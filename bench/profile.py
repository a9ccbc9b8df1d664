"""Profile one subject of the benchmark while it works (the findings in
bench/findings.md come from this).

    .venv/bin/python bench/profile.py py   [--shape joints] [--rate 1000] [--seconds 5]
    .venv/bin/python bench/profile.py cpp  ...      (perf, cpu-clock, call graphs)
    .venv/bin/python bench/profile.py relay-strict ...   (the floor, perf likewise)
    .venv/bin/python bench/profile.py ros2 ...
    .venv/bin/python bench/profile.py py --perf ...   (a Python module under perf: every thread,
                                          the kernel and the bindings' C++ with the interpreter)
    .venv/bin/python bench/profile.py cpp --callgrind [--rate 100] [--seconds 3]
                                          (C++: the instructions a tick costs, counted)

Wires the subject as bench/run.py does (own yarpserver, C++ producer and
consumer, event-driven unless --fixed), drives it at --rate and samples the
module process: py-spy (Python: py, ros2; the thread holding the GIL, so waiting is left out) or perf
(C++: cpp, relay, relay-strict). Prints the functions with the most samples, self and
inclusive, and writes the raw profile next to the build (bench/build/profile/).

With --callgrind (C++ subjects, cpp-ros2 and rcl-relay too) the module runs
under valgrind's callgrind, counting from the end of the warm-up: the
instructions of its own threads per tick (user space only: the kernel's
share, two thirds of a C++ module's CPU, is not in them), the same on a
busy machine as on a quiet one, which is how the C++ module and its floors
compare (bench/findings.md, "What a message costs"); valgrind runs it some
50 times slower, so the rate is low.
"""
from __future__ import annotations

import argparse
import collections
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import blocks as h  # noqa: E402
import run as bench  # noqa: E402
from blocks import mw  # noqa: E402


def top_collapsed(path: Path, n: int) -> str:
    """Self and inclusive sample counts per frame from collapsed stacks
    ("a;b;c count" lines, as py-spy --format raw and perf script | collapse give)."""
    self_c, incl = collections.Counter(), collections.Counter()
    total = 0
    for line in path.read_text().splitlines():
        stack, _, cnt = line.rpartition(" ")
        if not stack or not cnt.isdigit():
            continue
        c = int(cnt)
        total += c
        frames = stack.split(";")
        self_c[frames[-1]] += c
        for f in set(frames):
            incl[f] += c
    out = [f"{total} samples"]
    out.append("self:")
    out += [f"  {100 * c / total:5.1f} %  {f}" for f, c in self_c.most_common(n)]
    out.append("inclusive:")
    out += [f"  {100 * c / total:5.1f} %  {f}" for f, c in incl.most_common(n)]
    return "\n".join(out)


def collapse_perf(script_text: str) -> str:
    """`perf script` output (call graphs) to collapsed stacks."""
    stacks = collections.Counter()
    frames: list = []
    for line in script_text.splitlines() + [""]:
        if not line.strip():
            if frames:
                stacks[";".join(reversed(frames))] += 1
            frames = []
            continue
        if line[0] not in " \t":
            frames = []  # header line of a sample
            continue
        parts = line.strip().split(None, 1)
        if len(parts) == 2:
            sym = parts[1].rsplit(" (", 1)[0]
            frames.append(sym.split("+0x")[0])
    return "\n".join(f"{k} {v}" for k, v in stacks.items())


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("subject", choices=["relay", "relay-strict", "cpp", "py", "ros2", "cpp-ros2", "rcl-relay"])
    ap.add_argument("--shape", choices=list(bench.SHAPES), default="joints")
    ap.add_argument("--rate", type=int, default=1000)
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--fixed", action="store_true", help="run the module at --rate (fixed rate)")
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--perf", action="store_true",
                    help="a Python module: perf (every thread, kernel and the bindings' C++ too) instead of py-spy")
    ap.add_argument("--callgrind", action="store_true",
                    help="C++: count the instructions per tick under callgrind (use a low --rate)")
    ap.add_argument("--variant", type=Path, metavar="EXE",
                    help="with --callgrind: run this build of the subject instead (another commit's, "
                         "a changed copy), wired as the subject is")
    args = ap.parse_args()
    if args.callgrind:
        return callgrind(args)
    out_dir = bench.BENCH / "build" / "profile"
    out_dir.mkdir(parents=True, exist_ok=True)
    built = bench.prepare(bench.BENCH / "build",
                          () if args.subject in bench.FLOORS else (args.subject,), [args.shape])
    info = built["subjects"].get(args.subject, {"ok": True})
    if not info.get("ok", True):
        print(info["error"])
        return 1
    with mw.YarpServer() as server, mw.Ros2Domain() as dom:
        env = dict(dom.env)
        env.update(server.env)
        env.update(dom.ros_env)
        ctx = {"tools": built["tools"], "subjects": built["subjects"], "yarp_env": server.env,
               "ros2_env": env, "ros2_vars": dom.ros_env}
        rig = bench.Rig(ctx, args.subject, bench.SHAPES[args.shape],
                        args.rate if args.fixed else None).start()
        try:
            rig.source.run(200, args.rate)
            ticks = int((args.seconds + 2) * args.rate)
            result = {}
            driver = threading.Thread(target=lambda: result.update(rig.source.run(ticks, args.rate)))
            driver.start()
            time.sleep(1.0)
            pid = rig.module.pid
            stem = out_dir / f"{args.subject}_{args.shape}_{args.rate}"
            if args.subject in ("py", "ros2") and not args.perf:
                spy = shutil.which("py-spy") or str(mw.VENV / "bin" / "py-spy")
                raw = stem.with_suffix(".pyspy.txt")
                subprocess.run([spy, "record", "--pid", str(pid), "--duration", str(int(args.seconds)),
                                "--rate", "500", "--threads", "--gil", "--format", "raw", "-o", str(raw),
                                "--nonblocking"], check=True, capture_output=True)
                collapsed = raw
            else:
                data = stem.with_suffix(".perf.data")
                subprocess.run(["perf", "record", "-e", "cpu-clock", "-F", "2000", "-g", "-p", str(pid),
                                "-o", str(data), "--", "sleep", str(args.seconds)],
                               check=True, capture_output=True)
                script = subprocess.run(["perf", "script", "-i", str(data)], capture_output=True,
                                        text=True, check=True).stdout
                collapsed = stem.with_suffix(".perf.txt")
                collapsed.write_text(collapse_perf(script))
            driver.join()
            cpu = h.cpu_seconds(pid)
            print(f"{args.subject} {args.shape} {args.rate} Hz: profile in {collapsed}")
            print(top_collapsed(collapsed, args.top))
            print(f"module CPU time so far: {cpu:.2f} s")
        finally:
            rig.stop()
    return 0


def callgrind(args) -> int:
    """The subject under callgrind, its instructions counted over the ticks
    after the warm-up: the total per tick and the functions that cost most,
    inclusive."""
    if args.subject in ("py", "ros2"):
        print("--callgrind counts a C++ module's instructions; a Python module: without it (py-spy)")
        return 2
    out_dir = bench.BENCH / "build" / "profile"
    out_dir.mkdir(parents=True, exist_ok=True)
    built = bench.prepare(bench.BENCH / "build", () if args.subject in bench.FLOORS
                          else (args.subject,), [args.shape])
    info = built["subjects"].get(args.subject, {"ok": True})
    if not info.get("ok", True):
        print(info["error"])
        return 1
    stem = out_dir / f"{args.subject}_{args.shape}_{args.rate}.callgrind"
    for old in out_dir.glob(stem.name + ".*"):
        old.unlink()
    wrap = ["valgrind", "--tool=callgrind", "--instr-atstart=no", "--dump-instr=no",
            f"--callgrind-out-file={stem}.%p"]
    ctx0 = {"tools": built["tools"], "subjects": built["subjects"], "ros2_ok": True}
    subject = args.subject
    if args.variant is not None:
        subject = args.subject + "+variant"
        ctx0["subjects"][subject] = {"ok": True, "error": None, args.shape: args.variant.resolve()}
    iso = bench.Isolated(ctx0, subject)
    rig = None
    try:
        ctx = iso.start()
        rig = bench.Rig(ctx, subject, bench.SHAPES[args.shape], args.rate if args.fixed else None,
                        wrap=wrap).start()
        rig.source.run(max(20, args.rate), args.rate)
        pid = rig.module.pid
        subprocess.run(["callgrind_control", "-i", "on", str(pid)], check=True, capture_output=True)
        run = rig.source.run(int(args.seconds * args.rate), args.rate)
        rig.sink.settle(run["ticks"])
        subprocess.run(["callgrind_control", "-d", str(pid)], check=True, capture_output=True)
    finally:
        if rig is not None:
            rig.stop()
        iso.stop()
    dumps = sorted(out_dir.glob(stem.name + ".*.1"))
    if not dumps:
        print(f"no callgrind dump in {out_dir}")
        return 1
    text = subprocess.run(["callgrind_annotate", "--inclusive=yes", str(dumps[-1])], capture_output=True,
                          text=True, check=True).stdout
    total = next(int(line.split()[0].replace(",", "")) for line in text.splitlines()
                 if line.strip().endswith("PROGRAM TOTALS"))
    print(f"{subject} {args.shape} {args.rate} Hz under callgrind: {run['ticks']} ticks, "
          f"{total / run['ticks']:,.0f} instructions a tick ({dumps[-1]})")
    rows = [line for line in text.splitlines() if "%)" in line and "PROGRAM TOTALS" not in line]
    for line in rows[:args.top]:
        count, rest = line.split("(", 1)
        name = rest.split(")", 1)[1].strip().split(" [")[0].replace("???:", "")
        print(f"  {int(count.replace(',', '')) / run['ticks']:10,.0f}  {name[:110]}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
