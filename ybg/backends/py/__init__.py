"""The ``py`` backend: one self-contained Python module (``yarp`` and the
standard library only) that reads YARP ports or ROS 1 topics and writes a
Bottle on a YARP port or a ROS 1 topic.

The generated module is made of three templates: ``_runtime.py.j2`` (inputs,
freshness, converters, timing, message tree, shutdown; shared with other
Python backends), ``_yarp_output.py.j2`` (the message tree as a Bottle) and
``module.py.j2`` (this bridge's data, the message builder, the places for
custom code). :mod:`.lower` makes every decision; the templates only print.
"""

from __future__ import annotations

import functools
from pathlib import Path

import jinja2

from ybg.backends import Backend, RenderOptions, code_filter, indent_line_filter, template_environment
from ybg.backends.py.lower import LoweringError, lower, py_literal

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"
#: the shared runtime, for other Python backends to include
RUNTIME_TEMPLATE = "_runtime.py.j2"


def _int_literal(value) -> str:
    if not isinstance(value, int) or isinstance(value, bool):
        raise TypeError(f"expected an int, got {type(value).__name__}")
    return py_literal(value)


#: the template filters of a Python module (the ros2 backend uses them too)
FILTERS = {
    "code": code_filter,
    "int_literal": _int_literal,
    "indent_line": indent_line_filter,
    "pyliteral": py_literal,
}


@functools.lru_cache(maxsize=None)
def environment() -> jinja2.Environment:
    return template_environment([TEMPLATE_DIR], FILTERS)


class PyBackend(Backend):
    name = "py"
    description = "a self-contained Python module on YARP's Python bindings"
    output_kinds = frozenset({"yarp", "ros1"})
    input_kinds = frozenset({"yarp", "ros1"})

    def render(self, program, options: RenderOptions = RenderOptions()) -> dict[str, str]:
        view = lower(program)
        text = environment().get_template("module.py.j2").render(m=view)
        return {view.filename: text}


__all__ = ["PyBackend", "LoweringError", "TEMPLATE_DIR", "RUNTIME_TEMPLATE", "FILTERS", "environment"]
