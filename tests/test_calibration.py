"""[camera_info] from a YARP camera calibration file (ybg/compiler/passes/images.py):
iCub's groups, their `key value` lines with spaces or tabs, comments, and
what a group that lacks a key gives (E344 at the group's name)."""
from __future__ import annotations

from pathlib import Path

from ybg.compiler.pipeline import compile_path

CONFIG = """\
[mux eye]
ports = /icub/cam/left (image rgb8)

[output]
topic = /icub/cam/left/image_raw
type = sensor_msgs/Image
via = ros2

[message]
data = eye

[camera_info]
calibration = "eyes.ini", CAMERA_CALIBRATION_LEFT
"""


def camera_info(tmp_path: Path, calibration: str):
    (tmp_path / "eyes.ini").write_text(calibration, encoding="utf-8")
    (tmp_path / "eye.ini").write_text(CONFIG, encoding="utf-8")
    return compile_path(tmp_path / "eye.ini")


def fields(result) -> dict:
    return {f.name: getattr(f.source, "values", None) for f in result.program.output.camera_info.message.fields}


def test_spaces_tabs_and_comments_read_alike(tmp_path):
    spaced = camera_info(tmp_path, "[CAMERA_CALIBRATION_LEFT]\nprojection pinhole\nw 320\nh   240\n"
                                   "fx 219.057\nfy 219.028\ncx 174.742\ncy 102.874\nk1 -0.37\np2 0.0027\n")
    tabbed = camera_info(tmp_path, "// iCub's left eye\n[CAMERA_CALIBRATION_LEFT]\nprojection\tpinhole\nw\t320\n"
                                   "h\t\t240 # at 320x240\nfx\t219.057\nfy\t219.028\ncx\t174.742\ncy\t102.874\n"
                                   "k1\t-0.37\np2\t0.0027\n[CAMERA_CALIBRATION_RIGHT]\nw\t640\n")
    assert spaced.ok and tabbed.ok, tabbed.diagnostics
    assert fields(spaced) == fields(tabbed)
    got = fields(tabbed)
    assert (got["width"], got["height"], got["distortion_model"]) == ((320,), (240,), ("plumb_bob",))
    assert got["k"] == (219.057, 0.0, 174.742, 0.0, 219.028, 102.874, 0.0, 0.0, 1.0)
    assert got["d"] == (-0.37, 0.0, 0.0, 0.0027, 0.0)


def test_a_group_without_a_key_is_e344_at_the_group(tmp_path):
    result = camera_info(tmp_path, "[CAMERA_CALIBRATION_LEFT]\nw\t320\nh\t240\nfx\t219.0\nfy\t219.0\ncx\t174.7\n")
    (error,) = result.errors
    assert error.code == "E344" and "cy" in error.message
    assert (error.span.line, error.span.column) == (13, 27)
