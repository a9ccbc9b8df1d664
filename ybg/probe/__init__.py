"""``ybgc probe``: a config against the running YARP network and ROS 2
graph it would join, before its module starts (docs/probe.md).

One stage a module: :mod:`plan` (what the module would meet, from the IR),
:mod:`qos` (its QoS after the overrides it would be started with),
:mod:`yarp_graph` and :mod:`ros2_graph` (what the middleware says now; the
only modules that import YARP and rclpy), :mod:`layout` and :mod:`findings`
(what that says of the config: diagnostics at its lines), :mod:`report`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ybg.compiler import ir
from ybg.compiler.diagnostics import Diagnostic, Sink
from ybg.compiler.options import Options

from .findings import ros2_findings, service_findings, yarp_findings
from .plan import Unavailable, plan_of
from .qos import Override, OverrideError, Profile, overridden

DEFAULT_WAIT = 2.0

__all__ = ["DEFAULT_WAIT", "OverrideError", "Settings", "Unavailable", "probe"]


@dataclass(frozen=True)
class Settings:
    """``wait``: seconds for discovery and for a Bottle from each input;
    ``prefix``: the module's port prefix (None: ``/<module>``);
    ``overrides``: the QoS overrides it would be started with."""

    wait: float = DEFAULT_WAIT
    prefix: str | None = None
    overrides: tuple[Override, ...] = ()


def _hashes(program, options: Options, names) -> dict:
    from ybg.compiler.typehash import program_store, type_hash

    store = program_store(program, options)
    out = {}
    for name in names:
        try:
            out[name] = type_hash(store, name) if store is not None else None
        except LookupError:
            out[name] = None
    return out


def _unused_overrides(plans, overrides) -> None:
    """:class:`OverrideError` for an override that names no topic a module overrides."""
    uses = {(t.topic, t.role) for plan in plans for t in plan.topics if t.overridable}
    for o in overrides:
        if (o.topic, o.role) not in uses:
            known = ", ".join(f"{topic} ({role})" for topic, role in sorted(uses)) or "none"
            raise OverrideError(f"qos_overrides.{o.topic}.{o.role}.{o.policy}: no module probed has a {o.role} "
                                f"on {o.topic} that it overrides", f"the topics they override: {known}")


def _profiles(plan, overrides) -> dict:
    return {(t.topic, t.role): overridden(Profile.of(t.qos), t.topic, t.role, overrides if t.overridable else ())
            for t in plan.topics}


def probe(programs: list[tuple[ir.Program | ir.Commands, str]], options: Options,
          settings: Settings) -> dict[str, list[Diagnostic]]:
    """The diagnostics of each ``(program, path)`` against the graph now,
    by path. Their ROS 2 side shares one node and one wait for discovery.
    :class:`Unavailable` when YARP or ROS 2 cannot be asked,
    :class:`OverrideError` for an override the module has no topic for."""
    plans = [(program, path, plan_of(program, settings.prefix)) for program, path in programs]
    _unused_overrides([plan for _, _, plan in plans], settings.overrides)
    profiles = {path: _profiles(plan, settings.overrides) for _, path, plan in plans}
    sinks = {path: Sink(path) for _, path, _ in plans}
    graph = None
    if any(plan.uses_ros2 for _, _, plan in plans):  # discovery runs while YARP is asked
        from .ros2_graph import Graph

        graph = Graph().start()
    try:
        from .yarp_graph import observe

        for _, path, plan in plans:
            yarp_findings(plan, observe(plan, settings.wait), settings.wait, sinks[path])
        for program, path, plan in plans:
            if graph is not None and plan.uses_ros2:
                ros2 = graph.observe(plan, profiles[path], settings.wait)
                hashes = _hashes(program, options, {t.msg_type for t in plan.topics})
                ros2_findings(plan, ros2, hashes, profiles[path], sinks[path])
                service_findings(plan, ros2, sinks[path])
    finally:
        if graph is not None:
            graph.stop()
    return {path: sink.sorted() for path, sink in sinks.items()}
