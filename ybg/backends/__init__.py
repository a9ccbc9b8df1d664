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

from ybg.backends.wire import WIRE_ROS1, WIRE_YARP  # noqa: F401  (re-exported: the lowerings import them from here)

if TYPE_CHECKING:
    import jinja2

    from ybg.compiler.ir import Program


class LoweringError(ValueError):
    """A program that a backend cannot build; the message says why. The CLI
    reports it as an error (exit status 1), never as a traceback."""


@dataclass(frozen=True)
class Line:
    """One line of generated code, already made of escaped parts."""

    indent: int
    text: str


def code_filter(text) -> str:
    """Template filter: a one-line fragment of code that lowering already built
    from escaped parts (anything else is a bug, not something to print)."""
    if not isinstance(text, str):
        raise TypeError(f"expected lowered code, got {type(text).__name__}")
    if "\n" in text or "\r" in text:
        raise ValueError("lowered code must be one line")
    return text


def indent_line_filter(line: Line) -> str:
    """Template filter: a :class:`Line` at its indentation (4 spaces a level)."""
    if not isinstance(line, Line):
        raise TypeError(f"expected a Line, got {type(line).__name__}")
    return "    " * line.indent + code_filter(line.text)


def template_environment(folders, filters: dict) -> "jinja2.Environment":
    """The Jinja environment of a backend: templates only print (autoescape
    off, undefined names are errors, whitespace as written), and every value
    reaches them through one of ``filters``."""
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader([str(f) for f in folders]),
        autoescape=False,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    env.filters.update(filters)
    return env


@dataclass(frozen=True)
class RenderOptions:
    """Options every backend accepts. ``package``: also emit the packaging
    around the module (ament_python package for ``ros2``). ``single_file``:
    the runtime inlined into the module, one file with no runtime beside it."""

    package: bool = False
    single_file: bool = False
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
