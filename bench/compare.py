"""The working tree's modules against other builds of them, in the same
interleaved rounds (the figures bench/findings.md compares: on a shared
machine, only ratios measured in one run mean anything).

    .venv/bin/python bench/compare.py --variant py+before=/tmp/before/bench_joints.py \\
        --variant cpp+before=/tmp/before_cpp/build/bench_joints \\
        --subjects relay-strict,cpp,cpp+before,py,py+before [--rate 1000] [--seconds 6] [--rounds 6]

A variant is a subject's module of another commit or a changed copy (a py
module or ros2 node's script, a C++ module's executable), named SUBJECT+NAME
and wired as SUBJECT is (bench/run.py's rigs: its own yarpserver, the C++
producer and consumer, event-driven). Generate one from another commit with
that commit's ybgc, e.g. `git archive COMMIT | tar -x -C /tmp/src` and, from
another folder than the repository's (whose ybg would be imported first),
`PYTHONPATH=/tmp/src python -m ybg.cli bench/configs/joints_2x15.ini --backend py -o DIR`.
Prints each subject's median latency, its rounds' medians and its CPU.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import run as bench  # noqa: E402
from report import loadavg  # noqa: E402


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--subjects", required=True, help="comma-separated, variants among them")
    ap.add_argument("--variant", action="append", default=[], metavar="SUBJECT+NAME=PATH")
    ap.add_argument("--shape", choices=list(bench.SHAPES), default="joints")
    ap.add_argument("--rate", type=int, default=1000)
    ap.add_argument("--seconds", type=float, default=6.0, help="per subject, over all rounds")
    ap.add_argument("--rounds", type=int, default=6)
    args = ap.parse_args()
    variants = dict(v.split("=", 1) for v in args.variant)
    subjects = tuple(s.strip() for s in args.subjects.split(",") if s.strip())
    unknown = [s for s in subjects if s not in bench.SUBJECTS and s not in variants]
    if unknown or any(v.split("+")[0] not in bench.SUBJECTS for v in variants):
        ap.error(f"unknown subjects: {', '.join(unknown) or ', '.join(variants)}")
    built = bench.prepare(bench.BENCH / "build", tuple(s for s in subjects if s in bench.GENERATED),
                          [args.shape])
    ctx = {"tools": built["tools"], "subjects": built["subjects"], "ros2_ok": True}
    for name, path in variants.items():
        ctx["subjects"][name] = {"ok": True, "error": None, args.shape: Path(path).resolve()}
    workload = f"{args.shape}_{args.rate}hz"
    mode = bench.Mode("compare", [(workload, args.shape, args.rate, args.seconds)], [], 0.0, subjects, 200,
                      args.rounds)
    before = loadavg()
    results = {e["subject"]: e for e in bench.latency_stage(ctx, mode, bench.Progress(len(subjects)))}
    print(f"load average before {before}, after {loadavg()}")
    for s in subjects:
        e = results.get(s, {})
        if "error" in e or e.get("median_us") is None:
            print(f"{s:18s} {e.get('error', 'no data')}")
            continue
        rounds = ", ".join(f"{x:.0f}" for x in e.get("run_medians_us") or [] if x is not None)
        print(f"{s:18s} median {e['median_us']:7.0f} us (rounds {rounds})  CPU {e.get('cpu_pct') or 0:5.1f} %  "
              f"delivered {e['delivered']}/{e['sent']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
