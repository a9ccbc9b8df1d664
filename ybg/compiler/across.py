"""Checks across configs: what no config can be wrong about alone.

A robot runs many bridges at once, each from its own config; two of them
can agree with their own `.msg` and `.srv` definitions and still break each
other on the robot. ``ybgc check`` of several configs (a folder's, by
default) runs :func:`check_across` on the programs that check:

- E360: one ROS topic with two message types (published by one bridge,
  published or read by another);
- E361: one YARP port opened by two bridges (an output port, a served RPC
  port);
- E362: two bridges with one module name (the same ports `/<name>/...`,
  the same ROS node name);
- E363: one ROS 2 service served twice, or with two service types.

- W364: a ROS 2 topic one bridge reads with a QoS that another bridge's
  publisher does not offer (reliable against best effort, transient_local
  against volatile): they do not connect. A mux subscribes best effort and
  volatile, which matches every publisher, unless its config asks more.

Each problem is said in both configs, each at its own line and column,
naming the other's ``file:line:column``.
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass
from typing import Iterable

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import NOWHERE, Diagnostic, Severity, Span


@dataclass(frozen=True)
class _End:
    """One thing a bridge opens or uses on the robot's graph."""

    file: str
    span: Span
    what: str  # how the message names it: "publishes", "reads", "opens", "serves", "calls"
    type: str | None = None
    qos: ir.QoS | None = None  # a ROS 2 topic's: offered (publishes) or requested (reads)
    type_span: Span | None = None  # where ``type`` is written, when not at ``span``


def _where(end: _End) -> str:
    return f"{os.path.relpath(end.file) if os.path.isabs(end.file) else end.file}:{end.span.line}:{end.span.column}"


def _module_span(document: ast.Document | None) -> Span:
    if document is not None:
        for sec in document.sections:
            if sec.name == "module":
                entry = sec.get("name")
                if entry is not None and entry.items:
                    return entry.items[0].span
    return NOWHERE


def _value_span(document: ast.Document | None, section: str, label: str | None, key: str,
                fallback: Span | None) -> Span:
    """Where the value of ``key`` in ``[section label]`` is written: a
    name's span, without the `(type)` after it; else ``fallback``."""
    sec = document.section(section, label) if document is not None else None
    entry = sec.get(key) if sec is not None else None
    if entry is None or not entry.items:
        return fallback or NOWHERE
    item = entry.items[0]
    return item.func.span if isinstance(item, ast.Call) else item.span


def _norm(name: str | None) -> str | None:
    return None if name is None else name.replace("/msg/", "/").replace("/srv/", "/")


def _ends(path: str, program: ir.Bridge, document: ast.Document | None):
    """(kind, name, end) of everything ``program`` opens or uses."""
    yield "module", program.module, _End(path, _module_span(document), "is named")
    yield from _ENDS[program.kind](path, program, document)


def _commands_ends(path: str, program: ir.Commands, document: ast.Document | None):
    """A config of commands': its services, served and called, and the RPC
    ports it serves."""
    for svc in program.services:
        # the service's name and the port: the values of `serve` and `call`
        ros_key = "serve" if svc.serves == "ros2" else "call"
        span = _value_span(document, "service", svc.name, ros_key, svc.span)
        if svc.serves == "ros2":
            yield "service", svc.service, _End(path, span, "serves", svc.srv_type, type_span=svc.type_span)
        else:
            yield "service_call", svc.service, _End(path, span, "calls", svc.srv_type, type_span=svc.type_span)
    for port in program.served_ports:
        first = program.on_port(port)[0]
        yield "port", port, _End(path, _value_span(document, "service", first.name, "serve", first.span),
                                 "serves")


def _stream_ends(path: str, program: ir.Program, document: ast.Document | None):
    """A stream's: its output (a topic or a port, a camera's info topic), and
    the topics it reads."""
    out = program.output
    span = out.span or NOWHERE
    if out.kind in ("ros1", "ros2"):
        yield f"topic_{out.kind}", out.name, _End(path, out.type_span or span, "publishes", out.msg_type, out.qos)
        if out.camera_info is not None:
            yield "topic_ros2", out.camera_info.topic, _End(path, out.camera_info.span or span, "publishes",
                                                           "sensor_msgs/CameraInfo")
    else:
        yield "port", out.name, _End(path, _value_span(document, "output", None, "port", span), "writes")
    for m in program.muxes:
        for i in m.inputs:
            if i.kind in ("ros1", "ros2") and i.ros_type is not None:
                yield f"topic_{i.kind}", i.name, _End(path, i.span or NOWHERE, "reads", i.ros_type,
                                                      i.subscription_qos if i.kind == "ros2" else None)


def _actions_ends(path: str, program: ir.Actions, document: ast.Document | None):
    """A config of actions': the actions it serves, and the ports it writes set points to."""
    for a in program.actions:
        yield "action", a.action, _End(path, _value_span(document, "action", a.name, "serve", a.span), "serves",
                                       a.action_type, type_span=a.type_span)
        yield "setpoints", a.command, _End(path, _value_span(document, "action", a.name, "command", a.span),
                                           "writes set points to")


#: kind of bridge -> what a bridge of it opens or uses on the robot's graph
_ENDS = {"stream": _stream_ends, "commands": _commands_ends, "actions": _actions_ends}


def qos_mismatch(offered: ir.QoS, requested: ir.QoS) -> tuple[str, str, str] | None:
    """The policy by which a publisher of QoS ``offered`` and a subscription
    of QoS ``requested`` do not match (the rmw rules for the policies a
    config gives), with the publisher's and the subscription's values; None
    when they match."""
    if requested.reliability == "reliable" and offered.reliability == "best_effort":
        return "reliability", "best_effort", "reliable"
    if requested.durability == "transient_local" and offered.durability == "volatile":
        return "durability", "volatile", "transient_local"
    return None


def check_across(results: Iterable) -> list[Diagnostic]:
    """The problems between the programs of ``results`` (pipeline ``Result``s;
    those without a program are left out), sorted as diagnostics are."""
    seen: dict[tuple[str, str], list[_End]] = {}
    for r in results:
        if r.program is None:
            continue
        for kind, name, end in _ends(r.path, r.program, r.document):
            seen.setdefault((kind, name), []).append(end)
    # a service served by one bridge and called by another: its type must agree
    for (kind, name), ends in list(seen.items()):
        if kind == "service_call" and ("service", name) in seen:
            seen[("service", name)] = seen[("service", name)] + ends
    out: list[Diagnostic] = []

    def say(code: str, end: _End, other: _End, message: str, hint: str, severity=Severity.ERROR,
            at_type: bool = False) -> None:
        """``end``'s problem with ``other``, at ``end``'s value (its type's,
        ``at_type``), naming ``other``'s."""
        span, there = end.span, other
        if at_type:
            span = end.type_span or end.span
            there = dataclasses.replace(other, span=other.type_span or other.span)
        out.append(Diagnostic(severity, code, f"{message} ({_where(there)})", span, hint, end.file))

    for (kind, name), ends in seen.items():
        if len(ends) < 2:
            continue
        if kind == "module":
            for a in ends:
                for b in ends:
                    if a is not b and a.file != b.file:
                        say("E362", a, b, f"module `{name}` is also the name of another bridge",
                            "two bridges of one name open the same ports (`/<name>/rpc:i` ...) and the same ROS "
                            "node: give each its own `name` in [module]")
                        break
        elif kind == "port":
            for a in ends:
                other = next((b for b in ends if b is not a and b.file != a.file), None)
                if other is not None:
                    say("E361", a, other, f"the YARP port {name} is opened by another bridge too",
                        "a YARP port is opened once on the network: give one bridge another port")
        elif kind.startswith("topic_"):
            types = {_norm(e.type) for e in ends}
            if len(types) > 1:
                for a in ends:
                    other = next((b for b in ends if _norm(b.type) != _norm(a.type)), None)
                    if other is not None:
                        say("E360", a, other, f"the topic {name}: this bridge {a.what} {a.type}, another "
                                              f"{other.what} {other.type}",
                            "one topic has one message type: subscribers of the other type receive nothing")
            if kind == "topic_ros2":
                for reader in (e for e in ends if e.what == "reads" and e.qos is not None):
                    for writer in (e for e in ends if e.what == "publishes" and e.qos is not None):
                        why = qos_mismatch(writer.qos, reader.qos)
                        if why is None or reader.file == writer.file:
                            continue
                        policy, offered, requested = why
                        hint = (f"they never connect: read it {offered} (the mux's `{policy} = {offered}`), or "
                                f"publish it {requested} (the output's `{policy} = {requested}`)")
                        say("W364", reader, writer, f"the topic {name}: this bridge reads it {requested}, another "
                                                    f"publishes it {offered}", hint, Severity.WARNING)
                        say("W364", writer, reader, f"the topic {name}: this bridge publishes it {offered}, "
                                                    f"another reads it {requested}", hint, Severity.WARNING)
        elif kind == "service":
            servers = [e for e in ends if e.what == "serves"]
            if len(servers) > 1:
                for a in servers:
                    other = next(b for b in servers if b is not a)
                    say("E363", a, other, f"the ROS 2 service {name} is served by another bridge too",
                        "a service has one server: a client's call goes to either")
            types = {_norm(e.type) for e in ends}
            if len(types) > 1:
                for a in ends:
                    other = next((b for b in ends if _norm(b.type) != _norm(a.type)), None)
                    if other is not None:
                        say("E363", a, other, f"the ROS 2 service {name}: this bridge {a.what} it as {a.type}, "
                                              f"another {other.what} it as {other.type}",
                            "one service has one type: a call of the other type is never answered", at_type=True)
        elif kind in ("action", "setpoints"):
            for a in ends:
                other = next((b for b in ends if b is not a and b.file != a.file), None)
                if other is None:
                    continue
                if kind == "action":
                    say("E385", a, other, f"the ROS 2 action {name} is served by another bridge too",
                        "an action has one server: a goal goes to either")
                else:
                    say("E385", a, other, f"another bridge writes set points to {name} too",
                        "one joint, one commander: two writers of set points fight over the joints")
    return sorted(out, key=Diagnostic.sort_key)


__all__ = ["check_across", "qos_mismatch"]
