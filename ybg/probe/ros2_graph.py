"""The ROS 2 side of ``ybgc probe``: a node of its own joins the domain,
waits for discovery a bounded time, and reads the graph: every endpoint of
the topics the module would use (its node, type name, type hash and QoS,
and whether that QoS matches the module's by rmw's rules), and the servers
and types of its services. Imports rclpy, which is slow to load: only
``ybgc probe`` loads this module, and only for a module with ROS 2."""

from __future__ import annotations

import os
import time
from dataclasses import dataclass, field

from .plan import Plan, Unavailable
from .qos import Profile


@dataclass(frozen=True)
class Endpoint:
    """One publisher or subscription already on a topic. ``compatible``
    (an endpoint the module would match with: a subscription of what it
    publishes, a publisher of what it reads): ``"ok"``, ``"warning"`` or
    ``"error"`` by rmw's rules, and rmw's reason."""

    node: str
    kind: str
    type: str
    type_hash: str | None
    qos: str
    compatible: str | None = None
    reason: str = ""
    reliability: str = ""
    durability: str = ""


@dataclass
class Ros2Seen:
    """``endpoints``: topic -> its endpoints; ``service_types``: service ->
    the types its servers and clients have; ``servers``: service -> how many."""

    endpoints: dict[str, list[Endpoint]] = field(default_factory=dict)
    service_types: dict[str, list[str]] = field(default_factory=dict)
    servers: dict[str, int] = field(default_factory=dict)


def _describe(q) -> str:
    def name(policy) -> str:
        return policy.name.lower()

    parts = [name(q.reliability), name(q.durability)]
    for label, duration in (("deadline", q.deadline), ("lifespan", q.lifespan)):
        if duration.nanoseconds not in (0, 0x7FFFFFFFFFFFFFFF):
            parts.append(f"{label} {duration.nanoseconds / 1e9:g} s")
    parts.append(f"liveliness {name(q.liveliness)}")
    if q.liveliness_lease_duration.nanoseconds not in (0, 0x7FFFFFFFFFFFFFFF):
        parts.append(f"lease {q.liveliness_lease_duration.nanoseconds / 1e9:g} s")
    return ", ".join(parts)


def _hash(info) -> str | None:
    """The endpoint's RIHS01 type hash; None when it gives none (a distro
    before Iron gives zeros)."""
    text = str(getattr(info, "topic_type_hash", "") or "")
    digits = text[len("RIHS01_"):] if text.startswith("RIHS01_") else ""
    return text if digits.strip("0") else None


class Graph:
    """A node of the probe's own in the domain of the environment
    (ROS_DOMAIN_ID ...): discovery runs from :meth:`start` on."""

    def start(self) -> "Graph":
        try:
            import rclpy
        except ImportError as e:
            raise Unavailable(f"rclpy cannot be imported: {e}",
                              "install ROS 2's rclpy (scripts/setup.sh installs its wheels), or source a "
                              "ROS 2 install, in the environment that runs ybgc") from e
        self._rclpy = rclpy
        self.context = rclpy.Context()
        try:
            rclpy.init(args=[], context=self.context)
            self.node = rclpy.create_node(f"ybgc_probe_{os.getpid()}", context=self.context,
                                          start_parameter_services=False, enable_rosout=False)
        except Exception as e:  # an rmw that cannot start: a bad ROS_DOMAIN_ID, RMW_IMPLEMENTATION ...
            if self.context.ok():
                rclpy.shutdown(context=self.context)
            raise Unavailable(f"ROS 2 cannot join the graph: {e}",
                              "check ROS_DOMAIN_ID, RMW_IMPLEMENTATION and ROS_AUTOMATIC_DISCOVERY_RANGE, "
                              "as the module would be started with") from e
        self.started = time.monotonic()
        return self

    def stop(self) -> None:
        self.node.destroy_node()
        self._rclpy.shutdown(context=self.context)

    def observe(self, plan: Plan, profiles: dict, wait: float) -> Ros2Seen:
        """The graph once ``wait`` seconds have passed since :meth:`start`;
        ``profiles``: (topic, role) -> the module's :class:`Profile` there."""
        time.sleep(max(0.0, self.started + wait - time.monotonic()))
        seen = Ros2Seen()
        for use in plan.topics:
            mine = _profile(profiles[(use.topic, use.role)])
            found = []
            for kind, infos in (("publisher", self.node.get_publishers_info_by_topic(use.topic)),
                                ("subscription", self.node.get_subscriptions_info_by_topic(use.topic))):
                for info in infos:
                    level, reason = None, ""
                    if kind != use.role:
                        pub, sub = (mine, info.qos_profile) if use.role == "publisher" else (info.qos_profile, mine)
                        level, reason = _compatible(pub, sub)
                    q = info.qos_profile
                    found.append(Endpoint(f"{info.node_namespace.rstrip('/')}/{info.node_name}", kind,
                                          info.topic_type, _hash(info), _describe(q), level, reason,
                                          q.reliability.name.lower(), q.durability.name.lower()))
            seen.endpoints[use.topic] = found
        if plan.services:
            types = dict(self.node.get_service_names_and_types())
            for use in plan.services:
                seen.service_types[use.name] = list(types.get(use.name, []))
                seen.servers[use.name] = self.node.count_services(use.name)
        return seen


def _profile(p: Profile):
    """The module's QoS as the graph shows its endpoint: the policies it
    leaves to the system default are what rmw makes of them (deadline,
    lifespan and liveliness lease infinite, liveliness automatic)."""
    from rclpy.duration import Infinite
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, LivelinessPolicy, QoSProfile, ReliabilityPolicy

    return QoSProfile(history=HistoryPolicy[p.history.upper()], depth=p.depth,
                      reliability=ReliabilityPolicy[p.reliability.upper()],
                      durability=DurabilityPolicy[p.durability.upper()],
                      deadline=Infinite, lifespan=Infinite, liveliness=LivelinessPolicy.AUTOMATIC,
                      liveliness_lease_duration=Infinite)


def _compatible(pub, sub) -> tuple[str, str]:
    """rmw's verdict on a publisher's and a subscription's QoS
    (``rmw_qos_profile_check_compatible``, through rclpy)."""
    from rclpy.qos import QoSCompatibility, qos_check_compatible

    level, reason = qos_check_compatible(pub, sub)
    # rmw's reasons: "ERROR: Best effort publisher and reliable subscription;ERROR: ...;"
    reasons = [r.strip().removeprefix("ERROR:").removeprefix("WARNING:").strip() for r in reason.split(";")]
    verdict = {QoSCompatibility.OK: "ok", QoSCompatibility.WARNING: "warning"}.get(level, "error")
    return verdict, "; ".join(r for r in reasons if r)
