"""A fixed-size and a bounded array of messages, end to end through the
native ROS 2 module: ``ybg_demo_msgs/Polygon`` (msgpkgs/ybg_demo_msgs, built
into the venv by the setup) has ``geometry_msgs/Point32[4] corners`` and
``geometry_msgs/Point32[<=3] marks``, which no standard message package has.
Its definition is found as a user's is, through AMENT_PREFIX_PATH; the module
is built against the ROS 2 wheels, fed by YARP producers, and publishes the
exact message an rclpy subscriber expects, the same bit for bit as the rclpy
node of ``--backend ros2``; more marks than the bound is refused by
``ybgc check`` at its place."""
from __future__ import annotations

import os
import struct
import subprocess
from pathlib import Path

import pytest

from harness.build import Builds
from harness.differential import Differential, float_bits
from harness.env import VENV
from harness.launchers import require_message_packages
from harness.ros2 import ros2_environment
from ybg.backends import check_result
from ybg.compiler.options import Options
from ybg.compiler.pipeline import compile_text

YBGC = VENV / "bin" / "ybgc"

POLYGON = """\
[module]
name = polygon_native

[output]
topic = /fixarr/polygon
type = ybg_demo_msgs/Polygon
via = ros2
depth = 100

[mux m]
ports = /fixarr/corners:o (float64 x5)

[mux k]
ports = /fixarr/marks:o (float64 x4)

[message]
header.stamp = timestamp(m)
header.frame_id = "base_link"
label = "square"
corners[0] = m[0:3]
corners[2].x = m[3]
corners[2].z = m[4]
corners[3].y = -1.5
marks[0] = k[0:3]
marks[1].z = k[3]
"""

TOO_MANY_MARKS = """\
[output]
topic = /fixarr/polygon
type = ybg_demo_msgs/Polygon
via = ros2

[mux k]
ports = /fixarr/marks:o (float64 x3)

[message]
marks[0] = k[0:3]
marks[1] = k[0:3]
marks[2] = k[0:3]
marks[3] = k[0:3]
"""


def ament_environ() -> dict:
    """The environment of a user of the venv's message packages: ybgc finds
    their definitions in <venv>/share/<pkg>/msg."""
    return dict(os.environ, AMENT_PREFIX_PATH=str(VENV))


def ybgc_check(tmp_path: Path, text: str, name: str) -> subprocess.CompletedProcess:
    cfg = tmp_path / name
    cfg.write_text(text)
    return subprocess.run([str(YBGC), "check", str(cfg)], capture_output=True, text=True, timeout=60,
                          env=ament_environ())


def f32(x: float) -> float:
    """``x`` as a float32 field holds it (a C cast: to the nearest)."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def point(x=0.0, y=0.0, z=0.0) -> dict:
    return {"x": f32(x), "y": f32(y), "z": f32(z)}


def expected(k: int, corners: list, marks: list) -> dict:
    """The message of round ``k``: the corners and marks the config fills,
    every other field its definition's default."""
    return {"header": {"stamp": {"sec": 1_700_000_000 + k, "nanosec": 500_000_000}, "frame_id": "base_link"},
            "label": "square",
            "corners": [point(*corners[0:3]), point(), point(x=corners[3], z=corners[4]), point(y=-1.5)],
            "marks": [point(*marks[0:3]), point(z=marks[3])]}


def test_ybgc_check_finds_polygon_and_refuses_a_fourth_mark(tmp_path):
    r = ybgc_check(tmp_path, POLYGON, "polygon_native.ini")
    assert r.returncode == 0 and r.stderr == "", r.stderr
    r = ybgc_check(tmp_path, TOO_MANY_MARKS, "polygon_marks.ini")
    assert r.returncode == 1
    assert f"{tmp_path / 'polygon_marks.ini'}:13:1: error E331 `marks[3]` is beyond `marks`, which is " \
           "geometry_msgs/Point32[<=3]" in r.stderr, r.stderr


@pytest.mark.yarp_min((4, 0))
def test_fixed_and_bounded_arrays_of_messages_end_to_end(yarp, yarp_server, ros2_domain, tmp_path):
    """Corners 0 and 2 from a mux (2 in part), 3 a constant, 1 left at its
    defaults; 2 of the 3 bounded marks: the exact message each round, as the
    rclpy node publishes it."""
    result = check_result(compile_text(POLYGON, "polygon_native.ini", Options(environ=ament_environ())), "cpp")
    assert result.ok, [str(d) for d in result.diagnostics]
    require_message_packages(result.program)
    builds = Builds(tmp_path / "cpp", yarp)
    builds.add("polygon_native", result.program)
    rounds = 6
    sent = []
    with Differential(builds, "polygon_native", ros2_environment(yarp_server.env, ros2_domain),
                      tmp_path / "node") as diff:
        for k in range(rounds):
            corners = [0.1 * k, -2.5, 1e3 + k, 3.3 - k, -0.0]
            marks = [k / 3, 7.25, -1e-3 * k, 2.0 ** -k]
            # the stamp from m's envelope: a half second, exact in nanoseconds as a double
            diff.producers["/fixarr/corners:o"].write(corners, stamp=[k, 1.7e9 + k + 0.5])
            diff.producers["/fixarr/marks:o"].write(marks, stamp=[k, 1.7e9 + k + 0.75])
            for s in diff.subs:
                s.wait_for(k + 1)
            sent.append(expected(k, corners, marks))
        msgs = diff.messages(rounds)
    assert msgs == [float_bits(m) for m in sent]
