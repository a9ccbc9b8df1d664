"""The ROS 2 package around a module, as far as backends share it: the view
of a package and its launch file, which starts the module with the node's
parameters (the rclpy node's and the native C++ module's are the same,
:func:`~ybg.lower.rosnames.node_parameters`). Each backend makes its own
package files (ament_python, ament_cmake); the launch file is one template,
here."""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ybg.lower.python import py_literal
from ybg.lower.templates import py_comment_filter, template_environment

if TYPE_CHECKING:
    import jinja2

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"


@dataclass(frozen=True)
class PackageView:
    """A ROS 2 package around a module, and its launch file. Raw values: the
    package templates escape each one for its file (XML, Python)."""

    config: str
    package: str
    node_module: str
    executable: str
    node_name: str
    description: str
    depends: tuple[str, ...]
    launch_file: str
    parameters: tuple[tuple[str, object], ...]


@functools.lru_cache(maxsize=None)
def _environment() -> "jinja2.Environment":
    return template_environment([TEMPLATE_DIR], {"pyliteral": py_literal, "py_comment": py_comment_filter})


def launch_file(view: PackageView) -> str:
    """The text of ``launch/<module>.launch.py`` for the package ``view``."""
    return _environment().get_template("launch.py.j2").render(p=view)


__all__ = ["PackageView", "launch_file", "TEMPLATE_DIR"]
