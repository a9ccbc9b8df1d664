"""What a module would meet when it starts, read from its checked program:
the YARP ports it reads, calls and opens, the ROS 2 topics it publishes and
subscribes to (with the QoS it would ask for), the ROS 2 services it serves
and calls. Pure: no middleware is touched here (``ybgc probe`` looks at the
running graph with :mod:`ybg.probe.yarp_graph` and :mod:`ybg.probe.ros2_graph`).
"""

from __future__ import annotations

from dataclasses import dataclass

from ybg.compiler import ir
from ybg.compiler.diagnostics import Span

#: the bridge's totals, which every module with ROS 2 publishes (docs/runtime.md)
DIAGNOSTICS_TOPIC = "/diagnostics"
DIAGNOSTICS_TYPE = "diagnostic_msgs/DiagnosticArray"
DIAGNOSTICS_QOS = ir.QoS(depth=1)


class Unavailable(RuntimeError):
    """The middleware cannot be asked at all (no name server, no bindings):
    the message, and a hint. Nothing is probed then."""

    def __init__(self, message: str, hint: str):
        super().__init__(message)
        self.hint = hint


@dataclass(frozen=True)
class PortRead:
    """A YARP port the module reads (``layout`` its declared elements, None:
    undeclared, every element a number) or, ``call``, sends commands to."""

    name: str
    what: str
    span: Span | None
    layout: tuple[ir.ElementGroup, ...] | None = None
    image: bool = False
    call: bool = False


@dataclass(frozen=True)
class PortOpen:
    """A YARP port the module opens: it must be free."""

    name: str
    what: str
    span: Span | None


@dataclass(frozen=True)
class TopicUse:
    """A ROS 2 topic the module publishes (``role`` ``"publisher"``) or
    subscribes to (``"subscription"``), of ``msg_type`` (``pkg/Name``), with
    ``qos`` before overrides; ``overridable``: the module honours
    ``qos_overrides./<topic>.<role>.<policy>`` on it."""

    topic: str
    msg_type: str
    role: str
    qos: ir.QoS
    span: Span | None
    type_span: Span | None
    overridable: bool = True


@dataclass(frozen=True)
class ServiceUse:
    """A ROS 2 service the module serves (``role`` ``"server"``) or calls
    (``"client"``), of ``srv_type`` (``pkg/Name``); with ``action``, the
    goal service of the ROS 2 action of that name the module serves
    (``<action>/_action/send_goal``, of ``pkg/action/Name_SendGoal``:
    ``srv_type`` is the action's type)."""

    name: str
    srv_type: str
    role: str
    span: Span | None
    type_span: Span | None
    action: str | None = None


@dataclass(frozen=True)
class Plan:
    reads: tuple[PortRead, ...] = ()
    opens: tuple[PortOpen, ...] = ()
    topics: tuple[TopicUse, ...] = ()
    services: tuple[ServiceUse, ...] = ()

    @property
    def uses_ros2(self) -> bool:
        return bool(self.topics or self.services)


def plan_of(program: ir.Bridge, prefix: str | None = None) -> Plan:
    """What ``program`` would meet; ``prefix``: its ports' prefix (the
    module's ``--prefix``/``--name``; default ``/<module>``)."""
    return _PLANS[program.kind](program, prefix or "/" + program.module)


def _stream(program: ir.Program, prefix: str) -> Plan:
    reads, topics = [], []
    opens = [PortOpen(f"{prefix}/rpc:i", "the module's RPC port", program.span)]
    for mux in program.muxes:
        for k, inp in enumerate(mux.inputs):
            what = f"input {k} of mux `{mux.name}`"
            if inp.kind == "yarp":
                reads.append(PortRead(inp.name, what, inp.span or mux.span, inp.layout, image=inp.image is not None))
                opens.append(PortOpen(f"{prefix}/{mux.name}/in{k}:i", f"the port of {what}", inp.span or mux.span))
            elif inp.kind == "ros2" and inp.ros_type:
                topics.append(TopicUse(inp.name, inp.ros_type, "subscription", inp.subscription_qos, inp.span or mux.span,
                                       inp.span or mux.span))
    out = program.output
    if out.kind == "yarp":
        opens.insert(0, PortOpen(out.name, "the output port", out.span))
    elif out.kind == "ros2" and out.msg_type:
        qos = out.qos or ir.QoS()
        topics.append(TopicUse(out.name, out.msg_type, "publisher", qos, out.span, out.type_span or out.span))
        if out.camera_info is not None:
            topics.append(TopicUse(out.camera_info.topic, "sensor_msgs/CameraInfo", "publisher", qos,
                                   out.camera_info.span or out.span, out.camera_info.span or out.span))
    if topics:
        topics.append(TopicUse(DIAGNOSTICS_TOPIC, DIAGNOSTICS_TYPE, "publisher", DIAGNOSTICS_QOS, out.span,
                               out.span, overridable=False))
    return Plan(tuple(reads), tuple(opens), tuple(topics))


def _commands(program: ir.Commands, prefix: str) -> Plan:
    reads, services = [], []
    opens = [PortOpen(f"{prefix}/rpc:i", "the module's RPC port", program.span)]
    for port in program.served_ports:
        first = program.on_port(port)[0]
        if port == opens[0].name:  # its own RPC port answers the commands too
            opens[0] = PortOpen(port, "the RPC port the module serves", first.span)
        else:
            opens.append(PortOpen(port, "the RPC port the module serves", first.span))
    for s in program.services:
        if s.serves == "ros2":
            services.append(ServiceUse(s.service, s.srv_type, "server", s.span, s.type_span or s.span))
            if all(r.name != s.port for r in reads):
                reads.append(PortRead(s.port, f"the RPC port command `{s.name}` calls", s.span, call=True))
        else:
            services.append(ServiceUse(s.service, s.srv_type, "client", s.span, s.type_span or s.span))
    return Plan(tuple(reads), tuple(opens), (), tuple(services))


def _actions(program: ir.Actions, prefix: str) -> Plan:
    reads, services = [], []
    opens = [PortOpen(f"{prefix}/rpc:i", "the module's RPC port", program.span)]
    for a in program.actions:
        reads.append(PortRead(a.state, f"the encoders of action `{a.name}`", a.span, a.layout))
        reads.append(PortRead(a.command, f"the port action `{a.name}` writes set points to", a.span, call=True))
        opens.append(PortOpen(f"{prefix}/{a.name}/state:i", f"the port of action `{a.name}`'s encoders", a.span))
        opens.append(PortOpen(f"{prefix}/{a.name}/command:o", f"the port of action `{a.name}`'s set points", a.span))
        services.append(ServiceUse(f"{a.action}/_action/send_goal", a.action_type, "server", a.span,
                                   a.type_span or a.span, action=a.action))
    return Plan(tuple(reads), tuple(opens), (), tuple(services))


#: kind of bridge -> what a bridge of it would meet
_PLANS = {"stream": _stream, "commands": _commands, "actions": _actions}
