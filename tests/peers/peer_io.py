"""Tiny JSON-lines protocol shared by the peers (stdlib only; used by both the
venv python and Debian's /usr/bin/python3).

A peer gets its configuration as one JSON argument, prints one JSON object per
line on stdout (events, each with an "ev" key) and reads JSON commands (each
with a "cmd" key) from stdin.
"""
import json
import os
import queue
import signal
import sys
import threading
import time

_out_lock = threading.Lock()

# The events get a descriptor of their own: the standard output this process
# was given, duplicated. Descriptor 1 then goes to standard error, so that what
# the middleware writes there from its own threads (YARP prints its [INFO]
# lines on stdout) lands in the log instead of inside an event line.
_events = os.fdopen(os.dup(1), "w", buffering=1, encoding="utf-8")
os.dup2(2, 1)


def config():
    return json.loads(sys.argv[1]) if len(sys.argv) > 1 else {}


def emit(ev, **fields):
    fields["ev"] = ev
    fields.setdefault("t", time.time())
    line = json.dumps(fields)
    with _out_lock:
        _events.write(line + "\n")
        _events.flush()


def commands():
    """A queue filled by a daemon thread with the commands read from stdin;
    a None is queued at end of input."""
    q = queue.Queue()

    def pump():
        for line in sys.stdin:
            line = line.strip()
            if line:
                try:
                    q.put(json.loads(line))
                except ValueError:
                    emit("error", message="bad command %r" % line)
        q.put(None)

    threading.Thread(target=pump, daemon=True).start()
    return q


def exit_on_signals():
    """SIGTERM / SIGINT end the process at once (nothing to clean up)."""
    def handler(signum, frame):
        try:
            _events.flush()
        finally:
            os._exit(0)
    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)


def exit_at_stdin_eof():
    """End the process when stdin closes (the test process went away), for
    peers that take no commands."""
    def watch():
        for _ in sys.stdin:
            pass
        try:
            _events.flush()
        finally:
            os._exit(0)
    threading.Thread(target=watch, daemon=True).start()
