"""Pass ``images``: camera images, after the message passes.

A YARP port of images (`[output] image = <mux>`): the mux must read a ROS 2
``sensor_msgs/Image`` topic (E340), the output is a YARP port, and there is
no [message] to build (E343). The CameraInfo beside a ROS 2 image
(`[camera_info]`): its fields, type-checked as [message]'s are against
``sensor_msgs/CameraInfo`` (its `header` is the image's, E343 when set),
or read from a YARP camera calibration file (`calibration = "icub_eyes.ini",
CAMERA_CALIBRATION_LEFT`, E344 when it cannot be read), published on
`topic`, by default `camera_info` beside the image's topic (REP: `.../image_raw`
and `.../camera_info` in one namespace).
Reads ``sections``, ``output``, ``message``, ``muxes``, ``store``. Sets
``output`` (its ``image`` or ``camera_info``) and ``message`` for an image
port, and adds to ``used_muxes``.
"""

from __future__ import annotations

import dataclasses
import posixpath
from pathlib import Path

from ybg.compiler import ast, ir
from ybg.compiler.names import topic_problem
from ybg.compiler.passes import typed
from ybg.compiler.passes.context import Context
from ybg.compiler.passes.message import field_path, index_below
from ybg.compiler.passes.muxrefs import unknown_mux
from ybg.compiler.values import word

#: the keys of [camera_info] that are not fields of sensor_msgs/CameraInfo
INFO_KEYS = ("topic", "calibration")
#: what a calibration group must give (YARP's camera calibration files: iCub's eyes)
CALIBRATION_KEYS = ("w", "h", "fx", "fy", "cx", "cy")
#: a calibration's distortion: the CameraInfo's `distortion_model`, and the
#: group's keys its `d` holds, in order (each 0 when the group lacks it):
#: `plumb_bob` unless the group says `projection fisheye`
PLUMB_BOB = ("plumb_bob", ("k1", "k2", "p1", "p2", "k3"))
EQUIDISTANT = ("equidistant", ("k1", "k2", "k3", "k4"))
#: the CameraInfo's topic, beside the image's, unless [camera_info] names one
CAMERA_INFO_TOPIC = "camera_info"


def run(ctx: Context) -> None:
    out = ctx.output
    if out is None:
        return
    entry = ctx.output_keys.get("image")
    if entry is not None:
        _image_port(ctx, out, entry)
    info = ctx.sections.get("camera_info")
    if info is not None:
        _camera_info(ctx, out, info)


def _image_port(ctx: Context, out: ir.Output, entry: ast.Entry) -> None:
    s = ctx.sink
    name = word(entry, s, "mux")
    if name is None:
        return
    if name not in ctx.muxes:
        unknown_mux(ctx, name, entry.items[0].span)
        return
    mux = ctx.muxes[name]
    ctx.used_muxes.add(name)
    if mux.image is None or mux.inputs[0].kind != "ros2":
        s.error("E340", f"`image = {name}`: mux `{name}` does not read a ROS 2 camera", entry.items[0].span,
                f"read a `sensor_msgs/Image` topic: `topics = /camera/image_raw (sensor_msgs/Image)` with "
                "`via = ros2`")
        return
    if out.kind != "yarp":
        s.error("E340", "`image` writes a YARP port of camera images: give `port = ...`", entry.key_span,
                "a ROS 2 image is `type = sensor_msgs/Image` with `data = <mux>` in [message]")
        return
    msg = ctx.sections.get("message")
    if msg is not None and msg.entries:
        s.error("E343", f"the port writes the frames of mux `{name}`: [message] has nothing to set",
                msg.entries[0].key_span, "remove [message]")
        return
    ctx.output = dataclasses.replace(out, image=name)
    ctx.message = ir.Struct(())


def _camera_info(ctx: Context, out: ir.Output, sec: ast.Section) -> None:
    s = ctx.sink
    frame = _frame(ctx.message)
    if out.kind != "ros2" or frame is None:
        s.error("E340", "[camera_info] goes beside a ROS 2 image: a `sensor_msgs/Image` output whose `data` is "
                "an image mux", sec.span, "remove [camera_info], or publish the image (`data = <mux>`)")
        return
    keys = {e.key: e for e in sec.entries if e.key in INFO_KEYS}
    topic = posixpath.join(posixpath.dirname(out.name), CAMERA_INFO_TOPIC)
    if "topic" in keys:
        topic = word(keys["topic"], s, "topic") or topic
        problem = topic_problem(topic)
        if problem:
            s.error("E402", f"invalid ROS topic name `{topic}`: {problem}", keys["topic"].items[0].span)
            return
    msgdef = ctx.store.resolve("sensor_msgs/CameraInfo")
    if msgdef is None:
        s.error("E321", "the definition of `sensor_msgs/CameraInfo` was not found", sec.span,
                "give the folder of its .msg files with `--msg-path DIR`")
        return
    entries = {}
    for e in sec.entries:
        if e.key in INFO_KEYS:
            continue
        path = field_path(e.key)
        if path is None:
            s.error("E302", f"`{e.key}` is not a field path", e.key_span, "e.g. `k = [...]`, `distortion_model`")
            continue
        if path[0] == "header":
            s.error("E343", "the CameraInfo's header is its image's (the same stamp and frame_id)", e.key_span,
                    "remove the line; set `header.frame_id` in [message]")
            continue
        entries[path] = e
    # the message tree, built as [message]'s
    struct = typed.build_struct(ctx, msgdef, entries, index_below(entries))
    if "calibration" in keys:
        calibration = _calibration(ctx, keys["calibration"])
        if calibration is None:
            return
        struct = ir.Struct(tuple(
            ir.Field(f.name, calibration[f.name], f.type, f.span)
            if f.name in calibration and (f.name,) not in entries else f
            for f in struct.fields), struct.msg_type)
    ctx.output = dataclasses.replace(out, camera_info=ir.CameraInfo(topic, struct, sec.span))


def _frame(message: ir.Struct | None) -> ir.ImageFrame | None:
    if message is None or message.msg_type != ir.IMAGE_TYPE:
        return None
    for f in message.fields:
        if f.name == "data" and isinstance(f.source, ir.ImageFrame):
            return f.source
    return None


def _calibration(ctx: Context, entry: ast.Entry) -> dict[str, ir.Source] | None:
    """The CameraInfo fields of a YARP camera calibration group
    (`calibration = "icub_eyes.ini", CAMERA_CALIBRATION_LEFT`): `w` `h` the
    size it was made at, `fx` `fy` `cx` `cy`, and the plumb-bob distortion
    `k1` `k2` `p1` `p2` (`k3`), each 0 when absent; `projection fisheye`
    gives the equidistant model from `k1` to `k4`."""
    s = ctx.sink
    items = entry.items
    if len(items) != 2 or not isinstance(items[0], (ast.Str, ast.Word)) or not isinstance(items[1], ast.Word):
        s.error("E344", "`calibration` takes a file and its group: `calibration = \"icub_eyes.ini\", "
                "CAMERA_CALIBRATION_LEFT`", entry.span)
        return None
    file = items[0].value if isinstance(items[0], ast.Str) else items[0].text
    group = items[1].text
    base = Path(ctx.sink.file).parent if ctx.sink.file and not ctx.sink.file.startswith("<") else Path(".")
    path = base / file
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as e:
        s.error("E344", f"cannot read the calibration file {path}: {getattr(e, 'strerror', None) or e}",
                items[0].span, "give its path relative to the config's folder")
        return None
    values = _group(text, group)
    if values is None:
        s.error("E344", f"{file} has no group [{group}]", items[1].span,
                "iCub's eyes: CAMERA_CALIBRATION_LEFT or CAMERA_CALIBRATION_RIGHT")
        return None
    nums: dict[str, float] = {}
    for k, v in values.items():
        try:
            nums[k] = float(v)
        except ValueError:
            pass
    missing = [k for k in CALIBRATION_KEYS if k not in nums]
    if missing:
        s.error("E344", f"[{group}] of {file} does not give {', '.join(missing)}", items[1].span,
                f"a calibration group gives {' '.join(CALIBRATION_KEYS)} (and k1 k2 p1 p2)")
        return None
    fx, fy, cx, cy = nums["fx"], nums["fy"], nums["cx"], nums["cy"]
    model, coefficients = EQUIDISTANT if values.get("projection") == "fisheye" else PLUMB_BOB
    d = [nums.get(k, 0.0) for k in coefficients]

    def floats(xs):
        return ir.Literal(tuple(float(x) for x in xs), "float64", True)

    return {
        "width": ir.Literal((int(nums["w"]),), "uint32"),
        "height": ir.Literal((int(nums["h"]),), "uint32"),
        "distortion_model": ir.Literal((model,), "string"),
        "d": floats(d),
        "k": floats((fx, 0, cx, 0, fy, cy, 0, 0, 1)),
        "r": floats((1, 0, 0, 0, 1, 0, 0, 0, 1)),
        "p": floats((fx, 0, cx, 0, 0, fy, cy, 0, 0, 0, 1, 0)),
    }


def _group(text: str, group: str) -> dict[str, str] | None:
    """The `key value` lines of [group] in a YARP .ini file (None: no such group)."""
    current = None
    found: dict[str, str] | None = None
    for raw in text.splitlines():
        line = raw.split("//", 1)[0].split("#", 1)[0].strip()
        if not line:
            continue
        if line.startswith("[") and line.endswith("]"):
            current = line[1:-1].strip()
            if current == group:
                found = {}
            continue
        if current == group and found is not None:
            key, *value = line.split()  # `key value`, spaces or tabs between
            found[key] = value[0] if value else ""
    return found


__all__ = ["run"]
