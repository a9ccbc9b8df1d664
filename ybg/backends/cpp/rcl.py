"""ROS 2 names as the C++ module meets them through rcl and rosidl's C
type support: a message's C struct and header, and the message packages
the runtime's ROS 2 side links itself."""

from __future__ import annotations

from ybg.lower.rosnames import snake_case, split_type

#: the message packages the runtime's ROS 2 side uses itself: builtin_interfaces
#: (stamps), rosgraph_msgs (/clock, use_sim_time), diagnostic_msgs and std_msgs (/diagnostics)
RUNTIME_PACKAGES = ("builtin_interfaces", "diagnostic_msgs", "rosgraph_msgs", "std_msgs")


def c_struct(msg_type: str) -> str:
    """The C struct of a message type (``geometry_msgs/Point`` -> ``geometry_msgs__msg__Point``)."""
    pkg, name = split_type(msg_type)
    return f"{pkg}__msg__{name}"


def c_header(msg_type: str) -> str:
    """The header that declares a message's C struct and its functions."""
    pkg, name = split_type(msg_type)
    return f"{pkg}/msg/{snake_case(name)}.h"


__all__ = ["RUNTIME_PACKAGES", "c_struct", "c_header"]
