"""Speed of the ybgc front end, measured (not asserted).

    .venv/bin/python bench/compiler.py [--quick] [--out bench/results/compiler.json]

1. `ybgc check` on every example and legacy config (plus the canonical corpus,
   20 files) in one process, wall time from process start, against the same
   machine's bare `python -c pass`, median of repeated runs.
2. A synthetic config of 1,000 muxes of 8 ports each and 2,000 fields.
3. Growth: synthetic configs of 100 to 10,000 fields; time per field.

Figures are printed and written as JSON for docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time
from datetime import datetime, timezone
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PY = sys.executable
YBGC = str(Path(PY).parent / "ybgc")


def synthetic(n_mux: int, ports_per_mux: int, n_fields: int) -> str:
    """A YARP-to-YARP bridge: every port declares 4 float64, fields take
    single elements, slices and whole muxes in turn."""
    out = ["[output]", "port = /synthetic/out:o", "rate = 100", ""]
    for m in range(n_mux):
        ports = ", ".join(f"/robot/part{m}/sensor{p}:o (float64 x4)" for p in range(ports_per_mux))
        out += [f"[mux m{m}]", f"ports = {ports}", "convert = deg_to_rad[0:4], scale(0.5)[4:8]", ""]
    out.append("[message]")
    width = 4 * ports_per_mux
    for f in range(n_fields):
        m = f % n_mux
        kind = f % 3
        if kind == 0:
            out.append(f"f{f} = m{m}[{f % width}]")
        elif kind == 1:
            out.append(f"f{f} = [m{m}[0:{1 + f % width}]]")
        else:
            out.append(f"f{f} = [m{m}]")
    return "\n".join(out) + "\n"


def wall(cmd: list[str], repeat: int) -> tuple[float, float]:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = subprocess.run(cmd, capture_output=True)
        times.append(time.perf_counter() - t0)
        if r.returncode not in (0,):
            raise SystemExit(f"{' '.join(cmd[:3])}...: exit {r.returncode}\n{r.stderr.decode()[-2000:]}")
    return statistics.median(times), min(times)


def in_process(text: str, repeat: int) -> float:
    from ybg.compiler.pipeline import compile_text

    compile_text("[output]\nport = /w:o\n[mux m]\nports = /a:o\n[message]\nx = m\n")  # warm the parser
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        r = compile_text(text, "synthetic.ini")
        best = min(best, time.perf_counter() - t0)
        assert r.program is not None, r.errors[:3]
    return best


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer repetitions, smaller growth series")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results" / "compiler.json"))
    args = ap.parse_args()
    repeat = 3 if args.quick else 9
    files = sorted((ROOT / "examples").glob("*.ini")) + sorted((ROOT.parent / "shared" / "legacy").glob("*.ini"))
    files += sorted((ROOT / "tests" / "canonical").glob("*.ini"))
    files = [str(f) for f in files][:20]
    # bytecode as an installed package has it, and a warm parser cache
    subprocess.run([PY, "-m", "compileall", "-q", str(ROOT / "ybg")], check=True, capture_output=True)
    subprocess.run([YBGC, "check", files[0]], capture_output=True)

    results: dict = {
        "date": datetime.now(timezone.utc).strftime("%Y-%m-%d %H:%M UTC"),
        "machine": f"{platform.machine()}, {os.cpu_count()} cores, {platform.python_implementation()} {platform.python_version()}",
        "command": "python bench/compiler.py" + (" --quick" if args.quick else ""),
    }
    bare, _ = wall([PY, "-c", "pass"], repeat)
    check, check_min = wall([YBGC, "check", *files], repeat)
    results["check_files"] = len(files)
    results["bare_python_s"] = bare
    results["check_s"] = check
    results["check_over_bare"] = check / bare
    print(f"bare python -c pass          {bare * 1000:8.1f} ms")
    print(f"ybgc check of {len(files)} configs     {check * 1000:8.1f} ms  (x{check / bare:.1f} bare python; target < 300 ms)")

    with tempfile.TemporaryDirectory() as tmp:
        big = Path(tmp) / "synthetic_1000_mux.ini"
        big.write_text(synthetic(1000, 8, 2000))
        big_wall, _ = wall([YBGC, "check", str(big)], max(1, repeat // 3))
        results["mux1000_wall_s"] = big_wall
        results["mux1000_lines"] = big.read_text().count("\n")
        print(f"1,000 muxes x 8 ports, 2,000 fields ({results['mux1000_lines']} lines): "
              f"{big_wall * 1000:.0f} ms wall (target < 1 s)")

    sizes = [100, 300, 1000, 3000, 10000] if not args.quick else [100, 1000, 10000]
    growth = []
    for n in sizes:
        text = synthetic(max(1, n // 20), 8, n)
        t = in_process(text, 3 if n <= 3000 else 1)
        growth.append({"fields": n, "muxes": max(1, n // 20), "seconds": t, "us_per_field": t / n * 1e6})
        print(f"  {n:6d} fields, {max(1, n // 20):4d} muxes: {t * 1000:8.1f} ms  ({t / n * 1e6:6.1f} us/field)")
    results["growth"] = growth
    ratio = growth[-1]["us_per_field"] / growth[0]["us_per_field"]
    results["growth_per_field_ratio_largest_to_smallest"] = ratio
    print(f"time per field, largest / smallest: {ratio:.2f} (1.0 = linear)")
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(results, indent=2) + "\n")
    print(f"written: {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
