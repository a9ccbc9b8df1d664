"""Processes the tests start: each in a process group of its own, its
output in a log file, stopped with everything it started (SIGTERM, then
SIGKILL of the whole group and of its descendants); an ``atexit`` hook stops
anything a crashed test left behind.

    Proc(argv, env=None, cwd=None, name=None)   any process (e.g. a generated
        module), in a process group of its own, stdout+stderr to .log_path:
        .start(), .stop(timeout=3, sig=SIGTERM) -> exit status, .kill(),
        .wait_exit(timeout), .alive, .group_alive(), .log_text(), .returncode.
        stop() also kills descendants that left the group.
    Peer(env, config)   a script of tests/peers/ (JSON lines over stdin/stdout):
        .wait(pred, timeout), .wait_event(name), .events: the raw peer events
    Subscriber          a peer that records the ROS messages of a topic
        (.messages: Message(t, msg as nested dicts), .wait_for(n),
        .wait_publishers(n) / .wait_matched(n))
    wait_until(pred, timeout, what, proc=None)   poll until true, or fail with the log
    stop_all(), live_processes(), tmp_root() (one folder per run, removed at exit;
    kept with YBG_KEEP_TMP=1)
"""
from __future__ import annotations

import atexit
import fcntl
import json
import os
import re
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Iterable, Optional

from harness.env import PEERS, VENV_PYTHON, base_env

_SETPRIV = shutil.which("setpriv")
_LIVE: "set[Proc]" = set()
_LIVE_LOCK = threading.Lock()


def _proc_table() -> dict:
    """{pid: (state, ppid, pgrp, starttime)} of every process."""
    table = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as f:
                stat = f.read()
        except OSError:
            continue
        rest = stat[stat.rfind(")") + 2:].split()
        # rest[0] state, rest[1] ppid, rest[2] pgrp, rest[19] starttime
        try:
            table[int(d)] = (rest[0], int(rest[1]), int(rest[2]), int(rest[19]))
        except (IndexError, ValueError):
            continue
    return table


def _group_members(pgid: int) -> list:
    """Pids of the live (non-zombie) processes in process group ``pgid``."""
    return [pid for pid, (st, _, pg, _) in _proc_table().items()
            if pg == pgid and st not in ("Z", "X")]


def _tree(root: int, pgid: Optional[int]) -> set:
    """{(pid, starttime)} of the live processes in group ``pgid`` and of all
    descendants of ``root`` and of those group members (some programs, e.g.
    roslaunch, put their children in sessions of their own)."""
    table = _proc_table()
    children: dict = {}
    for pid, (_, ppid, _, _) in table.items():
        children.setdefault(ppid, []).append(pid)
    todo = [root] + [pid for pid, v in table.items() if pgid is not None and v[2] == pgid]
    seen = set()
    while todo:
        pid = todo.pop()
        if pid in seen or pid not in table:
            continue
        seen.add(pid)
        todo.extend(children.get(pid, []))
    return {(pid, table[pid][3]) for pid in seen if table[pid][0] not in ("Z", "X")}


def _still_running(known: set) -> set:
    table = _proc_table()
    return {(pid, st) for pid, st in known
            if pid in table and table[pid][3] == st and table[pid][0] not in ("Z", "X")}


class Proc:
    """A process started in its own process group (session), output to a log
    file (or, with ``pipe_stdout``, stdout to a pipe and stderr to the log).
    Context manager: started on enter, stopped (whole group) on exit."""

    def __init__(self, argv: Iterable, env: Optional[dict] = None, cwd=None,
                 name: Optional[str] = None, log_dir=None, pipe_stdout: bool = False,
                 pipe_stdin: bool = False, die_with_parent: bool = False,
                 gate_output: bool = False):
        self.argv = [str(a) for a in argv]
        self.env = dict(env) if env is not None else base_env()
        self.cwd = str(cwd) if cwd is not None else None
        self.name = name or Path(self.argv[0]).name
        self.log_dir = Path(log_dir) if log_dir else tmp_root()
        base = re.sub(r"[^A-Za-z0-9_.-]", "_", self.name)
        self.log_path = self.log_dir / f"{base}.log"
        k = 1
        while self.log_path.exists():
            k += 1
            self.log_path = self.log_dir / f"{base}.{k}.log"
        self.pipe_stdout = pipe_stdout
        self.pipe_stdin = pipe_stdin
        self.die_with_parent = die_with_parent
        self.gate_output = gate_output and not pipe_stdout
        self._gate: Optional[_OutputGate] = None
        self.popen: Optional[subprocess.Popen] = None
        self.pgid: Optional[int] = None
        self._known: set = set()
        self.starts = 0

    # -- lifecycle
    def start(self) -> "Proc":
        if self.alive:
            return self
        self.starts += 1
        log = open(self.log_path, "ab")
        log.write(f"==== start {self.starts}: {' '.join(self.argv)}\n".encode())
        log.flush()
        argv = self.argv
        # With die_with_parent the process gets SIGKILL if the test process
        # itself is killed (no atexit then). The kernel ties this to the thread
        # that starts it, so only from the main thread.
        if self.die_with_parent and _SETPRIV and threading.current_thread() is threading.main_thread():
            argv = [_SETPRIV, "--pdeathsig", "KILL", "--"] + argv
        stdout = subprocess.PIPE if self.pipe_stdout else log
        if self.gate_output:
            self._gate = _OutputGate(self.log_path)
            stdout = self._gate.write_fd
        try:
            self.popen = subprocess.Popen(
                argv, env=self.env, cwd=self.cwd,
                stdin=subprocess.PIPE if self.pipe_stdin else subprocess.DEVNULL,
                stdout=stdout, stderr=log, start_new_session=True)
        finally:
            log.close()
            if self._gate is not None:
                self._gate.started()
        self.pgid = self.popen.pid
        self._known = set()
        with _LIVE_LOCK:
            _LIVE.add(self)
        return self

    @property
    def pid(self) -> Optional[int]:
        return self.popen.pid if self.popen else None

    @property
    def alive(self) -> bool:
        return self.popen is not None and self.popen.poll() is None

    @property
    def returncode(self) -> Optional[int]:
        return self.popen.poll() if self.popen else None

    def tree(self) -> set:
        """{(pid, starttime)} of the live processes it started: its process
        group and every descendant (also those in sessions of their own),
        plus any seen at an earlier stop()."""
        if self.pgid is None:
            return set()
        self._known |= _tree(self.pgid, self.pgid)
        return _still_running(self._known)

    def group_alive(self) -> bool:
        """True while any process of its tree (group + descendants) runs."""
        return bool(self.tree())

    def _signal_group(self, sig) -> None:
        if self.pgid is None:
            return
        try:
            os.killpg(self.pgid, sig)
        except (ProcessLookupError, PermissionError):
            pass

    def _kill_tree(self) -> None:
        for pid, _ in _still_running(self._known):
            try:
                os.kill(pid, signal.SIGKILL)
            except (ProcessLookupError, PermissionError):
                pass

    def stop(self, timeout: float = 3.0, sig=signal.SIGTERM) -> Optional[int]:
        """Send ``sig`` to the whole group, wait up to ``timeout`` s for the
        process and everything it started to end, then SIGKILL whatever is
        left (group and descendants). Returns the exit status."""
        if self.popen is None:
            return None
        self.release_output()  # a held stdout would keep it from exiting
        self.tree()  # remember the descendants before they get orphaned
        if self.popen.poll() is None:
            self._signal_group(sig)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.popen.poll()
            if not self.tree():
                break
            time.sleep(0.02)
        end = time.monotonic() + 5
        while True:
            self.popen.poll()
            if not self.tree():
                break
            self._signal_group(signal.SIGKILL)
            self._kill_tree()
            if time.monotonic() > end:
                break
            time.sleep(0.02)
        try:
            self.popen.wait(5)
        except subprocess.TimeoutExpired:
            pass
        self._close_pipes()
        if self._gate is not None:
            self._gate.finish()
        with _LIVE_LOCK:
            _LIVE.discard(self)
        return self.popen.returncode

    def kill(self) -> Optional[int]:
        """SIGKILL the whole group at once (a crash, as seen by its peers)."""
        if self.popen is None:
            return None
        self.tree()
        self._signal_group(signal.SIGKILL)
        self._kill_tree()
        return self.stop(timeout=2.0)

    def _close_pipes(self) -> None:
        for f in (self.popen.stdin, self.popen.stdout):
            if f is not None:
                try:
                    f.close()
                except OSError:
                    pass

    # -- a held stdout (gate_output=True)
    def hold_output(self) -> None:
        """Stop copying the process's stdout to its log: once the small pipe
        (one page) is full, every thread of the process that writes on
        stdout blocks in write(2), the others run on. A test uses it to
        hold up exactly the threads that print (e.g. a module's --verbose
        values, printed by the thread that builds each message)."""
        if self._gate is None:
            raise RuntimeError(f"{self.name}: started without gate_output=True")
        self._gate.hold()

    def release_output(self) -> None:
        """Copy stdout to the log again (the blocked writers go on)."""
        if self._gate is not None:
            self._gate.release()

    def output_blocked(self) -> list:
        """The threads of the process asleep in a write(2)/writev(2) on its
        stdout (fd 1): those a held stdout holds up. [] when none."""
        if self.popen is None or self.popen.poll() is not None:
            return []
        out = []
        task = Path(f"/proc/{self.popen.pid}/task")
        try:
            tids = os.listdir(task)
        except OSError:
            return []
        for tid in tids:
            try:
                fields = (task / tid / "syscall").read_text().split()
            except OSError:
                continue
            # "<nr> <arg0> ...", or "running"; x86_64: write 1, writev 20
            if len(fields) > 1 and fields[0] in ("1", "20") and int(fields[1], 16) == 1:
                out.append(int(tid))
        return out

    def wait_output_blocked(self, timeout: float = 30.0) -> list:
        """Wait until a thread is held up writing on the held stdout."""
        return wait_until(lambda: self.output_blocked(), timeout,
                          f"a thread of {self.name} blocked on its held stdout", self,
                          interval=0.01)

    def wait_exit(self, timeout: Optional[float] = None) -> int:
        """Wait for the process itself to end; returns its exit status."""
        return self.popen.wait(timeout)

    def log_text(self) -> str:
        try:
            return self.log_path.read_text(errors="replace")
        except OSError:
            return ""

    def __enter__(self):
        return self.start()

    def __exit__(self, *exc):
        self.stop()

    def __repr__(self):
        return f"<Proc {self.name} pid={self.pid}>"


class _OutputGate:
    """A process's stdout: a one-page pipe that a thread copies to the log
    file, unless held (see Proc.hold_output)."""

    PIPE_SIZE = 4096

    def __init__(self, log_path: Path):
        self.log_path = log_path
        self.read_fd, self.write_fd = os.pipe()
        try:
            fcntl.fcntl(self.write_fd, getattr(fcntl, "F_SETPIPE_SZ", 1031), self.PIPE_SIZE)
        except OSError:
            pass
        self._open = threading.Event()
        self._open.set()
        self._thread = threading.Thread(target=self._pump, daemon=True, name=f"gate {log_path.name}")

    def started(self) -> None:
        os.close(self.write_fd)  # the child holds it now; EOF when it (and its children) exit
        self.write_fd = -1
        self._thread.start()

    def _pump(self) -> None:
        with open(self.log_path, "ab", buffering=0) as log:
            while True:
                self._open.wait()
                try:
                    data = os.read(self.read_fd, 65536)
                except OSError:
                    break
                if not data:
                    break
                log.write(data)

    def hold(self) -> None:
        self._open.clear()

    def release(self) -> None:
        self._open.set()

    def finish(self) -> None:
        self.release()
        self._thread.join(5)
        if not self._thread.is_alive():
            try:
                os.close(self.read_fd)
            except OSError:
                pass


def stop_all() -> None:
    """Stop every process these helpers started that is still running."""
    with _LIVE_LOCK:
        procs = list(_LIVE)
    for p in procs:
        try:
            p.stop(timeout=1.0)
        except Exception:
            pass


def live_processes() -> list:
    """The Procs started by these helpers and not stopped yet."""
    with _LIVE_LOCK:
        return [p for p in _LIVE if p.alive or p.group_alive()]


_TMP_ROOT: list = []


def tmp_root() -> Path:
    """One temporary folder per test run holding every helper's files and logs;
    removed at exit (kept when YBG_KEEP_TMP is set)."""
    with _LIVE_LOCK:
        if not _TMP_ROOT:
            _TMP_ROOT.append(Path(tempfile.mkdtemp(prefix="ybg-tests-")))
        return _TMP_ROOT[0]


def _at_exit() -> None:
    stop_all()
    if _TMP_ROOT and not os.environ.get("YBG_KEEP_TMP"):
        shutil.rmtree(_TMP_ROOT[0], ignore_errors=True)


atexit.register(_at_exit)


def wait_until(pred: Callable[[], Any], timeout: float, what: str, proc: Optional[Proc] = None,
               interval: float = 0.05):
    """Poll ``pred`` until it is true (returned); fails with the log of
    ``proc`` when it exits first, or on a timeout."""
    end = time.monotonic() + timeout
    while True:
        v = pred()
        if v:
            return v
        if proc is not None and proc.popen is not None and proc.popen.poll() is not None:
            raise RuntimeError(f"{proc.name} exited (status {proc.popen.returncode}) while "
                               f"waiting for {what}; log:\n{proc.log_text()[-3000:]}")
        if time.monotonic() > end:
            tail = f"; log of {proc.name}:\n{proc.log_text()[-3000:]}" if proc else ""
            raise TimeoutError(f"timed out after {timeout} s waiting for {what}{tail}")
        time.sleep(interval)


class TmpDir:
    """A folder under tmp_root() (or the given one, never removed here)."""

    def __init__(self, prefix: str, tmpdir=None):
        self.own = tmpdir is None
        self.path = Path(tmpdir) if tmpdir else Path(tempfile.mkdtemp(prefix=prefix, dir=tmp_root()))
        self.path.mkdir(parents=True, exist_ok=True)

    def remove(self):
        pass  # kept until the end of the run, so that logs can be read after stop()


# --------------------------------------------------------------------------
# peers


class Peer(Proc):
    """A peer script of tests/peers/: config as one JSON argument, JSON events
    on stdout (collected in ``.events`` by a thread), JSON commands on stdin."""

    script = ""
    python = str(VENV_PYTHON)
    ready_timeout = 30.0

    def __init__(self, env: dict, config: dict, name: Optional[str] = None):
        self.config = config
        super().__init__([self.python, PEERS / self.script, json.dumps(config)], env=env,
                         cwd=PEERS, name=name or Path(self.script).stem,
                         pipe_stdout=True, pipe_stdin=True)
        self.events: list = []
        self._mark = 0  # index in .events where the current run starts
        self.noise: list = []
        self._cond = threading.Condition()
        self._reader: Optional[threading.Thread] = None

    def start(self) -> "Peer":
        if self.alive:
            return self
        super().start()
        self._mark = len(self.events)
        out = self.popen.stdout
        self._reader = threading.Thread(target=self._pump, args=(out,), daemon=True)
        self._reader.start()
        self.wait_event("ready", timeout=self.ready_timeout, since=self._mark)
        return self

    def _pump(self, out) -> None:
        for raw in iter(out.readline, b""):
            line = raw.decode(errors="replace").strip()
            if not line:
                continue
            try:
                ev = json.loads(line)
            except ValueError:
                ev = None
            with self._cond:
                if isinstance(ev, dict) and "ev" in ev:
                    self.events.append(ev)
                    self._on_event(ev)
                else:
                    self.noise.append(line)
                self._cond.notify_all()
        with self._cond:
            self._cond.notify_all()

    def _on_event(self, ev: dict) -> None:  # called with the lock held
        pass

    def send(self, **cmd) -> None:
        if not self.alive:
            raise RuntimeError(f"{self.name} is not running; log:\n{self.log_text()[-2000:]}")
        self.popen.stdin.write((json.dumps(cmd) + "\n").encode())
        self.popen.stdin.flush()

    def wait(self, pred: Callable[[], Any], timeout: float = 60.0, what: str = "a condition"):
        """Wait until ``pred()`` (called with the event lock held) is true; return it."""
        end = time.monotonic() + timeout
        with self._cond:
            while True:
                v = pred()
                if v:
                    return v
                if self.popen is not None and self.popen.poll() is not None:
                    raise RuntimeError(f"{self.name} exited (status {self.popen.returncode}) "
                                       f"while waiting for {what}; log:\n{self.log_text()[-3000:]}")
                left = end - time.monotonic()
                if left <= 0:
                    recent = "\n".join(json.dumps(e) for e in self.events[-10:])
                    raise TimeoutError(f"{self.name}: timed out after {timeout} s waiting for "
                                       f"{what}; last events:\n{recent}\n"
                                       f"log:\n{self.log_text()[-3000:]}")
                self._cond.wait(min(left, 0.1))

    def wait_event(self, ev: str, pred: Callable[[dict], bool] = lambda e: True,
                   timeout: float = 60.0, since: int = 0) -> dict:
        def find():
            for e in self.events[since:]:
                if e["ev"] == ev and pred(e):
                    return e
            return None
        return self.wait(find, timeout, f"event {ev!r}")

    def last_event(self, ev: str) -> Optional[dict]:
        with self._cond:
            for e in reversed(self.events):
                if e["ev"] == ev:
                    return e
        return None

    def stop(self, timeout: float = 3.0, sig=signal.SIGTERM):
        rc = super().stop(timeout, sig)
        if self._reader is not None:
            self._reader.join(2)
        return rc

    def __exit__(self, *exc):
        self.stop()


@dataclass
class Message:
    """A ROS message received by a subscriber peer."""
    t: float                 # receive time, time.time()
    msg: dict                # nested dicts of the fields


class Subscriber(Peer):
    """A peer that records the messages of a ROS topic (rospy or rclpy)."""

    def __init__(self, env, config, name):
        super().__init__(env, config, name=name)
        self.messages: list = []
        self.publishers = 0

    def _on_event(self, ev: dict) -> None:
        if ev["ev"] == "msg":
            self.messages.append(Message(ev["t"], ev["msg"]))
        elif ev["ev"] in ("publishers", "matched"):
            self.publishers = ev["n"]

    def wait_for(self, n: int, timeout: float = 60.0) -> list:
        """Wait until ``n`` messages in all have arrived; returns them all."""
        self.wait(lambda: len(self.messages) >= n, timeout, f"{n} messages")
        with self._cond:
            return list(self.messages)

    def wait_publishers(self, n: int = 1, timeout: float = 60.0) -> None:
        self.wait(lambda: self.publishers >= n, timeout, f"{n} publishers")

    wait_matched = wait_publishers

    def clear(self) -> None:
        with self._cond:
            self.messages.clear()
