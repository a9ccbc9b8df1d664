"""The backends, by name: where each is, what it makes, and what it builds
(its :class:`~ybg.backends.base.Builds` declaration), known without
importing it, so that ``ybgc check --backend`` stays quick. A new backend is
one package under ``ybg/backends/`` and one entry here."""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import TYPE_CHECKING

from ybg.backends.base import Builds

if TYPE_CHECKING:
    from ybg.backends.base import Backend


@dataclass(frozen=True)
class BackendInfo:
    """``target``: ``"module:Class"``; ``description``: what it makes (the
    command's help); ``builds``: what it builds."""

    target: str
    description: str
    builds: Builds


_PY_TO_ROS1 = ("YARP's Python bindings cannot promise the type that would let the module send the message "
               "serialized itself")

#: name -> backend
REGISTRY: dict[str, BackendInfo] = {
    "cpp": BackendInfo(
        "ybg.backends.cpp:CppBackend",
        "a C++17 YARP module and its CMakeLists.txt, on ybgc's C++ runtime library "
        "(ROS 2 outputs and inputs through rcl)",
        Builds(
            outputs=frozenset({"yarp", "ros1", "ros2"}),
            inputs=frozenset({"yarp", "ros1", "ros2"}),
            features={"yarp": frozenset({"fixed_array", "message_array", "rows", "image"}),
                      "ros1": frozenset({"fixed_array", "message_array", "rows"}),
                      "ros2": frozenset({"fixed_array", "message_array", "image"})},
            why={("ros2", "rows"): "a ROS 2 message is not filled from rows",
                 ("ros1", "image"): "camera images are bridged to and from ROS 2"},
            kinds=frozenset({"stream", "commands"}),
            why_not={"actions": "the C++ module does not serve ROS 2 actions yet (rcl_action is to come); the "
                                "ros2 backend's node does"},
            composes=frozenset({"stream", "commands"}),
        )),
    "py": BackendInfo(
        "ybg.backends.py:PyBackend",
        "a Python module on YARP's Python bindings and ybgc's Python runtime library",
        Builds(
            outputs=frozenset({"yarp", "ros1"}),
            inputs=frozenset({"yarp", "ros1"}),
            features={"yarp": frozenset({"fixed_array", "message_array"}),
                      "ros1": frozenset()},
            why={("ros1", "fixed_array"): "YARP's Bottle translation sends a length before it, which ROS 1 "
                                          "reads as its first values, and " + _PY_TO_ROS1,
                 ("ros1", "message_array"): "YARP translates a Bottle to ROS 1 by a map that has no arrays of "
                                            "messages, and " + _PY_TO_ROS1,
                 ("yarp", "image"): "a camera image goes to or comes from ROS 2, which the py module does not "
                                    "speak"},
            why_not={"commands": "a command goes between a YARP RPC port and a ROS 2 service, and the py module "
                                 "speaks no ROS 2",
                     "actions": "an action is served on ROS 2, and the py module speaks no ROS 2"},
            composes=frozenset({"stream"}),
        )),
    "ros2": BackendInfo(
        "ybg.backends.ros2:Ros2Backend",
        "an rclpy node between YARP ports and ROS 2 topics (optionally an ament_python package)",
        Builds(
            outputs=frozenset({"ros2", "yarp"}),
            inputs=frozenset({"yarp", "ros2"}),
            features={"yarp": frozenset({"fixed_array", "message_array", "rows", "image"}),
                      "ros2": frozenset({"fixed_array", "message_array", "image"})},
            why={("ros2", "rows"): "a ROS 2 message is not filled from rows"},
            kinds=frozenset({"stream", "commands", "actions"}),
            composes=frozenset({"stream", "commands", "actions"}),
        )),
}


def get_backend(name: str) -> "Backend":
    """The backend registered as ``name`` (KeyError if there is none)."""
    module_name, cls_name = REGISTRY[name].target.split(":")
    return getattr(importlib.import_module(module_name), cls_name)()


def backend_names() -> list[str]:
    return sorted(REGISTRY)


__all__ = ["BackendInfo", "REGISTRY", "get_backend", "backend_names"]
