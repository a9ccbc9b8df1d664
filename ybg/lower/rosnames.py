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


def split_type(msg_type: str, interface: str = "msg") -> tuple[str, str]:
    """``pkg/Name`` or ``pkg/msg/Name`` -> (pkg, Name), both checked; of a
    service (``interface`` ``"srv"``), ``pkg/srv/Name``."""
    parts = msg_type.split("/")
    if len(parts) == 3 and parts[1] == interface:
        parts = [parts[0], parts[2]]
    if len(parts) != 2 or not _PKG.match(parts[0]) or not _MSG_NAME.match(parts[1]) \
            or keyword.iskeyword(parts[0]):
        what = {"srv": "service", "action": "action"}.get(interface, "message")
        raise LoweringError(f"{msg_type!r} is not a ROS {what} type name (pkg/Name)")
    return parts[0], parts[1]


def split_srv(srv_type: str) -> tuple[str, str]:
    """``pkg/Name`` or ``pkg/srv/Name`` -> (pkg, Name), both checked."""
    return split_type(srv_type, "srv")


def srv_type_name(srv_type: str) -> str:
    """``pkg/Name`` -> ``pkg/srv/Name``."""
    pkg, name = split_srv(srv_type)
    return f"{pkg}/srv/{name}"


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


def node_name(bridge: ir.Bridge) -> str:
    """The ROS 2 node's name: a stream's output `node`, else the module's
    name (of commands, made a ROS name)."""
    return _NODE_NAME[bridge.kind](bridge)


def _stream_node_name(program: ir.Program) -> str:
    node = (program.output.node or "").strip("/") if program.output.kind == "ros2" else ""
    if node and re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", node):
        return node
    return identifier(program.module, "module name")


def _commands_node_name(commands: ir.Commands) -> str:
    name = re.sub(r"\W", "_", commands.module, flags=re.ASCII)
    return name if re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", name) else "ybgc_" + name


def used_packages(bridge: ir.Bridge) -> tuple[str, ...]:
    """The ROS packages whose messages or services the node uses, sorted."""
    return _USED_PACKAGES[bridge.kind](bridge)


def _stream_packages(program: ir.Program) -> tuple[str, ...]:
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


def _commands_packages(commands: ir.Commands) -> tuple[str, ...]:
    return tuple(sorted({split_srv(s.srv_type)[0] for s in commands.services}))


def node_parameters(bridge: ir.Bridge) -> tuple[tuple[str, object], ...]:
    """The node's parameters a launch file gives, with their defaults from the
    config (the rclpy node's and the native C++ module's alike)."""
    return _NODE_PARAMETERS[bridge.kind](bridge)


def _stream_parameters(program: ir.Program) -> tuple[tuple[str, object], ...]:
    rate = program.timing.rate
    return (
        ("rate", 0.0 if rate is None else float(rate)),
        ("timeout", 0.0),
        ("prefix", "/" + program.module),
        ("verbose", False),
        ("diagnostics", True),
    )


def _commands_parameters(commands: ir.Commands) -> tuple[tuple[str, object], ...]:
    return (("prefix", "/" + commands.module), ("verbose", False), ("diagnostics", True))


def split_action(action_type: str) -> tuple[str, str]:
    """``pkg/Name`` or ``pkg/action/Name`` -> (pkg, Name), both checked."""
    return split_type(action_type, "action")


def action_type_name(action_type: str) -> str:
    """``pkg/Name`` -> ``pkg/action/Name``."""
    pkg, name = split_action(action_type)
    return f"{pkg}/action/{name}"


def _actions_packages(actions: ir.Actions) -> tuple[str, ...]:
    return tuple(sorted({split_action(a.action_type)[0] for a in actions.actions}))


#: kind of bridge -> each of the above (a node of actions is named and
#: takes its parameters as a node of commands)
_NODE_NAME = {"stream": _stream_node_name, "commands": _commands_node_name, "actions": _commands_node_name}
_USED_PACKAGES = {"stream": _stream_packages, "commands": _commands_packages, "actions": _actions_packages}
_NODE_PARAMETERS = {"stream": _stream_parameters, "commands": _commands_parameters, "actions": _commands_parameters}


__all__ = ["identifier", "split_type", "split_srv", "srv_type_name", "split_action", "action_type_name", "ros2_type_name", "snake_case", "package_name", "node_name",
           "used_packages", "node_parameters"]
