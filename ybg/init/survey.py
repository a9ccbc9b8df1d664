"""The YARP side of ``ybgc init``: what a running robot's name server lists
under a prefix, what each of its streaming ports sends for a while, and what
its RPC ports answer. Imports the YARP bindings: only ``ybgc init`` loads
this module.

What it touches on the robot, and nothing else:
- the name server: one `list`;
- each listed port that is not an input by YARP's naming (a name ending in
  ``:i``) nor an RPC port (``rpc`` in its last part): one connection to a
  port of its own (``/ybgc/init/<pid>/<k>:i``) for the sampling time, then
  closed;
- each RPC port: `help`; a controlboard's (``<part>/rpc:i`` beside a
  ``<part>/state:o``) also `get axes` and `get name <j>` for each axis, the
  questions YARP's own remote controlboard asks (IAxisInfo). From YARP 4.0
  a controlboard server answers them on ``<part>/nws/rpc:i``, in its
  thrift service (ControlBoardMsgs: `getAxesRPC`, `getAxisNameRPC j`). A
  Bottle written to it through the bindings gets no reply (4.0.0), while
  YARP's own `yarp rpc` gets one: those are asked through `yarp rpc` (the
  `yarp` on PATH), and where it is missing or does not answer the joints
  are numbered, said to confirm.
  These only read; nothing is written to any other port."""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field

from ybg.probe.layout import seen as layout_text
from ybg.probe.yarp_graph import _yarp, element, name_server

#: the one-word replies that refuse a command (YARP's devices answer [fail])
REFUSALS = ("fail", "failed", "nack", "no", "error", "unknown")

#: a registration in the name server's answer to `list`
_REGISTRATION = re.compile(r"registration name (\S+) ip ")


@dataclass
class Sampled:
    """What one port sent while it was read: ``bottles`` counted, the
    ``first`` one's elements (``(wire type, value)``, as ``ybgc probe``
    reads them), every layout seen (:func:`ybg.probe.layout.seen` texts),
    ``image`` (pixel code, width, height) for a YARP image, the arrival times
    of the first and last (for the rate), ``refused`` when it took no
    connection."""

    name: str
    bottles: int = 0
    first: list | None = None
    layouts: set = field(default_factory=set)
    image: tuple[str, int, int] | None = None
    first_at: float = 0.0
    last_at: float = 0.0
    refused: bool = False

    def rate(self) -> float | None:
        """Messages a second, from the first to the last arrival; None below 3."""
        if self.bottles < 3 or self.last_at <= self.first_at:
            return None
        return (self.bottles - 1) / (self.last_at - self.first_at)


@dataclass
class Answers:
    """What an RPC port answered: ``help`` (its reply's text; None: no
    reply), and for a controlboard's, its number of ``axes`` and their
    ``names`` (None where it did not say)."""

    help: str | None = None
    axes: int | None = None
    names: list | None = None
    #: how the axes were asked: "get axes" (YARP 3) or "getAxesRPC" (YARP 4's thrift service)
    asked: str = "get axes"


@dataclass
class Survey:
    prefix: str
    server: str
    seconds: float
    ports: list = field(default_factory=list)      # every port listed under the prefix
    sampled: dict = field(default_factory=dict)    # name -> Sampled
    answers: dict = field(default_factory=dict)    # name -> Answers


def under(name: str, prefix: str) -> bool:
    prefix = prefix.rstrip("/")
    return not prefix or name == prefix or name.startswith(prefix + "/")


def is_rpc(name: str) -> bool:
    return "rpc" in name.rsplit("/", 1)[-1]


def is_input(name: str) -> bool:
    """An input by YARP's naming: ``:i`` at the end (``state:o`` is an
    output, ``command:i`` an input)."""
    return name.endswith(":i")


def controlboard_rpc(name: str, ports) -> bool:
    """An RPC port of a controlboard: ``<part>/rpc:i`` (YARP 4.0:
    ``<part>/nws/rpc:i``) with ``<part>/state:o`` listed."""
    for tail in ("/nws/rpc:i", "/rpc:i"):
        if name.endswith(tail):
            return name[: -len(tail)] + "/state:o" in ports
    return False


def list_ports(yarp, timeout: float = 3.0) -> list[str]:
    """Every port the name server lists (its `list`), in its order."""
    cmd = yarp.Bottle()
    cmd.addString("list")
    reply = yarp.Bottle()
    style = yarp.ContactStyle()
    style.quiet = True
    style.timeout = timeout
    if not yarp.NetworkBase.writeToNameServer(cmd, reply, style):
        return []
    names = []
    # YARP's yarpserver answers one string of lines; another name server may
    # answer one registration an item: either reads
    texts = [reply.get(k).toString() if reply.get(k).isList() else reply.get(k).asString()
             for k in range(reply.size())]
    for text in texts:
        names += _REGISTRATION.findall(text)
    return [n for n in dict.fromkeys(names) if n.startswith("/")]


def survey(prefix: str, seconds: float, wait: float = 3.0) -> Survey:
    """Ask the name server about the ports under ``prefix``, read each
    streaming one for ``seconds`` (all at once), and ask each RPC port."""
    yarp = _yarp()
    # the bindings print on the standard output (SWIG's "memory leak" notes
    # for the port readers' types), where the table and --format json go:
    # dropped while YARP is in use (YARP's own messages go to stderr)
    sys.stdout.flush()
    saved = os.dup(1)
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, 1)
    os.close(devnull)
    yarp.Network.init()
    try:
        found = Survey(prefix, name_server(yarp, wait), seconds)
        found.ports = [p for p in list_ports(yarp, wait) if under(p, prefix) and p != found.server
                       and not p.startswith("/ybgc/")]
        streams = [p for p in found.ports if not is_input(p) and not is_rpc(p)]
        found.sampled = _sample(yarp, streams, seconds)
        for p in found.ports:
            if is_rpc(p):
                found.answers[p] = _ask(yarp, p, controlboard_rpc(p, found.ports), wait)
        return found
    finally:
        yarp.Network.fini()
        os.dup2(saved, 1)
        os.close(saved)


class _Counter:
    """Counts what one port sends, in the thread of its connection."""

    def __init__(self, yarp, seen: Sampled):
        self.seen = seen
        self.lock = threading.Lock()
        self.bottle = yarp.Bottle()
        self.yarp = yarp

    def read(self, connection) -> bool:
        b = self.bottle
        if not b.read(connection):
            return False
        now = time.monotonic()
        image = _image(b)
        elements = None if image else [element(self.yarp, b.get(i)) for i in range(b.size())]
        with self.lock:
            s = self.seen
            s.bottles += 1
            s.last_at = now
            if s.bottles == 1:
                s.first_at = now
                s.first = elements
                s.image = image
            s.layouts.add(f"image {image[0]} {image[1]}x{image[2]}" if image else layout_text(elements))
        return True


def _image(b) -> tuple[str, int, int] | None:
    """A YARP image read as a Bottle: ``[mat] [<pixel code>] (depth size
    quantum width height) {pixels}``: (pixel code, width, height)."""
    if b.size() != 4 or not (b.get(0).isVocab32() and b.get(1).isVocab32() and b.get(2).isList()):
        return None
    if b.get(0).toString().strip("[]") != "mat":
        return None
    dims = b.get(2).asList()
    if dims.size() < 5:
        return None
    return b.get(1).toString().strip("[]"), dims.get(3).asInt32(), dims.get(4).asInt32()


def _sample(yarp, names: list[str], seconds: float) -> dict[str, Sampled]:
    class Reader(yarp.PortReader):
        def __init__(self, counter):
            yarp.PortReader.__init__(self)
            self.counter = counter

        def read(self, connection):
            try:
                return self.counter.read(connection)
            except Exception:  # never an exception into YARP's thread
                return False

    out = {n: Sampled(n) for n in names}
    ports, readers = {}, []
    try:
        for k, name in enumerate(names):
            seen = out[name]
            reader = Reader(_Counter(yarp, seen))
            readers.append(reader)
            port = yarp.Port()
            port.setReader(reader)
            port.setInputMode(True)
            port.setOutputMode(False)
            local = f"/ybgc/init/{os.getpid()}/{k}:i"
            if port.open(local) and yarp.Network.connect(name, local, "", True):
                ports[name] = port
            else:
                seen.refused = True
                port.close()
        time.sleep(seconds)
    finally:
        for name, port in ports.items():
            yarp.Network.disconnect(name, port.getName(), True)
            port.close()
    return out


def _call(yarp, name: str, words: list, wait: float):
    """The reply of the RPC port ``name`` to a command of ``words`` (a str a
    string, ("vocab", text) a vocab, an int an int32), or None."""
    style = yarp.ContactStyle()
    style.quiet = True
    style.timeout = wait
    cmd = yarp.Bottle()
    for w in words:
        if isinstance(w, tuple):
            cmd.addVocab32(w[1])
        elif isinstance(w, int):
            cmd.addInt32(w)
        else:
            cmd.addString(w)
    reply = yarp.Bottle()
    if not yarp.Network.write(yarp.Contact(name), cmd, reply, style):
        return None
    return reply


def _yarp_rpc(yarp, name: str, commands: list[str], wait: float) -> list | None:
    """The replies (Bottles) of the RPC port ``name`` to ``commands`` typed
    into YARP's `yarp rpc`, one a command; None without a `yarp` on PATH."""
    tool = shutil.which("yarp")
    if tool is None:
        return None
    try:
        done = subprocess.run([tool, "rpc", name], input="".join(c + "\n" for c in commands), text=True,
                              capture_output=True, timeout=wait * (1 + len(commands)))
    except (OSError, subprocess.SubprocessError):
        return None
    out = []
    for line in done.stdout.splitlines():
        if line.startswith("Response: "):
            out.append(yarp.Bottle(line[len("Response: "):]))
    return out


def _thrift_value(reply, kind: str):
    """The value of a YARP 4 ControlBoardMsgs reply, ``([ok]) VALUE``, or None."""
    if reply is None or reply.size() < 2 or not reply.get(0).isList():
        return None
    if reply.get(0).asList().get(0).toString().strip("[]") != "ok":
        return None
    v = reply.get(1)
    if kind == "int":
        return v.asInt32() if v.isInt32() else None
    return v.asString() if v.isString() else None


def _ask_thrift(yarp, name: str, got: Answers, wait: float) -> Answers:
    """A YARP 4 controlboard's axes and names (`getAxesRPC`, `getAxisNameRPC j`)."""
    got.asked = "getAxesRPC"
    replies = _yarp_rpc(yarp, name, ["getAxesRPC"], wait) or [None]
    got.axes = _thrift_value(replies[0], "int")
    if got.axes is None or not 0 < got.axes <= 256:
        return got
    replies = _yarp_rpc(yarp, name, ["getAxisNameRPC %d" % j for j in range(got.axes)], wait) or []
    names = [_thrift_value(r, "str") for r in replies]
    if len(names) == got.axes and None not in names:
        got.names = names
    return got


def _ask(yarp, name: str, controlboard: bool, wait: float) -> Answers:
    got = Answers()
    reply = _call(yarp, name, ["help"], wait)
    # a refusal (YARP's [fail], a nack) is no answer to help
    if reply is not None and reply.size() and not (
            reply.size() == 1 and reply.get(0).toString().strip("[]").lower() in REFUSALS):
        got.help = reply.toString()
    if not controlboard:
        return got
    if name.endswith("/nws/rpc:i"):
        return _ask_thrift(yarp, name, got, wait)
    get = ("vocab", "get")
    reply = _call(yarp, name, [get, ("vocab", "axes")], wait)
    # YARP's controlboard answers [is] axes N [ok]
    if reply is not None and reply.size() >= 3 and reply.get(2).isInt32():
        got.axes = reply.get(2).asInt32()
    if got.axes is None or not 0 < got.axes <= 256:
        return got
    names = []
    for j in range(got.axes):
        reply = _call(yarp, name, [get, ("vocab", "name"), j], wait)
        if reply is None or reply.size() < 3 or not reply.get(2).isString():
            return got
        names.append(reply.get(2).asString())
    got.names = names
    return got
