"""The ``ros2`` backend: an rclpy node between YARP ports and ROS 2 topics.

``<module>_node.py`` is one Python file (rclpy, the ``yarp`` bindings and the
standard library). It is made of the ``py`` backend's shared runtime
(``_runtime.py.j2``: inputs, freshness, converters, timing, shutdown), the
ROS 2 side (``_ros2_node.py.j2``: topics as inputs, typed messages, the
node's clock and parameters), for a Bottle output the ``py`` backend's
``_yarp_output.py.j2``, and ``node.py.j2`` (this bridge's data and message
builder). With ``RenderOptions(package=True)`` the files of an
ament_python package are generated around it. :mod:`.lower` makes every
decision; the templates only print.
"""

from __future__ import annotations

import functools
import re
from pathlib import Path
from xml.sax.saxutils import escape as _xml_escape

import jinja2

from ybg.backends import Backend, RenderOptions, template_environment
from ybg.backends.py import FILTERS as PY_FILTERS
from ybg.backends.py import TEMPLATE_DIR as PY_TEMPLATE_DIR
from ybg.backends.py.lower import LoweringError
from ybg.backends.ros2.lower import lower, lower_package

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"


def _xml(text) -> str:
    """Text for an XML element or attribute value."""
    if not isinstance(text, str):
        raise TypeError(f"expected a str, got {type(text).__name__}")
    return _xml_escape(text, {'"': "&quot;", "'": "&apos;"})


def _xml_comment(text) -> str:
    """Text for inside an XML comment (which cannot hold ``--``)."""
    return _xml(text).replace("--", "- -")


def _package_name(text) -> str:
    """A ROS package name, checked (it is printed unquoted in setup.cfg)."""
    if not isinstance(text, str) or not re.fullmatch(r"[a-z][a-z0-9_]*", text):
        raise ValueError(f"{text!r} is not a ROS package name")
    return text


def _py_comment(text) -> str:
    """Text for a Python comment: one line."""
    if not isinstance(text, str):
        raise TypeError(f"expected a str, got {type(text).__name__}")
    return " ".join(text.splitlines())


@functools.lru_cache(maxsize=None)
def environment() -> jinja2.Environment:
    """Templates of this backend first, then the ``py`` backend's shared ones."""
    return template_environment([TEMPLATE_DIR, PY_TEMPLATE_DIR], {
        **PY_FILTERS,
        "xml": _xml,
        "xml_comment": _xml_comment,
        "py_comment": _py_comment,
        "package_name": _package_name,
    })


class Ros2Backend(Backend):
    name = "ros2"
    description = "an rclpy node between YARP ports and ROS 2 topics (optionally an ament_python package)"
    output_kinds = frozenset({"ros2", "yarp"})
    input_kinds = frozenset({"yarp", "ros2"})

    def render(self, program, options: RenderOptions = RenderOptions()) -> dict[str, str]:
        view = lower(program)
        env = environment()
        node = env.get_template("node.py.j2").render(m=view)
        if not options.package:
            return {view.filename: node}
        pkg = lower_package(program, view)
        files = {
            f"{pkg.package}/{view.filename}": node,
            f"{pkg.package}/__init__.py": env.get_template("package_init.py.j2").render(p=pkg),
            "package.xml": env.get_template("package.xml.j2").render(p=pkg),
            "setup.py": env.get_template("setup.py.j2").render(p=pkg),
            "setup.cfg": env.get_template("setup.cfg.j2").render(p=pkg),
            f"resource/{pkg.package}": env.get_template("resource_marker.j2").render(p=pkg),
            f"launch/{pkg.launch_file}": env.get_template("launch.py.j2").render(p=pkg),
        }
        return files


__all__ = ["Ros2Backend", "LoweringError", "TEMPLATE_DIR", "environment"]
