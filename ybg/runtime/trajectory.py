"""A joint trajectory goal, with no middleware: checked against the joints a
bridge drives, sampled at the bridge's command rate, and watched against its
tolerances, as control_msgs' FollowJointTrajectory describes them and
ros2_controllers' joint_trajectory_controller carries them out
(docs/actions.md).

Everything here is in the goal's units (radians, rad/s, seconds): the bridge
converts the robot's encoders before and its set points after. Times are
seconds on the bridge's clock. The shell that serves the action (ROS 2
through rclpy or rcl_action) turns the goal message into plain lists, and
these functions' answers into set points, feedback and the result.

- :func:`accept` checks a goal and makes its :class:`Trajectory`, or gives a
  :class:`Refusal` with control_msgs' code and why (nothing of a refused goal
  reaches the robot);
- :meth:`Trajectory.sample` gives the desired positions, velocities and
  accelerations of every joint of the bridge at a time: from where the
  joints were when the goal started to the first point, then point to point
  (quintic where both points give velocities and accelerations, cubic where
  they give velocities, linear otherwise), and the last point held after;
  a joint the goal does not name holds where it was;
- :meth:`Trajectory.verdict` compares the encoders with the samples: a path
  tolerance exceeded while it runs, the goal reached within its tolerance
  once it has ended, or not within ``goal_time_tolerance`` after.
"""

import math

SUCCESSFUL = 0
INVALID_GOAL = -1
INVALID_JOINTS = -2
OLD_HEADER_TIMESTAMP = -3
PATH_TOLERANCE_VIOLATED = -4
GOAL_TOLERANCE_VIOLATED = -5

#: control_msgs' name of each code, for logs and error strings
CODE_NAMES = {SUCCESSFUL: "SUCCESSFUL", INVALID_GOAL: "INVALID_GOAL", INVALID_JOINTS: "INVALID_JOINTS",
              OLD_HEADER_TIMESTAMP: "OLD_HEADER_TIMESTAMP", PATH_TOLERANCE_VIOLATED: "PATH_TOLERANCE_VIOLATED",
              GOAL_TOLERANCE_VIOLATED: "GOAL_TOLERANCE_VIOLATED"}

_KINDS = ("position", "velocity", "acceleration")


class Refusal:
    """A goal not carried out: control_msgs' ``code`` and the ``text`` of its
    ``error_string``."""

    __slots__ = ("code", "text")

    def __init__(self, code, text):
        self.code = code
        self.text = text

    def __repr__(self):
        return "Refusal(%s, %r)" % (CODE_NAMES.get(self.code, self.code), self.text)


class Tolerance:
    """The largest error allowed of one joint's position, velocity and
    acceleration; ``None``: not checked."""

    __slots__ = _KINDS

    def __init__(self, position=None, velocity=None, acceleration=None):
        self.position = position
        self.velocity = velocity
        self.acceleration = acceleration

    def merged(self, given):
        """This default with a goal's JointTolerance values ``given``
        ``(position, velocity, acceleration)``: 0 keeps the default, -1 erases
        it (not checked), a positive value replaces it."""
        out = []
        for kind, value in zip(_KINDS, given):
            if value == 0:
                out.append(getattr(self, kind))
            elif value == -1:
                out.append(None)
            else:
                out.append(float(value))
        return Tolerance(*out)

    def __eq__(self, other):
        return isinstance(other, Tolerance) and all(getattr(self, k) == getattr(other, k) for k in _KINDS)

    def __repr__(self):
        return "Tolerance(%r, %r, %r)" % (self.position, self.velocity, self.acceleration)


class Point:
    """One point of a goal, in the bridge's joint order's subset the goal
    names: ``time`` from the trajectory's start; ``velocities`` and
    ``accelerations`` empty when the goal gives none."""

    __slots__ = ("time", "positions", "velocities", "accelerations")

    def __init__(self, time, positions, velocities=(), accelerations=()):
        self.time = time
        self.positions = list(positions)
        self.velocities = list(velocities)
        self.accelerations = list(accelerations)


def _all_finite(values):
    return all(isinstance(v, (int, float)) and math.isfinite(v) for v in values)


def accept(joints, names, points, actual, now, stamp=0.0, path_tolerance=(), goal_tolerance=(),
           goal_time_tolerance=0.0, defaults=None):
    """The :class:`Trajectory` of a goal, or its :class:`Refusal`.

    ``joints``: the names of the joints the bridge drives, in its order;
    ``names``: the goal's joint names (any subset, any order); ``points``:
    :class:`Point` in the goal's joint order; ``actual``: the joints' positions
    now (the bridge's order); ``stamp``: the goal header's time (0: start
    now); ``path_tolerance``, ``goal_tolerance``: ``(name, position,
    velocity, acceleration)`` of the goal; ``defaults``: the bridge's
    :class:`Defaults`."""
    defaults = defaults or Defaults(len(joints))
    index = {name: k for k, name in enumerate(joints)}
    if not names:
        return Refusal(INVALID_JOINTS, "the goal names no joint; this controller drives %s" % ", ".join(joints))
    unknown = [n for n in names if n not in index]
    if unknown:
        return Refusal(INVALID_JOINTS, "joint%s %s not driven by this controller, which drives %s" % (
            "s" if len(unknown) > 1 else "", ", ".join(repr(n) for n in unknown), ", ".join(joints)))
    twice = sorted({n for n in names if list(names).count(n) > 1})
    if twice:
        return Refusal(INVALID_JOINTS, "joint%s %s named twice" % ("s" if len(twice) > 1 else "",
                                                                  ", ".join(repr(n) for n in twice)))
    if not points:
        return Refusal(INVALID_GOAL, "the trajectory has no point")
    n = len(names)
    last = -1.0
    for k, p in enumerate(points):
        if len(p.positions) != n:
            return Refusal(INVALID_GOAL, "point %d has %d positions for %d joints" % (k, len(p.positions), n))
        for what in ("velocities", "accelerations"):
            got = len(getattr(p, what))
            if got not in (0, n):
                return Refusal(INVALID_GOAL, "point %d has %d %s for %d joints" % (k, got, what, n))
        if p.accelerations and not p.velocities:
            return Refusal(INVALID_GOAL, "point %d has accelerations but no velocities" % k)
        if not _all_finite([p.time] + p.positions + p.velocities + p.accelerations):
            return Refusal(INVALID_GOAL, "point %d has a value that is not a finite number" % k)
        if p.time <= last or p.time < 0:
            return Refusal(INVALID_GOAL, "point %d's time_from_start %.9g s is not after point %d's %.9g s" % (
                k, p.time, k - 1, last) if k else "point 0's time_from_start %.9g s is negative" % p.time)
        last = p.time
    for what, given in (("path_tolerance", path_tolerance), ("goal_tolerance", goal_tolerance)):
        for name, *values in given:
            if name not in index:
                return Refusal(INVALID_JOINTS, "%s names joint %r, not driven by this controller" % (what, name))
            if not _all_finite(values) or any(v < 0 and v != -1 for v in values):
                return Refusal(INVALID_GOAL, "%s of %r: %s (a tolerance is 0 for the default, -1 for none, "
                                             "or positive)" % (what, name, ", ".join("%g" % v for v in values)))
    if not math.isfinite(goal_time_tolerance) or goal_time_tolerance < 0:
        return Refusal(INVALID_GOAL, "goal_time_tolerance %g s is negative" % goal_time_tolerance)
    start = now if stamp == 0 else stamp
    if start + last < now:
        return Refusal(OLD_HEADER_TIMESTAMP, "the trajectory ended %.3f s ago (its header's stamp is %.3f s "
                                             "before now, its last point %.3f s after the stamp)" % (
                                                 now - start - last, now - start, last))
    path = list(defaults.path)
    goal = list(defaults.goal)
    for tolerances, given in ((path, path_tolerance), (goal, goal_tolerance)):
        for name, *values in given:
            tolerances[index[name]] = tolerances[index[name]].merged(values)
    return Trajectory(joints, [index[name] for name in names], points, list(actual), start, path, goal,
                      goal_time_tolerance or defaults.goal_time)


class Defaults:
    """A bridge's tolerances where a goal gives none: ``path`` and ``goal``,
    a :class:`Tolerance` per joint; ``goal_time``, seconds."""

    def __init__(self, n, path=None, goal=None, goal_time=0.0):
        self.path = list(path) if path is not None else [Tolerance() for _ in range(n)]
        self.goal = list(goal) if goal is not None else [Tolerance() for _ in range(n)]
        self.goal_time = goal_time


def _segment(t, span, p0, v0, a0, p1, v1, a1, degree):
    """Position, velocity and acceleration at ``t`` in [0, span] of the
    polynomial of ``degree`` (1, 3, 5) from (p0, v0, a0) to (p1, v1, a1)."""
    if span <= 0:
        return p1, v1, a1
    if degree == 1:
        v = (p1 - p0) / span
        return p0 + v * t, v, 0.0
    if degree == 3:
        c2 = (3 * (p1 - p0) - (2 * v0 + v1) * span) / span ** 2
        c3 = (2 * (p0 - p1) + (v0 + v1) * span) / span ** 3
        return (p0 + v0 * t + c2 * t ** 2 + c3 * t ** 3, v0 + 2 * c2 * t + 3 * c3 * t ** 2, 2 * c2 + 6 * c3 * t)
    T = span
    d = p1 - p0
    c3 = (20 * d - (8 * v1 + 12 * v0) * T - (3 * a0 - a1) * T ** 2) / (2 * T ** 3)
    c4 = (-30 * d + (14 * v1 + 16 * v0) * T + (3 * a0 - 2 * a1) * T ** 2) / (2 * T ** 4)
    c5 = (12 * d - 6 * (v1 + v0) * T - (a0 - a1) * T ** 2) / (2 * T ** 5)
    c2 = a0 / 2
    return (p0 + v0 * t + c2 * t ** 2 + c3 * t ** 3 + c4 * t ** 4 + c5 * t ** 5,
            v0 + 2 * c2 * t + 3 * c3 * t ** 2 + 4 * c4 * t ** 3 + 5 * c5 * t ** 4,
            2 * c2 + 6 * c3 * t + 12 * c4 * t ** 2 + 20 * c5 * t ** 3)


class Trajectory:
    """An accepted goal (made by :func:`accept`)."""

    def __init__(self, joints, order, points, hold, start, path, goal, goal_time):
        self.joints = list(joints)
        self.order = order              # the bridge's index of each of the goal's joints
        self.points = points
        self.hold = hold                # where every joint was when the goal came
        self.start = start
        self.end = start + points[-1].time
        self.path = path
        self.goal = goal
        self.goal_time = goal_time

    def index_at(self, t):
        """The index of the point the trajectory heads for at ``t`` (the
        last one once it has ended)."""
        rel = t - self.start
        for k, p in enumerate(self.points):
            if rel < p.time:
                return k
        return len(self.points) - 1

    def sample(self, t):
        """``(positions, velocities, accelerations)`` of every joint of the
        bridge at time ``t``."""
        pos = list(self.hold)
        vel = [0.0] * len(pos)
        acc = [0.0] * len(pos)
        rel = t - self.start
        k = self.index_at(t)
        after = self.points[k]
        if rel >= after.time:  # ended: the last point, at rest where it gives nothing
            for i, j in enumerate(self.order):
                pos[j] = after.positions[i]
                vel[j] = after.velocities[i] if after.velocities else 0.0
                acc[j] = after.accelerations[i] if after.accelerations else 0.0
            return pos, vel, acc
        before = self.points[k - 1] if k else None
        t0 = before.time if before else 0.0
        degree = 5 if after.accelerations and (before is None or before.accelerations) else \
            3 if after.velocities and (before is None or before.velocities) else 1
        for i, j in enumerate(self.order):
            if before is None:
                p0, v0, a0 = self.hold[j], 0.0, 0.0
            else:
                p0 = before.positions[i]
                v0 = before.velocities[i] if before.velocities else 0.0
                a0 = before.accelerations[i] if before.accelerations else 0.0
            p1 = after.positions[i]
            v1 = after.velocities[i] if after.velocities else 0.0
            a1 = after.accelerations[i] if after.accelerations else 0.0
            pos[j], vel[j], acc[j] = _segment(max(0.0, rel - t0), after.time - t0, p0, v0, a0, p1, v1, a1, degree)
        return pos, vel, acc

    def _worst(self, tolerances, desired, actual, measured_velocity):
        """The first joint of the goal out of ``tolerances``: ``(name, kind,
        error, tolerance)``, or None."""
        for j in self.order:
            tol = tolerances[j]
            for kind, want, got in (("position", desired[0][j], actual[j]),
                                    ("velocity", desired[1][j],
                                     measured_velocity[j] if measured_velocity is not None else None)):
                limit = getattr(tol, kind)
                if limit is None or got is None:
                    continue
                error = got - want
                if abs(error) > limit:
                    return self.joints[j], kind, error, limit
        return None

    def verdict(self, t, actual, velocity=None):
        """What the encoders ``actual`` (positions of every joint, the
        bridge's order; ``velocity`` likewise when measured) at ``t`` say:
        None while the goal goes on; else ``(code, text)``."""
        desired = self.sample(t)
        if t <= self.end:
            out = self._worst(self.path, desired, actual, velocity)
            if out is not None:
                return PATH_TOLERANCE_VIOLATED, "%s: %s error %.6g beyond the path tolerance %.6g, %.3f s " \
                                                "into the trajectory" % (out + (t - self.start,))
            return None
        out = self._worst(self.goal, desired, actual, velocity)
        if out is None:
            return SUCCESSFUL, ""
        if t > self.end + self.goal_time:
            return GOAL_TOLERANCE_VIOLATED, "%s: %s error %.6g beyond the goal tolerance %.6g, %.3f s after " \
                                            "the trajectory's end (goal_time_tolerance %.3f s)" % (
                                                out + (t - self.end, self.goal_time))
        return None

    def feedback(self, t, actual):
        """``(desired, actual, error)`` positions of the goal's joints, in the
        goal's order, and the index of the point headed for."""
        desired = self.sample(t)[0]
        want = [desired[j] for j in self.order]
        got = [actual[j] for j in self.order]
        return want, got, [g - w for g, w in zip(got, want)], self.index_at(t)
