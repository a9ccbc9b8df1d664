"""A config of actions' checked program (:class:`Actions`): ROS 2 action
servers carried out on a YARP robot's ports (docs/actions.md). The first
kind: a FollowJointTrajectory served from a part's encoder port, its set
points written to a port of the robot (:class:`TrajectoryAction`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar

from ybg.compiler.diagnostics import Span
from ybg.compiler.ir.streams import Converter, ElementGroup

#: the action types a [action] section serves as a trajectory
TRAJECTORY_TYPES = ("control_msgs/FollowJointTrajectory",)
#: set points a second, feedback messages a second, and the seconds without
#: an encoder Bottle that abort a goal, when the config gives none
TRAJECTORY_RATE = 100.0
FEEDBACK_RATE = 20.0
STALE_AFTER = 0.25


@dataclass(frozen=True)
class TrajectoryAction:
    """A FollowJointTrajectory served as ``action`` (a ROS 2 action name) of
    type ``action_type``, for the joints ``joints`` (the bridge's order).

    The encoders are the first ``len(joints)`` elements of each Bottle of the
    YARP port ``state`` (declared by ``layout``; None: not declared, checked
    when each Bottle comes), converted to the goal's units (radians, metres)
    by ``converters``; the set points, converted back by their inverses, are
    written ``rate`` times a second as a Bottle of one float64 a joint to the
    YARP port ``command``. Feedback goes out ``feedback_rate`` times a second.
    ``path_tolerance`` and ``goal_tolerance`` (radians, every joint; None: not
    checked) and ``goal_time_tolerance`` (seconds) hold where a goal gives
    none; encoders older than ``stale`` seconds abort the goal.
    """

    name: str
    action: str
    action_type: str
    joints: tuple[str, ...]
    state: str
    command: str
    layout: tuple[ElementGroup, ...] | None = None
    converters: tuple[Converter, ...] = ()
    rate: float = TRAJECTORY_RATE
    feedback_rate: float = FEEDBACK_RATE
    path_tolerance: float | None = None
    goal_tolerance: float | None = None
    goal_time_tolerance: float = 0.0
    stale: float = STALE_AFTER
    span: Span | None = field(default=None, compare=False, repr=False)
    type_span: Span | None = field(default=None, compare=False, repr=False)

    @property
    def width(self) -> int | None:
        """The elements each state Bottle is declared to hold; None: not declared."""
        return None if self.layout is None else sum(g.count for g in self.layout)


@dataclass(frozen=True)
class Actions:
    """A checked config of actions, ready for any backend."""

    #: its kind of bridge (ybg.compiler.ir.BRIDGE_KINDS)
    kind: ClassVar[str] = "actions"

    module: str
    source: str
    actions: tuple[TrajectoryAction, ...]
    distro: str | None = None
    ros: str = "ros2"

    @property
    def span(self) -> Span | None:
        """Where the config writes the bridge: its first action."""
        return self.actions[0].span if self.actions else None


__all__ = ["TRAJECTORY_TYPES", "TRAJECTORY_RATE", "FEEDBACK_RATE", "STALE_AFTER", "TrajectoryAction", "Actions"]
