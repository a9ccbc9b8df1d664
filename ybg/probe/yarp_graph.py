"""The YARP side of ``ybgc probe``: what the name server and the ports say
now. Each port the module would read is asked whether it answers; each that
sends Bottles is connected for a moment to a port of the probe's own
(``/ybgc/probe/<pid>/<k>:i``) until one Bottle arrives or the wait ends.
Imports the YARP bindings: only ``ybgc probe`` loads this module."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

from .plan import Plan, Unavailable


@dataclass
class YarpSeen:
    """``answers``: port -> does it answer (registered and alive);
    ``bottles``: port -> the elements of the first Bottle read from it
    (absent: none within the wait, or not read); ``refused``: the ports
    that answer and took no connection to the probe's port."""

    answers: dict[str, bool] = field(default_factory=dict)
    bottles: dict[str, list] = field(default_factory=dict)
    refused: set[str] = field(default_factory=set)


def _yarp():
    # YARP's own log (a line for each port opened and connection made, on
    # stdout, where the JSON and GitHub reports go) says nothing the
    # diagnostics do not: quiet unless the user asked otherwise
    os.environ.setdefault("YARP_QUIET", "1")
    try:
        import yarp
    except ImportError as e:
        raise Unavailable(f"the YARP Python bindings cannot be imported: {e}",
                          "install YARP with its Python bindings (scripts/setup.sh does), "
                          "in the environment that runs ybgc") from e
    return yarp


def element(yarp, v) -> tuple[str, object]:
    """(wire type, value) of one Bottle element."""
    if v.isList():
        return "list", None
    if v.isBool():
        return "bool", v.asBool()
    if v.isVocab32():
        return "vocab", v.toString()
    for kind in ("Int8", "Int16", "Int32", "Int64"):
        if getattr(v, "is" + kind)():
            return kind.lower(), v.asInt64()
    if v.isFloat32():
        return "float32", v.asFloat64()
    if v.isFloat64():
        return "float64", v.asFloat64()
    if v.isString():
        return "string", v.asString()
    return ("blob" if v.isBlob() else "unknown"), None


def name_server(yarp, wait: float) -> str:
    """The name server's name, once it answers within ``wait`` seconds (at
    least 0.5, at most 5); else :class:`Unavailable`."""
    server = yarp.Network.getNameServerName()
    if not (yarp.Network.checkNetwork(min(max(wait, 0.5), 5.0)) and yarp.Network.exists(server, True)):
        raise Unavailable(f"no YARP name server answers (as {server})",
                          "start yarpserver, or point ybgc at the robot's (yarp conf <ip> <port>; "
                          "yarp detect --write finds it on the network)")
    return server


def observe(plan: Plan, wait: float) -> YarpSeen:
    """Ask the name server about every port of ``plan``, and read one Bottle
    from each input port that answers, all at once, for ``wait`` seconds at
    most."""
    yarp = _yarp()
    yarp.Network.init()
    try:
        name_server(yarp, wait)
        seen = YarpSeen()
        for name in dict.fromkeys([o.name for o in plan.opens] + [r.name for r in plan.reads]):
            seen.answers[name] = bool(yarp.Network.exists(name, True))
        wanted = dict.fromkeys(r.name for r in plan.reads if seen.answers[r.name] and not r.call and not r.image)
        _read_each(yarp, list(wanted), wait, seen)
        return seen
    finally:
        yarp.Network.fini()


def _read_each(yarp, sources: list[str], wait: float, seen: YarpSeen) -> None:
    ports = {}
    try:
        for k, src in enumerate(sources):
            port = yarp.BufferedPortBottle()
            local = f"/ybgc/probe/{os.getpid()}/{k}:i"
            if port.open(local) and yarp.Network.connect(src, local, "", True):
                ports[src] = port
            else:
                seen.refused.add(src)
                port.close()
        end = time.monotonic() + wait
        while ports.keys() - seen.bottles.keys() and time.monotonic() < end:
            for src, port in ports.items():
                if src not in seen.bottles:
                    b = port.read(False)
                    if b is not None:
                        seen.bottles[src] = [element(yarp, b.get(i)) for i in range(b.size())]
            time.sleep(0.01)
    finally:
        for src, port in ports.items():
            yarp.Network.disconnect(src, port.getName(), True)
            port.close()
