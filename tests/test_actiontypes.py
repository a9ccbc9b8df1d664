"""ROS 2 action definitions (``.action``) in the type store: the vendored
ones (``ybg/msgs/<distro>/control_msgs/``, scripts/vendor_srvs.py), the
user's own (``--msg-path``, ``AMENT_PREFIX_PATH``), and bad files, which are
problems with their line, never exceptions."""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from ybg.compiler.ir import TypeRef
from ybg.compiler.msgtypes import VENDORED_DIR, load_store, parse_action

ACTION_DISTROS = ("humble", "jazzy", "kilted")
NO_ENV: dict[str, str] = {}


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
    return path


@pytest.mark.parametrize("distro", ACTION_DISTROS)
def test_follow_joint_trajectory_in_every_distro(distro):
    store = load_store("ros2", distro, environ=NO_ENV)
    files = sorted((Path(VENDORED_DIR) / distro).glob("*/*.action"))
    assert store.action_names() == sorted(f"{p.parent.name}/{p.stem}" for p in files)
    fjt = store.resolve_action("control_msgs/action/FollowJointTrajectory")
    assert fjt is not None, store.problems
    assert (fjt.goal.name, fjt.result.name, fjt.feedback.name) == (
        "control_msgs/FollowJointTrajectory_Goal", "control_msgs/FollowJointTrajectory_Result",
        "control_msgs/FollowJointTrajectory_Feedback")
    goal = {f.name: f.type for f in fjt.goal.fields}
    assert goal["trajectory"] == TypeRef("trajectory_msgs/JointTrajectory")
    assert goal["path_tolerance"] == TypeRef("control_msgs/JointTolerance", "sequence")
    assert goal["goal_time_tolerance"] == TypeRef("builtin_interfaces/Duration")
    # the result codes control_msgs gives, by name
    codes = {c.name: c.value for c in fjt.result.constants}
    assert codes == {"SUCCESSFUL": 0, "INVALID_GOAL": -1, "INVALID_JOINTS": -2, "OLD_HEADER_TIMESTAMP": -3,
                     "PATH_TOLERANCE_VIOLATED": -4, "GOAL_TOLERANCE_VIOLATED": -5}
    # its parts resolve as messages, and so do the messages they name
    assert store.resolve("control_msgs/FollowJointTrajectory_Feedback") is fjt.feedback
    tolerance = store.resolve("control_msgs/JointTolerance")
    assert [f.name for f in tolerance.fields] == ["name", "position", "velocity", "acceleration"]
    feedback = [f.name for f in fjt.feedback.fields]
    assert feedback[:5] == ["header", "joint_names", "desired", "actual", "error"]
    # Kilted's control_msgs (6.3 on) numbers the point the feedback is at; Jazzy's and Humble's not
    assert ("index" in feedback) == (distro == "kilted")
    assert store.problems == []


def test_an_action_is_not_a_message_or_a_service():
    store = load_store("ros2", "kilted", environ=NO_ENV)
    assert store.resolve("control_msgs/FollowJointTrajectory") is None
    assert store.resolve_service("control_msgs/FollowJointTrajectory") is None
    assert store.resolve_action("std_srvs/Trigger") is None
    assert store.resolve_action("control_msgs/msg/FollowJointTrajectory") is not None  # "pkg/msg/Name" is taken too
    assert store.resolve_action("not a name") is None


LOOK = """
    # look at a point, until the gaze is there
    geometry_msgs/Point target
    float64 speed 10.0
    ---
    bool reached
    ---
    geometry_msgs/Point fixation
    float64 distance
    """


def test_a_user_action_through_the_msg_path_and_the_environment(tmp_path):
    write(tmp_path / "dirs" / "my_gaze" / "action" / "Look.action", LOOK)
    write(tmp_path / "prefix" / "share" / "my_arm" / "action" / "Home.action", "string part\n---\nbool ok\n---\n")
    store = load_store("ros2", "jazzy", [tmp_path / "dirs"], environ={"AMENT_PREFIX_PATH": str(tmp_path / "prefix")})
    look = store.resolve_action("my_gaze/Look")
    assert look is not None, store.problems
    assert [f.name for f in look.goal.fields] == ["target", "speed"]
    assert look.goal.fields[1].default is not None
    assert [f.name for f in look.feedback.fields] == ["fixation", "distance"]
    assert store.action_path("my_gaze/action/Look") == str(tmp_path / "dirs" / "my_gaze" / "action" / "Look.action")
    home = store.resolve_action("my_arm/Home")
    assert home is not None and home.feedback.fields == ()
    assert {"my_gaze/Look", "my_arm/Home", "control_msgs/FollowJointTrajectory"} <= set(store.action_names())


@pytest.mark.parametrize("text, line, says", [
    ("int32 order\n---\nint32[] sequence\n", 3, "no '---' line between the result and the feedback"),
    ("int32 order\n", 1, "no '---' line between the goal and the result"),
    ("int32 order\n---\n---\nint32 x\n---\nint32 y\n", 5, "a 3th '---' line"),
    ("int32 order\n---\nint32 Bad-name\n---\n", 3, ""),
    ("int32 order\n---\n---\nNoSuchType x\n", 4, "unknown message type"),
])
def test_a_bad_action_file_is_a_problem_at_its_line(tmp_path, text, line, says):
    path = write(tmp_path / "bad_pkg" / "action" / "Bad.action", text)
    store = load_store("ros2", "kilted", [tmp_path], environ=NO_ENV)
    assert store.resolve_action("bad_pkg/Bad") is None
    [problem] = [p for p in store.problems if p.path == str(path)][:1]
    assert problem.line == line and says in problem.message, store.problems


def test_parse_action_keeps_every_parts_line_numbers():
    action, problems = parse_action("int32 a\n---\n\nint32 b\n---\n# c\nint32 c\n", "p/A", "ros2")
    assert problems == []
    assert [(f.name, f.line) for part in action.parts for f in part.fields] == [("a", 1), ("b", 4), ("c", 7)]
