"""Lowering of the ROS 2 topic inputs (``[mux] topics = /t (pkg/Type
field ...)``, ``via = ros2``) of the ``cpp`` backend: the module subscribes
through the rcl C API with the runtime's ``ybgc::ros2::Subscriptions``
(docs/ros2-native.md).

Each topic gets a small reader in the module, one line a field the config
lists: ``ybgc::ros2::read(out, msg.point.x);`` appends the field of the
message's C struct (``<pkg>/msg/<name>.h``, ``pkg__msg__Name``) to the
input's values, the runtime's overload deducing how from the field's C type
(a number as it is, a time or duration as seconds, a sequence or a fixed
array element by element), as the Python ROS 2 node reads the same fields
(``ybg/runtime/ros2_io.py``). The values then go through the same checks,
freshness and matching as a Bottle.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from ybg.backends.cpp.escape import comment, cpp_identifier, cpp_string
from ybg.backends.cpp.rcl import RUNTIME_PACKAGES, c_header
from ybg.compiler import ir
from ybg.lower.errors import Line, LoweringError
from ybg.lower.qos import checked_qos
from ybg.lower.rosnames import node_name, split_type, used_packages

_ELEMENT = re.compile(r"([A-Za-z_][A-Za-z0-9_]*)((?:\[[0-9]+\])*)\Z")


@dataclass(frozen=True)
class TopicReaderView:
    """The reader of one ROS 2 topic input and its entry in ``kTopics``
    (a camera image's reader is the runtime's: no function of the module)."""

    function: str             # its C++ name
    c_type: str               # the message's C struct
    out: str                  # its output parameter: the input's values, or its rows
    comment: str
    lines: tuple[Line, ...]   # its body
    entry: tuple[Line, ...]   # its ybgc::ros2::topic<...>(...) in kTopics
    in_module: bool = True    # the module holds its function


@dataclass(frozen=True)
class Ros2InputsView:
    """What the module and its CMakeLists print of the ROS 2 inputs."""

    node: str                          # string literal: the node that reads them (a YARP output)
    includes: tuple[str, ...]          # <pkg>/msg/<name>.h of each input's message
    readers: tuple[TopicReaderView, ...]
    packages: tuple[str, ...]          # the message packages to link


def _member_path(path: str) -> str:
    """A dotted field path (``pose.covariance[3]``) as C member access."""
    parts = []
    for part in path.split("."):
        match = _ELEMENT.match(part)
        if match is None:
            raise LoweringError(f"field {path!r} cannot be read from a C struct")
        try:
            name = cpp_identifier(match.group(1))
        except ValueError as e:
            raise LoweringError(f"field {path!r} cannot be read from a C struct ({e})") from None
        parts.append(name + match.group(2))
    return ".".join(parts)


def _qos_argument(i: ir.Input) -> str:
    """The QoS argument of a topic's entry when its mux asks one, else none
    (the runtime's default: best effort, volatile, depth 1)."""
    if i.qos is None:
        return ""
    q = checked_qos(i.qos, i.span)
    return (f", ybgc::ros2::InputQos{{{'true' if q.reliability == 'reliable' else 'false'}, "
            f"{'true' if q.durability == 'transient_local' else 'false'}, {int(q.depth)}}}),  "
            f"// {q.reliability}, {q.durability}, depth {int(q.depth)}")


def _end(i: ir.Input) -> str:
    """The end of a topic's entry: its QoS argument, if any, and the call's end."""
    qos = _qos_argument(i)
    return qos if qos else "),"


def _image_reader(i: ir.Input, index: int) -> TopicReaderView:
    """A ROS 2 camera (sensor_msgs/Image, the whole frame): read by the runtime."""
    if i.ros_type != ir.IMAGE_TYPE or i.fields:
        raise LoweringError(f"the ROS 2 camera {i.name} reads whole sensor_msgs/Image messages", i.span)
    c_type = "sensor_msgs__msg__Image"
    entry = (Line(2, f"ybgc::ros2::topic<{c_type}, &{c_type}__create, &{c_type}__destroy, &ybgc::images::read>("),
             Line(3, f"{index}, {cpp_string(i.name)}, {cpp_string('sensor_msgs/msg/Image')}, "
                     f"ROSIDL_GET_MSG_TYPE_SUPPORT(sensor_msgs, msg, Image){_end(i)}"))
    what = f"{comment(i.name)} (sensor_msgs/msg/Image): the frame (ybgc::images::read)"
    return TopicReaderView("ybgc::images::read", c_type, "ybgc::Reading& out", what, (), entry, in_module=False)


def _reader(program: ir.Program, m: ir.Mux, k: int, i: ir.Input, index: int, member: str) -> TopicReaderView:
    where = i.span
    if not i.ros_type:
        raise LoweringError(f"the ROS 2 input {i.name} has no message type", where)
    if i.image is not None:
        return _image_reader(i, index)
    if not i.fields:
        raise LoweringError(f"the ROS 2 input {i.name} names no numeric field", where)
    if i.each is not None and program.output.kind == "ros2":
        raise LoweringError(f"the ROS 2 input {i.name} reads the elements of an array of messages "
                            f"({i.each}), a row each, which a ROS 2 message is not filled from", where)
    try:
        pkg, name = split_type(i.ros_type)
        if i.each is None:
            out = "ybgc::Mux& out"
            lines = tuple(Line(1, f"ybgc::ros2::read(out, msg.{_member_path(f)});") for f in i.fields)
        else:  # one row for each element of the array of messages
            out = "ybgc::Rows& rows"
            lines = (Line(1, f"ybgc::ros2::forEach(msg.{_member_path(i.each)}, [&rows](const auto& element) {{"),
                     Line(2, "ybgc::Mux& row = rows.emplace_back();"),
                     *(Line(2, f"ybgc::ros2::read(row, element.{_member_path(f)});") for f in i.fields),
                     Line(1, "});"))
    except LoweringError as e:
        raise e.at(where)
    c_type = f"{pkg}__msg__{name}"
    function = f"read_{member}_{k}"
    entry = (Line(2, f"ybgc::ros2::topic<{c_type}, &{c_type}__create, &{c_type}__destroy, &{function}>("),
             Line(3, f"{index}, {cpp_string(i.name)}, {cpp_string(f'{pkg}/msg/{name}')}, "
                     f"ROSIDL_GET_MSG_TYPE_SUPPORT({pkg}, msg, {name}){_end(i)}"))
    what = f"{comment(i.name)} ({comment(f'{pkg}/msg/{name}')}): {comment(' '.join(i.fields))}"
    if i.each is not None:
        what = (f"{comment(i.name)} ({comment(f'{pkg}/msg/{name}')}): a row for each element of "
                f"{comment(i.each)}, {comment(' '.join(i.fields))}")
    return TopicReaderView(function, c_type, out, what, lines, entry)


def lower(program: ir.Program, members: dict[str, str]) -> Ros2InputsView:
    """The readers of ``program``'s ROS 2 inputs; ``members``: the C++ member of each mux."""
    readers = []
    includes = set()
    index = 0
    for m in program.muxes:
        for k, i in enumerate(m.inputs):
            if i.kind == "ros2":
                reader = _reader(program, m, k, i, index, members[m.name])
                readers.append(reader)
                includes.add(c_header(i.ros_type or ""))
            index += 1
    return Ros2InputsView(
        node=cpp_string(node_name(program)),
        includes=tuple(sorted(includes)),
        readers=tuple(readers),
        packages=tuple(sorted(set(used_packages(program)) | set(RUNTIME_PACKAGES))),
    )


__all__ = ["Ros2InputsView", "TopicReaderView", "lower"]
