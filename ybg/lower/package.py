"""The ROS 2 package around a module, as far as backends share it: the view
of a package and its launch file, which starts the module with the node's
parameters (the rclpy node's and the native C++ module's are the same,
:func:`~ybg.lower.rosnames.node_parameters`). Each backend makes its own
package files (ament_python, ament_cmake); the launch file is one template,
here."""

from __future__ import annotations

import functools
import json
import re
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


@dataclass(frozen=True)
class NodeParameters:
    """The parameters of one node of a composed module's parameter file."""

    name: str
    parameters: tuple[tuple[str, object], ...]


_PLAIN_KEY = re.compile(r"[A-Za-z_/][A-Za-z0-9_./]*\Z")


def yaml_key(text) -> str:
    """A YAML mapping key: plain when it is a name, else double-quoted (JSON)."""
    if not isinstance(text, str):
        raise TypeError(f"expected a str, got {type(text).__name__}")
    return text if _PLAIN_KEY.match(text) and text not in ("true", "false", "null") else json.dumps(text)


def yaml_value(value) -> str:
    """A YAML scalar of a ROS parameter: a bool, a number or a string."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (int, float)):
        return repr(value)
    if isinstance(value, str):
        return json.dumps(value)
    raise TypeError(f"not a parameter value: {value!r}")


#: the filters of a parameter file's template
YAML_FILTERS = {"yaml_key": yaml_key, "yaml_value": yaml_value}


@functools.lru_cache(maxsize=None)
def _environment() -> "jinja2.Environment":
    return template_environment([TEMPLATE_DIR], {"pyliteral": py_literal, "py_comment": py_comment_filter})


def launch_file(view: PackageView) -> str:
    """The text of ``launch/<module>.launch.py`` for the package ``view``."""
    return _environment().get_template("launch.py.j2").render(p=view)


__all__ = ["PackageView", "NodeParameters", "launch_file", "yaml_key", "yaml_value", "YAML_FILTERS", "TEMPLATE_DIR"]
