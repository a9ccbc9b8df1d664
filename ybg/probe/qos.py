"""The QoS a module would ask for on each topic, after the overrides it
would be started with: ``qos_overrides./<topic>.publisher.<policy>``
(``.subscription.`` for the topics it reads), the parameters the module
honours (docs/runtime.md; history, depth, reliability and durability), given
to ``ybgc probe`` as to the module: ``-p qos_overrides./joint_states.publisher.reliability:=best_effort``.
Pure: rclpy makes a profile of it in :mod:`ybg.probe.ros2_graph`."""

from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass

from ybg.compiler import ir

#: policy -> the values it takes (None: a positive integer)
POLICIES: dict[str, tuple[str, ...] | None] = {
    "history": ("keep_last", "keep_all"),
    "depth": None,
    "reliability": ("reliable", "best_effort"),
    "durability": ("volatile", "transient_local"),
}
_OVERRIDE = re.compile(r"qos_overrides\.(?P<topic>/.*)\.(?P<role>publisher|subscription)\.(?P<policy>[a-z_]+)$")


class OverrideError(ValueError):
    """A parameter that cannot be an override of this module: the message,
    and a hint."""

    def __init__(self, message: str, hint: str):
        super().__init__(message)
        self.hint = hint


@dataclass(frozen=True)
class Profile:
    """The policies a module sets; the others (deadline, liveliness, its
    lease, lifespan) are rmw's defaults: infinite, automatic."""

    reliability: str = "reliable"
    durability: str = "volatile"
    depth: int = 10
    history: str = "keep_last"

    @staticmethod
    def of(qos: ir.QoS) -> "Profile":
        return Profile(qos.reliability, qos.durability, qos.depth)


@dataclass(frozen=True)
class Override:
    topic: str
    role: str
    policy: str
    value: str | int


def parse_parameter(text: str) -> Override | None:
    """``NAME:=VALUE`` (as ``--ros-args -p`` takes it) as an override, or
    None for a parameter that is no QoS override (the module's others: rate,
    prefix ...); :class:`OverrideError` for a malformed one."""
    name, sep, value = text.partition(":=")
    if not sep:
        raise OverrideError(f"-p {text}: not NAME:=VALUE",
                            "write it as the module takes it: -p qos_overrides./TOPIC.publisher.POLICY:=VALUE")
    if not name.startswith("qos_overrides."):
        return None
    m = _OVERRIDE.match(name)
    if m is None:
        raise OverrideError(f"-p {text}: not qos_overrides./TOPIC.publisher.POLICY "
                            "(or .subscription. for a topic the module reads)",
                            "e.g. -p qos_overrides./joint_states.publisher.reliability:=best_effort")
    policy = m["policy"]
    if policy not in POLICIES:
        raise OverrideError(f"-p {text}: the module does not override `{policy}`",
                            f"it overrides {', '.join(POLICIES)}; deadline, liveliness and lifespan are rmw's "
                            "defaults (infinite, automatic)")
    choices = POLICIES[policy]
    value = value.strip().strip("'\"")
    if choices is None:
        if not value.isdigit() or int(value) < 1:
            raise OverrideError(f"-p {text}: {policy} is a positive integer", f"e.g. {name}:=10")
        return Override(m["topic"], m["role"], policy, int(value))
    if value.lower() not in choices:
        raise OverrideError(f"-p {text}: {policy} is {' or '.join(choices)}", f"e.g. {name}:={choices[-1]}")
    return Override(m["topic"], m["role"], policy, value.lower())


def overridden(profile: Profile, topic: str, role: str, overrides) -> Profile:
    """``profile`` of ``topic`` (``role``) with the overrides that name it."""
    changes = {o.policy: o.value for o in overrides if o.topic == topic and o.role == role}
    return dataclasses.replace(profile, **changes)
