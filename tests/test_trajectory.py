"""ybg/runtime/trajectory.py: a FollowJointTrajectory goal checked, sampled
and watched, with no middleware. Each of control_msgs' codes from a goal or
an encoder reading that causes it; the samples pass through every point, are
continuous, and hold what the goal does not name."""

from __future__ import annotations

import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ybg.runtime import trajectory as tj
from ybg.runtime.trajectory import Defaults, Point, Refusal, Tolerance, accept

ARM = ["shoulder_pitch", "shoulder_roll", "shoulder_yaw", "elbow"]
HOME = [0.1, -0.2, 0.3, 0.4]
NOW = 1000.0


def ok(*args, **kw) -> tj.Trajectory:
    out = accept(ARM, *args, **kw)
    assert isinstance(out, tj.Trajectory), out
    return out


def refused(*args, **kw) -> Refusal:
    out = accept(ARM, *args, **kw)
    assert isinstance(out, Refusal), out
    return out


# --------------------------------------------------------------------------
# refused goals: the code, and a reason a user can act on


@pytest.mark.parametrize("names, code, says", [
    ([], tj.INVALID_JOINTS, "names no joint"),
    (["elbow", "wrist"], tj.INVALID_JOINTS, "'wrist' not driven by this controller, which drives shoulder_pitch"),
    (["elbow", "elbow"], tj.INVALID_JOINTS, "'elbow' named twice"),
])
def test_joints_the_controller_does_not_drive(names, code, says):
    r = refused(names, [Point(1.0, [0.0] * len(names))], HOME, NOW)
    assert r.code == code and says in r.text, r


@pytest.mark.parametrize("points, says", [
    ([], "no point"),
    ([Point(1.0, [0.0])], "point 0 has 1 positions for 2 joints"),
    ([Point(1.0, [0.0, 0.0], [1.0])], "point 0 has 1 velocities for 2 joints"),
    ([Point(1.0, [0.0, 0.0], [], [0.0, 0.0])], "accelerations but no velocities"),
    ([Point(1.0, [0.0, 0.0]), Point(1.0, [1.0, 1.0])], "point 1's time_from_start 1 s is not after point 0's 1 s"),
    ([Point(2.0, [0.0, 0.0]), Point(1.0, [1.0, 1.0])], "point 1's time_from_start 1 s is not after"),
    ([Point(-1.0, [0.0, 0.0])], "negative"),
    ([Point(1.0, [math.nan, 0.0])], "not a finite number"),
    ([Point(1.0, [0.0, math.inf])], "not a finite number"),
])
def test_an_invalid_trajectory(points, says):
    r = refused(["elbow", "shoulder_pitch"], points, HOME, NOW)
    assert r.code == tj.INVALID_GOAL and says in r.text, r


def test_tolerances_of_the_wrong_sign_or_joint():
    names = ["elbow"]
    pts = [Point(1.0, [0.0])]
    r = refused(names, pts, HOME, NOW, path_tolerance=[("elbow", -0.5, 0, 0)])
    assert r.code == tj.INVALID_GOAL and "path_tolerance of 'elbow': -0.5, 0, 0" in r.text
    r = refused(names, pts, HOME, NOW, goal_tolerance=[("knee", 0.1, 0, 0)])
    assert r.code == tj.INVALID_JOINTS and "goal_tolerance names joint 'knee'" in r.text
    r = refused(names, pts, HOME, NOW, goal_time_tolerance=-1.0)
    assert r.code == tj.INVALID_GOAL and "goal_time_tolerance" in r.text
    # a tolerance of a joint the goal does not move is allowed (it is the controller's)
    ok(names, pts, HOME, NOW, path_tolerance=[("shoulder_roll", 0.1, -1, 0)])


def test_a_trajectory_that_ended_before_it_came():
    r = refused(["elbow"], [Point(1.0, [0.0]), Point(2.0, [1.0])], HOME, NOW, stamp=NOW - 3.0)
    assert r.code == tj.OLD_HEADER_TIMESTAMP and "ended 1.000 s ago" in r.text, r
    # one that started in the past but goes on is taken up where it is
    t = ok(["elbow"], [Point(1.0, [0.0]), Point(2.0, [1.0])], HOME, NOW, stamp=NOW - 1.5)
    assert t.start == NOW - 1.5 and t.sample(NOW)[0][3] == pytest.approx(0.5)
    # a stamp in the future: nothing moves before it
    t = ok(["elbow"], [Point(1.0, [0.0])], HOME, NOW, stamp=NOW + 2.0)
    assert t.sample(NOW + 1.0)[0] == HOME


# --------------------------------------------------------------------------
# sampling


def test_positions_only_is_linear_from_where_the_joints_are():
    t = ok(["elbow", "shoulder_pitch"], [Point(1.0, [1.4, 1.1]), Point(3.0, [0.4, 2.1])], HOME, NOW)
    pos, vel, acc = t.sample(NOW + 0.5)
    assert pos == pytest.approx([0.6, -0.2, 0.3, 0.9])  # halfway from HOME; the others hold
    assert vel == pytest.approx([1.0, 0.0, 0.0, 1.0]) and acc == [0.0] * 4
    assert t.sample(NOW + 2.0)[0] == pytest.approx([1.6, -0.2, 0.3, 0.9])
    assert t.sample(NOW + 99.0) == ([2.1, -0.2, 0.3, 0.4], [0.0] * 4, [0.0] * 4)
    assert [t.index_at(NOW + x) for x in (0.0, 0.99, 1.0, 2.9, 3.0, 50.0)] == [0, 0, 1, 1, 1, 1]


def test_velocities_make_it_cubic_and_accelerations_quintic():
    cubic = ok(["elbow"], [Point(1.0, [1.0], [0.0]), Point(2.0, [2.0], [0.0])], HOME, NOW)
    pos, vel, _ = cubic.sample(NOW + 1.5)
    assert pos[3] == pytest.approx(1.5) and vel[3] == pytest.approx(1.5)  # smoothstep's middle
    assert cubic.sample(NOW + 1.0001)[1][3] == pytest.approx(0.0, abs=1e-3)  # at rest at the point
    quintic = ok(["elbow"], [Point(1.0, [1.0], [0.0], [0.0]), Point(2.0, [2.0], [0.0], [0.0])], HOME, NOW)
    pos, vel, acc = quintic.sample(NOW + 1.5)
    assert pos[3] == pytest.approx(1.5) and vel[3] == pytest.approx(1.875) and acc[3] == pytest.approx(0.0)


finite = st.floats(-3.0, 3.0, allow_nan=False)


@st.composite
def goals(draw):
    names = draw(st.permutations(ARM).map(lambda p: p[:draw(st.integers(1, len(ARM)))]))
    n = len(names)
    steps = draw(st.lists(st.floats(0.01, 2.0), min_size=1, max_size=5))
    kind = draw(st.sampled_from(["p", "pv", "pva"]))
    points, time = [], 0.0
    for step in steps:
        time += step
        points.append(Point(time, draw(st.lists(finite, min_size=n, max_size=n)),
                            draw(st.lists(finite, min_size=n, max_size=n)) if "v" in kind else [],
                            draw(st.lists(finite, min_size=n, max_size=n)) if "a" in kind else []))
    return names, points


@settings(max_examples=200, deadline=None)
@given(goals(), st.lists(finite, min_size=4, max_size=4))
def test_samples_pass_through_every_point_and_hold_the_rest(goal, home):
    names, points = goal
    t = ok(names, points, home, NOW)
    order = [ARM.index(n) for n in names]
    for p in points:
        pos, vel, _ = t.sample(NOW + p.time)
        assert [pos[j] for j in order] == pytest.approx(p.positions, abs=1e-9)
        if p.velocities and p is not points[-1]:
            assert [vel[j] for j in order] == pytest.approx(p.velocities, abs=1e-6)
    for x in (0.0, points[-1].time / 3, points[-1].time + 1.0):
        pos = t.sample(NOW + x)[0]
        assert all(pos[j] == home[j] for j in range(4) if j not in order)
    assert t.sample(NOW)[0] == pytest.approx(home)  # it starts where the joints are


@settings(max_examples=100, deadline=None)
@given(goals(), st.lists(finite, min_size=4, max_size=4))
def test_samples_are_continuous(goal, home):
    names, points = goal
    t = ok(names, points, home, NOW)
    eps = 1e-7
    for p in points[:-1]:
        left, right = t.sample(NOW + p.time - eps)[0], t.sample(NOW + p.time + eps)[0]
        assert right == pytest.approx(left, abs=1e-3)


# --------------------------------------------------------------------------
# watching the encoders


def test_a_joint_held_back_violates_the_path_tolerance():
    d = Defaults(4, path=[Tolerance(0.05)] * 4)
    t = ok(["elbow"], [Point(2.0, [2.4])], HOME, NOW, defaults=d)
    assert t.verdict(NOW + 1.0, [0.1, -0.2, 0.3, 1.42]) is None  # 0.02 behind
    code, text = t.verdict(NOW + 1.0, [0.1, -0.2, 0.3, 1.3])
    assert code == tj.PATH_TOLERANCE_VIOLATED and "elbow: position error -0.1 beyond the path tolerance 0.05" in text
    # a joint the goal does not move is not watched by it
    assert t.verdict(NOW + 1.0, [9.0, -0.2, 0.3, 1.4]) is None
    # the goal's own tolerance: 0 keeps the default, -1 erases it, positive replaces it
    assert ok(["elbow"], [Point(2.0, [2.4])], HOME, NOW, defaults=d,
              path_tolerance=[("elbow", -1, 0, 0)]).verdict(NOW + 1.0, [0.1, -0.2, 0.3, 0.0]) is None
    loose = ok(["elbow"], [Point(2.0, [2.4])], HOME, NOW, defaults=d, path_tolerance=[("elbow", 0.2, 0, 0)])
    assert loose.verdict(NOW + 1.0, [0.1, -0.2, 0.3, 1.3]) is None
    assert loose.path[3] == Tolerance(0.2) and loose.path[0] == Tolerance(0.05)


def test_the_goal_reached_late_or_never():
    d = Defaults(4, goal=[Tolerance(0.01)] * 4, goal_time=0.5)
    t = ok(["elbow"], [Point(1.0, [1.0])], HOME, NOW, defaults=d)
    there, short = [0.1, -0.2, 0.3, 0.995], [0.1, -0.2, 0.3, 0.9]
    assert t.verdict(NOW + 1.1, short) is None  # within goal_time_tolerance: still going
    assert t.verdict(NOW + 1.2, there) == (tj.SUCCESSFUL, "")
    code, text = t.verdict(NOW + 1.6, short)
    assert code == tj.GOAL_TOLERANCE_VIOLATED and "elbow: position error -0.1" in text and "0.500 s" in text
    # the goal's goal_time_tolerance replaces the default
    t = ok(["elbow"], [Point(1.0, [1.0])], HOME, NOW, defaults=d, goal_time_tolerance=2.0)
    assert t.verdict(NOW + 2.5, short) is None
    # no goal_time_tolerance at all: the end is the deadline
    t = ok(["elbow"], [Point(1.0, [1.0])], HOME, NOW, defaults=Defaults(4, goal=[Tolerance(0.01)] * 4))
    assert t.verdict(NOW + 1.01, short)[0] == tj.GOAL_TOLERANCE_VIOLATED


def test_velocity_is_watched_only_where_it_is_measured():
    d = Defaults(4, path=[Tolerance(None, 0.1)] * 4)
    t = ok(["elbow"], [Point(2.0, [2.4])], HOME, NOW, defaults=d)  # 1 rad/s
    at = [0.1, -0.2, 0.3, 1.4]
    assert t.verdict(NOW + 1.0, at) is None
    assert t.verdict(NOW + 1.0, at, velocity=[0.0, 0.0, 0.0, 1.05]) is None
    code, text = t.verdict(NOW + 1.0, at, velocity=[0.0, 0.0, 0.0, 0.5])
    assert code == tj.PATH_TOLERANCE_VIOLATED and "elbow: velocity error -0.5" in text


def test_feedback_in_the_goals_order():
    t = ok(["elbow", "shoulder_pitch"], [Point(1.0, [1.4, 1.1])], HOME, NOW)
    desired, actual, error, index = t.feedback(NOW + 0.5, [0.5, -0.2, 0.3, 0.8])
    assert desired == pytest.approx([0.9, 0.6]) and actual == [0.8, 0.5]
    assert error == pytest.approx([-0.1, -0.1]) and index == 0
