"""What the graph seen says of the module: the diagnostics of ``ybgc probe``
(codes E370-E376, W570-W572 of docs/diagnostics.md), each at the line of
the config that the problem is about. Pure: the graph comes in as data
(:class:`~ybg.probe.yarp_graph.YarpSeen`, :class:`~ybg.probe.ros2_graph.Ros2Seen`)."""

from __future__ import annotations

from ybg.compiler.diagnostics import Sink
from ybg.compiler.typehash import ros2_name

from .layout import NUMBERS, declared, mismatch, seen
from .plan import Plan, TopicUse
from .qos import Profile


def yarp_findings(plan: Plan, yarp, wait: float, sink: Sink) -> None:
    for r in plan.reads:
        if not yarp.answers.get(r.name):
            sink.error("E370", f"{r.what}: the YARP port {r.name} does not answer", r.span,
                       "start what opens it before this module (yarp name list shows the ports the name server "
                       "knows), or correct the name in the config")
            continue
        if r.call or r.image:
            continue
        elements = yarp.bottles.get(r.name)
        if r.name in yarp.refused:
            sink.warning("W570", f"{r.what}: {r.name} answers, and took no connection to the probe's port: "
                         "its layout is not checked", r.span,
                         "is it an output port? A module reads a port that writes (yarp name list; "
                         f"yarp read ... {r.name} shows what it sends)")
            continue
        if elements is None:
            sink.warning("W570", f"{r.what}: {r.name} sent no Bottle within {wait:g} s: its layout is not checked",
                         r.span, "a port that sends only when something happens sends nothing now; probe again "
                         "with a longer --wait while it sends")
            continue
        why = mismatch(r.layout, elements)
        if why is not None:
            sink.error("E371", f"{r.what}: {r.name} sends {seen(elements)}; the config declares "
                       f"{declared(r.layout)}: {why}", r.span, _declare_hint(r.name, elements))
        else:
            sink.note("N670", f"{r.what}: {r.name} sends {seen(elements)}, which fits {declared(r.layout)}", r.span)
    for o in plan.opens:
        if yarp.answers.get(o.name):
            sink.error("E372", f"{o.what} {o.name} is open already: another process holds it, or this module "
                       "runs already", o.span,
                       "stop what holds it, or start the module under another name (--prefix) "
                       "and probe with that --prefix")


def _declare_hint(port: str, elements: list) -> str:
    kinds = {k for k, _ in elements}
    if elements and kinds <= set(NUMBERS) | {"string"}:
        groups = seen(elements).split(": ", 1)[1]
        return f"if the port is right, declare what it sends: `{port} ({groups})`; else correct the port's name"
    return ("the Bottle holds what a mux cannot take (nested lists, vocabs, blobs): read the port the config "
            f"means, or declare {port} without its elements to take numbers only")


def _text(p: Profile) -> str:
    return f"{p.reliability}, {p.durability}, {p.history} {p.depth}" if p.history == "keep_last" \
        else f"{p.reliability}, {p.durability}, keep_all"


def ros2_findings(plan: Plan, ros2, hashes: dict, profiles: dict, sink: Sink) -> None:
    """``hashes``: ``pkg/Name`` -> ybgc's RIHS01 hash of it (None: none);
    ``profiles``: (topic, role) -> the module's QoS after overrides."""
    for use in plan.topics:
        want = ros2_name(use.msg_type)
        endpoints = ros2.endpoints.get(use.topic, [])
        sink.note("N670", f"the topic {use.topic} (the module's {use.role}, {_text(profiles[(use.topic, use.role)])}): "
                  + ("; ".join(f"{ep.node}'s {ep.kind} of {ep.type} ({ep.qos})" for ep in endpoints)
                     or "no endpoint yet"), use.span)
        for ep in endpoints:
            who = f"the topic {use.topic}: {ep.node}'s {ep.kind}"
            if ep.type != want:
                sink.error("E373", f"{who} has the type {ep.type}, the module's {use.role} {want}", use.type_span,
                           "the two never match: correct the type in the config, or the topic's name")
                continue
            mine = hashes.get(use.msg_type)
            if ep.type_hash and mine and ep.type_hash != mine:
                sink.error("E374", f"{who} has {ep.type} of type hash {ep.type_hash}; ybgc's definition of it "
                           f"hashes to {mine}", use.type_span,
                           f"two builds of {use.msg_type} with different definitions: the peer was built from "
                           "another .msg than the one ybgc reads; rebuild one of the two from the other's, or "
                           "give ybgc the robot's with --msg-path (or AMENT_PREFIX_PATH)")
                continue
            if ep.compatible in ("error", "warning"):
                _qos(use, ep, profiles[(use.topic, use.role)], sink)


#: (the module's role, policy, its value, the peer's) that rmw refuses -> what the module's must be
_REFUSED = {
    ("publisher", "reliability", "best_effort", "reliable"): "reliable",
    ("publisher", "durability", "volatile", "transient_local"): "transient_local",
    ("subscription", "reliability", "reliable", "best_effort"): "best_effort",
    ("subscription", "durability", "transient_local", "volatile"): "volatile",
}


def _overrides(use: TopicUse, ep, mine: Profile) -> list[str]:
    """The overrides that make the module's side of ``use`` match ``ep``
    in reliability and durability (the policies it sets)."""
    out = []
    for policy in ("reliability", "durability"):
        value = _REFUSED.get((use.role, policy, getattr(mine, policy), getattr(ep, policy)))
        if value is not None:
            out.append(f"-p qos_overrides.{use.topic}.{use.role}.{policy}:={value}")
    return out


def _qos(use: TopicUse, ep, mine: Profile, sink: Sink) -> None:
    message = (f"the topic {use.topic}: {ep.node}'s {ep.kind} ({ep.qos}) and the module's {use.role} "
               f"({_text(mine)}): {ep.reason or 'rmw cannot tell'}")
    if ep.compatible == "warning":
        sink.warning("W571", message, use.span, "a policy of one side is the system default or unknown: "
                     "set it explicitly on that side to know")
        return
    fixes = _overrides(use, ep, mine) if use.overridable else []
    if not fixes:  # deadline, liveliness: the module leaves them to rmw's defaults
        hint = (f"{ep.node} asks for what the module does not offer (it sets no deadline, liveliness or "
                "lifespan): change that peer's QoS")
    else:
        hint = f"start the module with {' '.join(fixes)}, and probe with the same"
        if use.role == "publisher":
            settings = [f.split(".")[-1].replace(":=", " = ") for f in fixes]
            hint += f"; or set {' and '.join(f'`{x}`' for x in settings)} in the config's [output]"
        hint += f"; or change {ep.node}'s QoS"
    sink.error("E375", message, use.span, hint)


def service_findings(plan: Plan, ros2, sink: Sink) -> None:
    for use in plan.services:
        pkg, _, name = use.srv_type.partition("/")
        # an action is served as services: its goal service tells its server and type
        want = f"{pkg}/action/{name}_SendGoal" if use.action else f"{pkg}/srv/{name}"
        what = f"the ROS 2 action {use.action}" if use.action else f"the ROS 2 service {use.name}"
        for other in [t for t in ros2.service_types.get(use.name, []) if t != want]:
            if use.action:
                other = other.replace("/action/", "/", 1).removesuffix("_SendGoal")
            sink.error("E373", f"{what} has the type {other} in the graph, the module's "
                       f"{use.role} {use.srv_type if use.action else want}", use.type_span,
                       f"the two never match: correct the {'action' if use.action else 'service'} type in the "
                       f"config, or the {'action' if use.action else 'service'}'s name")
        servers = ros2.servers.get(use.name, 0)
        if use.role == "server" and servers:
            sink.error("E376", f"{what} has {servers} server{'s' if servers > 1 else ''} "
                       f"already: a {'goal' if use.action else 'call'} would reach either", use.span,
                       f"stop the other server (ros2 {'action' if use.action else 'service'} info shows it"
                       f"{'' if use.action else ' on Jazzy and later'}), or serve another name")
        elif use.role == "client" and not servers:
            sink.warning("W572", f"the ROS 2 service {use.name} the module calls has no server now: its calls "
                         "fail until one comes", use.span, "start the server before the module")
