"""A generated module running, and what the tests read of it: its log, its
exit totals (one parser for every backend), its clean exit, its RPC port's
`stats`.

    Module(argv, env, name)   a module (Proc): .wait_log(text), .wait_match(regex),
                        .count(regex), .interrupt(sig) -> (status, seconds to exit)
    Node(env, path, *args)    a generated Python module or node run by the venv's
                        Python (the ones started are in ``Node.started``)
    totals(log) -> {source: (received, dropped, stale periods), "published",
                    "skipped", "failures"}
    assert_delivered(counters, totals), assert_fixed_rate(stamped, skipped, rate)
    assert_clean_exit(server, module, rc, seconds, ports=()), stop_clean(node, sig)
    wait_log(proc, regex), stop_within(proc, seconds, sig)   for any Proc
    stats(server, port), wait_stats(server, port, pred)   the module's `stats` over RPC
    quit_over_rpc(env, module, port) -> (status, seconds from the `[bye]` reply to the exit)
    EXIT_BOUND   the seconds a module may take to exit before a test calls it hung
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

#: The seconds a module may take to exit, after SIGINT, SIGTERM or `quit`,
#: before a test calls it hung. The runtimes bound their own waits on the way
#: out (docs/runtime.md, "Shutdown": within 2 s); a machine whose cores are
#: taken by other processes delays the rest, interpreter and all, by an
#: amount no test controls: the bound is a hang detector, not a figure.
EXIT_BOUND = 10.0


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
        a module still running after EXIT_BOUND is stopped (status None)."""
        t0 = time.monotonic()
        os.kill(self.pid, sig)
        try:
            rc = self.popen.wait(EXIT_BOUND)
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
    """Exit 0 within EXIT_BOUND, no traceback, the totals printed, and
    ``ports`` gone from the name server."""
    log = module.log_text()
    assert rc == 0, f"exit status {rc}; log:\n{log[-3000:]}"
    assert seconds < EXIT_BOUND, f"took {seconds:.2f} s to exit"
    assert "Traceback" not in log, log[-3000:]
    assert "totals:" in log
    for p in ports:
        assert not registered(server, p), f"{p} still registered after exit"
    return log


def assert_fixed_rate(stamped: list, skipped: int, rate: float) -> None:
    """Messages of a module at a fixed ``rate``, each (its counter, the time
    its module stamped on it by its own clock), held to how the loop runs:
    cycle k is due at start + k / rate, and is published at most a period
    after it is due (a later one is skipped, and counted: ``skipped``, the
    module's count over its life) plus the time it takes to build. So the
    first and last are (their counters apart, plus at most ``skipped``)
    periods apart, within 2 periods either way: a test of the module's own
    clock and counts, which a loaded machine cannot fail (a reader's arrival
    times would measure the reader)."""
    (c0, s0), (c1, s1) = stamped[0], stamped[-1]
    period = 1.0 / rate
    span = s1 - s0
    assert (c1 - c0 - 2) * period <= span <= (c1 - c0 + skipped + 2) * period, \
        f"{c1 - c0} messages in {span:.3f} s at {rate} Hz, {skipped} cycles skipped: {stamped}"


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
    """Stop the node with ``sig``: exit 0 within EXIT_BOUND, no traceback;
    its log."""
    rc, took = node.interrupt(sig)
    log = node.log_text()
    assert rc == 0, f"exit status {rc}; log:\n{log[-3000:]}"
    assert took < EXIT_BOUND, f"took {took:.2f} s to exit"
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


def stop_within(proc: Proc, seconds: float = EXIT_BOUND, sig=signal.SIGINT) -> tuple:
    """(exit status, seconds): ``sig`` to the module alone, as a user's
    Ctrl-C; a process still running ``seconds`` later is stopped (status None)."""
    t0 = time.monotonic()
    os.kill(proc.pid, sig)
    try:
        rc = proc.popen.wait(seconds)
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


def quit_over_rpc(env: dict, module: Proc, port: str) -> tuple[Optional[int], float]:
    """`quit` on the module's RPC port ``port``, from a client connected
    beforehand: (exit status, seconds from the `[bye]` reply to the exit),
    so that what is timed is the module's exit, not a client's start or
    close; a module still running EXIT_BOUND after its reply is stopped
    (status None)."""
    from harness.services import RpcClient  # (services imports this module)

    client = RpcClient(env, port, name="/test/quit")
    client.start()
    try:
        client.connect()
        reply = client.call(["quit"])
        assert reply.ok and "bye" in reply.text, reply
        try:
            rc = module.popen.wait(max(0.0, reply.t1 + EXIT_BOUND - time.time()))
        except subprocess.TimeoutExpired:
            rc = None
        took = time.time() - reply.t1
    finally:
        client.stop()
    if rc is None:
        module.stop()
    return rc, took
