"""The figures of the network faults: for each backend's module and each
fault of tests/test_network.py (the same functions, on the same four-host
rig of network namespaces, YARP 4.0.0), the seconds to recover, the messages
unused or missed and the module's resident memory before and after.

    sudo .venv/bin/python bench/network_faults.py [--rounds N] [--backends cpp,py,ros2]
        about 2 minutes a round; writes bench/results/network_faults.json
        and prints the table of docs/network.md

The tests assert only what comes out (no hang, no traceback, the totals);
the times and memory here are measurements of one machine, never asserted.
Needs root, as the tests do.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import signal
import statistics
import sys
import tempfile
import traceback
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))
sys.path.insert(0, str(ROOT))

import test_network as net  # noqa: E402
from harness import netns  # noqa: E402  (tests/harness/)
from harness.build import Builds  # noqa: E402
from harness.env import yarp_install  # noqa: E402
from harness.procs import tmp_root  # noqa: E402
from harness.programs import relay_program  # noqa: E402
from harness.yarp import require_yarp  # noqa: E402

RESULTS = ROOT / "bench" / "results" / "network_faults.json"


def run(backends, rounds: int) -> dict:
    install = yarp_install(net.VERSION)
    require_yarp(install)
    work = Path(tempfile.mkdtemp(prefix="ybg-netbench-", dir=tmp_root()))
    builds = None
    if "cpp" in backends:
        builds = Builds(work / "cpp", install)
        builds.add("relay_bridge", relay_program(), optimize=True)
    out: dict = {}
    for r in range(rounds):
        for backend in backends:
            for fault, scenario in net.FAULTS.items():
                modules = net.launcher(backend, work / f"{backend}_{r}", builds)
                with netns.Rig(install) as rig:
                    rig.start_name_server()
                    try:
                        figures = scenario(rig, modules)
                    except Exception as e:  # a fault that misbehaves: said, the others go on
                        traceback.print_exc()
                        figures = {"error": f"{type(e).__name__}: {str(e)[:300]}"}
                out.setdefault(fault, {}).setdefault(backend, []).append(figures)
                print(f"round {r + 1} {backend:4} {fault}: {figures}", flush=True)
    return out


def summary(runs: list) -> dict:
    """The median of each figure over the rounds that did not fail."""
    ok = [f for f in runs if "error" not in f]
    if not ok:
        return {"error": runs[-1]["error"]}
    return {k: statistics.median(f[k] for f in ok) for k in ok[0]}


def table(results: dict) -> str:
    lines = ["| fault | backend | figures (median over the rounds) |", "|---|---|---|"]
    for fault, per_backend in results.items():
        for backend, runs in per_backend.items():
            s = summary(runs)
            text = ", ".join(f"{k} {v:.2f}" if isinstance(v, float) and not float(v).is_integer()
                             else f"{k} {int(v)}" if isinstance(v, (int, float)) else f"{k}: {v}"
                             for k, v in s.items())
            lines.append(f"| {fault} | {backend} | {text} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rounds", type=int, default=1)
    ap.add_argument("--backends", default=",".join(net.BACKENDS))
    args = ap.parse_args(argv)
    why = netns.why_unavailable()
    if why:
        print(why, file=sys.stderr)
        return 2
    # stopped: the rig's namespaces and processes are removed (atexit)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    backends = [b for b in args.backends.split(",") if b]
    results = run(backends, args.rounds)
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(json.dumps({
        "when": datetime.now(timezone.utc).isoformat(timespec="seconds"),
        "machine": {"cpus": os.cpu_count(), "python": platform.python_version(),
                    "load": list(os.getloadavg())},
        "yarp": net.VERSION, "rounds": args.rounds, "results": results,
    }, indent=1) + "\n")
    print(table(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
