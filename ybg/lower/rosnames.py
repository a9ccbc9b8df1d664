"""ROS naming, as every backend that speaks ROS 2 needs it: message type
names split and checked, ROS 2 type names, package, node and header names,
the packages a program uses, and the node's parameters."""

from __future__ import annotations

import keyword
import re

from ybg.compiler import ir
from ybg.lower.errors import LoweringError
from ybg.lower.tree import message_types

_PKG = re.compile(r"[a-z][a-z0-9_]*\Z")
_MSG_NAME = re.compile(r"[A-Za-z][A-Za-z0-9]*\Z")


def identifier(name: str, what: str) -> str:
    """``name`` if it is a Python identifier that is no keyword (a node,
    module or field name that generated code writes as a name)."""
    if not name.isidentifier() or keyword.iskeyword(name) or not name.isascii():
        raise LoweringError(f"{what} {name!r} is not a Python identifier")
    return name


def split_type(msg_type: str) -> tuple[str, str]:
    """``pkg/Name`` or ``pkg/msg/Name`` -> (pkg, Name), both checked."""
    parts = msg_type.split("/")
    if len(parts) == 3 and parts[1] == "msg":
        parts = [parts[0], parts[2]]
    if len(parts) != 2 or not _PKG.match(parts[0]) or not _MSG_NAME.match(parts[1]) \
            or keyword.iskeyword(parts[0]):
        raise LoweringError(f"{msg_type!r} is not a ROS message type name (pkg/Name)")
    return parts[0], parts[1]


def ros2_type_name(msg_type: str) -> str:
    """``pkg/Name`` -> ``pkg/msg/Name``."""
    pkg, name = split_type(msg_type)
    return f"{pkg}/msg/{name}"


def snake_case(name: str) -> str:
    """A message name as rosidl names its header (``JointState`` -> ``joint_state``)."""
    name = re.sub(r"(.)([A-Z][a-z]+)", r"\1_\2", name)
    return re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", name).lower()


def package_name(module: str) -> str:
    """A ROS package name (REP 144: lower case, digits, single `_`) for ``module``."""
    name = re.sub(r"_+", "_", re.sub(r"[^a-z0-9_]", "_", module.lower())).strip("_")
    if not name or not name[0].isalpha():
        name = "ybg_" + name
    return name


def node_name(program: ir.Program) -> str:
    """The ROS 2 node's name: the output's `node`, else the module's name."""
    node = (program.output.node or "").strip("/") if program.output.kind == "ros2" else ""
    if node and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", node):
        return node
    return identifier(program.module, "module name")


def used_packages(program: ir.Program) -> tuple[str, ...]:
    """The ROS packages whose messages the node uses, sorted."""
    types: set[str] = set()
    if program.output.kind == "ros2":
        if program.output.msg_type:
            types.add(program.output.msg_type)
        message_types(program.message, types)
    for m in program.muxes:
        for i in m.inputs:
            if i.kind == "ros2" and i.ros_type:
                types.add(i.ros_type)
    return tuple(sorted({split_type(t)[0] for t in types if t not in ("time", "duration")}))


def node_parameters(program: ir.Program) -> tuple[tuple[str, object], ...]:
    """The node's parameters a launch file gives, with their defaults from the
    config (the rclpy node's and the native C++ module's alike)."""
    rate = program.timing.rate
    return (
        ("rate", 0.0 if rate is None else float(rate)),
        ("timeout", 0.0),
        ("prefix", "/" + program.module),
        ("verbose", False),
        ("diagnostics", True),
    )


__all__ = ["identifier", "split_type", "ros2_type_name", "snake_case", "package_name", "node_name",
           "used_packages", "node_parameters"]
