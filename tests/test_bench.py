"""The bridge benchmark harness (bench/run.py) works: its smoke path builds the
C++ producer, consumer and reference relays, runs the floors (direct producer
-> consumer, producer -> relay -> consumer, and the same through the strict
relay) over a real yarpserver for a few hundred messages, and writes its JSON. No timing is asserted (the machine
is shared); what is asserted is that every message is accounted for and
carries the right values."""
import json
import subprocess

import pytest

from harness.env import ROOT, VENV_PYTHON, base_env
from harness.yarp import require_yarp


@pytest.mark.timeout(180)
def test_bench_smoke_floors(tmp_path):
    require_yarp()
    results = tmp_path / "results"
    r = subprocess.run(
        [str(VENV_PYTHON), str(ROOT / "bench" / "run.py"), "--smoke", "--results", str(results),
         "--build-dir", str(tmp_path / "build")],
        cwd=ROOT, env=base_env(tmp_path), capture_output=True, text=True, timeout=170)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    assert "latency joints_500hz" in r.stdout  # progress is shown
    data = json.loads((results / "smoke.json").read_text())
    assert data["mode"] == "smoke"
    assert data["fixed_rate"] == [] and data["memory"] == []
    by = {e["subject"]: e for e in data["latency"]}
    assert set(by) == {"direct", "relay", "relay-strict"}
    for s, e in by.items():
        assert "error" not in e, (s, e.get("error"))
        # nothing beyond the run's ticks; a warm-up tick delivered late (under load) is counted apart
        assert e["bad"] == 0 and e["foreign"] == 0, e
        assert 0 < e["median_us"] <= e["p99_us"] <= e["max_us"], e
        assert len(e["cdf_us"]) == 1001 and e["cdf_us"] == sorted(e["cdf_us"])
    direct, relay, strict = by["direct"], by["relay"], by["relay-strict"]
    # 0.6 s at 500 Hz: 300 ticks, one Bottle per port (2 ports) each
    assert direct["sent"] == 600
    # strict writes over TCP into a Port reader: the direct hop loses nothing
    assert direct["delivered"] == 600 and direct["lost"] == 0
    # the relay keeps only the newest Bottle of each input: under load a tick
    # may be overwritten, but most come out, each whole (all ports of one tick)
    assert relay["sent"] == 300
    assert relay["delivered"] + relay["lost"] == 300
    assert relay["delivered"] >= 150, relay
    assert relay["delivered"] > relay["mismatched"]
    assert relay["cpu_pct"] is not None and relay["rss_peak_kb"] > 0
    assert relay["exit_status"] == 0  # SIGTERM: ports closed, exit 0
    # the strict relay reads every Bottle and pairs them by envelope stamp:
    # every tick comes out, whole
    assert strict["sent"] == 300
    assert strict["delivered"] == 300 and strict["mismatched"] == 0, strict
    assert strict["exit_status"] == 0
    assert not (results / "benchmarks.md").exists()  # the smoke path writes no report
