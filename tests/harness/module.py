"""A generated module running, and what the tests read of it: its log, its
exit totals (one parser for every backend), its clean exit, its RPC port's
`stats`.

    Module(argv, env, name)   a module (Proc): .wait_log(text), .wait_match(regex),
                        .count(regex), .interrupt(sig) -> (status, seconds to exit)
    Node(env, path, *args)    a generated Python module or node run by the venv's
                        Python (the ones started are in ``Node.started``)
    totals(log) -> {source: (received, dropped, stale periods), "published",
                    "skipped", "failures"}
    assert_clean_exit(server, module, rc, seconds, ports=()), stop_clean(node, sig)
    wait_log(proc, regex), stop_within(proc, seconds, sig)   for any Proc
    stats(server, port), wait_stats(server, port, pred)   the module's `stats` over RPC
"""
from __future__ import annotations

import os
import re
import signal
import subprocess
import time
from typing import Optional

from harness.env import VENV_PYTHON
from harness.procs import Proc, wait_until
from harness.yarp import registered, rpc


class Module(Proc):
    """A generated module (or node) started with the given environment."""

    def wait_log(self, text: str, timeout: float = 60.0, count: int = 1) -> str:
        """Wait until ``text`` is in the module's log ``count`` times; the log."""
        return self.wait_match(re.escape(text), timeout, count)

    def wait_match(self, pattern: str, timeout: float = 60.0, count: int = 1) -> str:
        """Wait until the regex ``pattern`` matches ``count`` times; the log."""
        end = time.monotonic() + timeout
        while True:
            log = self.log_text()
            if len(re.findall(pattern, log)) >= count:
                return log
            if not self.alive:
                raise AssertionError(f"{self.name} exited ({self.returncode}); log:\n{log[-3000:]}")
            if time.monotonic() > end:
                raise AssertionError(f"no {pattern!r} (x{count}) in the log of {self.name}:\n{log[-3000:]}")
            time.sleep(0.02)

    def count(self, pattern: str) -> int:
        return len(re.findall(pattern, self.log_text()))

    def interrupt(self, sig=signal.SIGINT) -> tuple[Optional[int], float]:
        """Send ``sig`` to the module alone: (exit status, seconds to exit);
        a module still running after 5 s is stopped (status None)."""
        t0 = time.monotonic()
        os.kill(self.pid, sig)
        try:
            rc = self.popen.wait(5.0)
        except subprocess.TimeoutExpired:
            rc = None
        elapsed = time.monotonic() - t0
        if rc is None:
            self.stop()
        return rc, elapsed


class Node(Module):
    """A generated Python module or ROS 2 node run as a script by the venv's
    Python; every one started is in ``Node.started`` (a test file prints
    their logs when a test fails)."""

    started: list = []

    def __init__(self, env, path, *args, name=None):
        self.path = path
        super().__init__([VENV_PYTHON, path, *args], env=env, name=name or path.stem)
        Node.started.append(self)


def totals(log: str) -> dict:
    """{source: (received, dropped, stale periods)}, 'published', 'skipped',
    'failures' (messages that could not be built) and 'missed' (by YARP
    readers: 0 when the totals have no such line) from the exit totals."""
    out = {}
    for m in re.finditer(r"input (\S+): received (\d+), dropped (\d+), stale periods (\d+)", log):
        out[m.group(1)] = tuple(int(x) for x in m.groups()[1:])
    m = re.search(r"published (\d+) messages, skipped (\d+) cycles(?:, build failures (\d+))?", log)
    if m:
        out["published"] = int(m.group(1))
        out["skipped"] = int(m.group(2))
        if m.group(3) is not None:
            out["failures"] = int(m.group(3))
        missed = re.search(r"^\S*\s*readers missed (\d+) messages", log, re.M)
        out["missed"] = int(missed.group(1)) if missed else 0
    return out


def assert_delivered(counters: list, t: dict) -> None:
    """The module's message counters a reader got: in order, none twice, and
    a gap only where the module counts messages missed in its exit totals
    ``t`` (totals(): written while the reader's connection still sent the
    one before, a reader not scheduled in time on a loaded machine)."""
    missed = t["missed"]
    assert counters == sorted(set(counters)), f"out of order or repeated: {counters}"
    lost = counters[-1] - counters[0] + 1 - len(counters) if counters else 0
    assert lost <= missed, f"{lost} messages never reached the reader, {missed} counted missed: {counters}"


def assert_clean_exit(server, module: Module, rc, seconds: float, ports=()) -> str:
    """Exit 0 within 2 s, no traceback, the totals printed, and ``ports``
    (default: every port of the module's prefix) gone from the name server."""
    log = module.log_text()
    assert rc == 0, f"exit status {rc}; log:\n{log[-3000:]}"
    assert seconds < 2.0, f"took {seconds:.2f} s to exit"
    assert "Traceback" not in log, log[-3000:]
    assert "totals:" in log
    for p in ports:
        assert not registered(server, p), f"{p} still registered after exit"
    return log


def rate_from_counters(bottles, skipped: int, nominal: float) -> tuple:
    """(lowest, highest) rate a fixed-rate module can have had, from the
    message counters (data[0]) and receive times of ``bottles``: between the
    message received soonest after its cycle in the first second and the
    same in the last second (a reader held up by the machine only delays a
    receive time, never advances it), the module published the counter
    difference and skipped at most ``skipped`` cycles."""
    per = max(1, int(nominal))

    def soonest(part):
        return min(part, key=lambda b: b.t - b.data[0] / nominal)
    a, b = soonest(bottles[:per]), soonest(bottles[-per:])
    span = b.t - a.t
    published = b.data[0] - a.data[0]
    return published / span, (published + skipped) / span


def hold_the_reader(module: Module, reader, producer, width=16, limit=500) -> int:
    """Hold up the module's thread that reads (and publishes, event-driven)
    while its port goes on accepting: with the module's stdout held, write
    one Bottle at a time until that thread blocks printing one (--verbose);
    returns how many Bottles were written, the last one being the one held."""
    module.hold_output()
    k = 0
    while k < limit:
        producer.write([float(k)] + [0.5] * (width - 1))
        k += 1
        # its message comes out, or the thread is held printing it
        wait_until(lambda: len(reader.bottles) >= k or module.output_blocked(), 60,
                   f"message {k} or a held stdout", module)
        if len(reader.bottles) < k:
            module.wait_output_blocked()
            return k
    raise AssertionError(f"{module.name}: never blocked on its held stdout")


def stop_clean(node: Module, sig=signal.SIGINT) -> str:
    """Stop the node with ``sig``: exit 0 within 2 s, no traceback; its log."""
    rc, took = node.interrupt(sig)
    log = node.log_text()
    assert rc == 0, f"exit status {rc}; log:\n{log[-3000:]}"
    assert took < 2.0, f"took {took:.2f} s to exit"
    assert "Traceback" not in log, log
    assert "totals:" in log
    return log


def wait_log(proc: Proc, pattern: str, timeout: float = 60.0) -> str:
    """Wait until the regex ``pattern`` is in the log of ``proc``; the log."""
    end = time.monotonic() + timeout
    while True:
        log = proc.log_text()
        if re.search(pattern, log):
            return log
        if not proc.alive:
            raise AssertionError(f"{proc.name} exited ({proc.returncode}) before {pattern!r}; log:\n{log[-3000:]}")
        if time.monotonic() > end:
            raise AssertionError(f"no {pattern!r} in the log of {proc.name} after {timeout} s:\n{log[-3000:]}")
        time.sleep(0.05)


def stop_within(proc: Proc, seconds: float = 2.0, sig=signal.SIGINT) -> tuple:
    """(exit status, seconds): ``sig`` to the module alone, as a user's Ctrl-C."""
    t0 = time.monotonic()
    os.kill(proc.pid, sig)
    try:
        rc = proc.popen.wait(seconds + 5.0)
    except subprocess.TimeoutExpired:
        rc = None
    took = time.monotonic() - t0
    proc.stop()
    return rc, took


# --------------------------------------------------------------------------
# the module's RPC port

# `yarp rpc` prints each item of a "many" answer on a line of its own
# (each input's `refused N` follows: tests/test_foreign_source.py)
STATS_INPUT = re.compile(r'^\s*input "?([^"\s]+)"? received (\d+) dropped (\d+) stale (\d+) unused (\d+) refused \d+$',
                         re.M)
STATS_PUBLISHED = re.compile(r"^\s*published (\d+) skipped (\d+) failures (\d+) missed (\d+)$", re.M)
# the rates are text, which YARP prints quoted when it starts with a digit
STATS_RATE = re.compile(r'^\s*rate "?([^"\s]+)"? configured "?([^"\s]+)"?$', re.M)


def stats(server, port: str) -> dict:
    """The `stats` answer: {"inputs": {source: (received, dropped, stale, unused)},
    "published": (published, skipped, failures), "missed" (messages YARP
    readers missed), "rate": (achieved, configured)}."""
    text = rpc(server, port, "stats")
    published = STATS_PUBLISHED.search(text)
    rate = STATS_RATE.search(text)
    assert published and rate, text
    return {"inputs": {m[0]: tuple(map(int, m[1:])) for m in STATS_INPUT.findall(text)},
            "published": tuple(map(int, published.groups()[:3])), "missed": int(published.group(4)),
            "rate": (float(rate.group(1)), rate.group(2)), "text": text}


def wait_stats(server, port: str, pred, timeout: float = 30.0) -> dict:
    """The first `stats` answer that satisfies ``pred``."""
    end = time.monotonic() + timeout
    while True:
        got = stats(server, port)
        if pred(got):
            return got
        if time.monotonic() > end:
            raise AssertionError(f"stats never matched in {timeout} s; last answer:\n{got['text']}")
        time.sleep(0.1)
