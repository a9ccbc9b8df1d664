"""Backends: lower a checked :class:`~ybg.compiler.ir.Program` to files.

Each backend is one package (``cpp/``, ``py/``, ``ros2/``) with its own
``templates/``. A backend only reads the IR and returns ``{relative path:
text}``; writing files (atomically, only when changed) is the CLI's job.
Lowering decisions are made in Python; templates only print.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ybg.compiler.ir import Program


class LoweringError(ValueError):
    """A program that a backend cannot build; the message says why. The CLI
    reports it as an error (exit status 1), never as a traceback."""


@dataclass(frozen=True)
class RenderOptions:
    """Options every backend accepts. ``package``: also emit the packaging
    around the module (ament_python package for ``ros2``)."""

    package: bool = False
    extra: dict = field(default_factory=dict)


class Backend:
    """Base class of a backend. Subclasses set ``name``/``description`` and
    implement :meth:`render`."""

    name: str = ""
    description: str = ""
    #: the IR ``output.kind`` values and input kinds this backend can build
    output_kinds: frozenset[str] = frozenset()
    input_kinds: frozenset[str] = frozenset()

    def render(self, program: "Program", options: RenderOptions = RenderOptions()) -> dict[str, str]:
        raise NotImplementedError


@dataclass(frozen=True)
class BackendInfo:
    """What the registry knows of a backend without importing it: where it is,
    and which IR output and input kinds it builds (``ybgc check --backend``)."""

    target: str  # "module:Class"
    output_kinds: frozenset[str]
    input_kinds: frozenset[str]


_YARP = frozenset({"yarp", "ros1"})

#: name -> backend, imported on first use so ``ybgc check`` stays quick
REGISTRY: dict[str, BackendInfo] = {
    "cpp": BackendInfo("ybg.backends.cpp:CppBackend", _YARP, _YARP),
    "py": BackendInfo("ybg.backends.py:PyBackend", _YARP, _YARP),
    "ros2": BackendInfo("ybg.backends.ros2:Ros2Backend", frozenset({"ros2", "yarp"}),
                        frozenset({"yarp", "ros2"})),
}


def get_backend(name: str) -> Backend:
    """The backend registered as ``name`` (KeyError if there is none)."""
    target = REGISTRY[name].target
    module_name, cls_name = target.split(":")
    module = importlib.import_module(module_name)
    return getattr(module, cls_name)()


def backend_names() -> list[str]:
    return sorted(REGISTRY)
