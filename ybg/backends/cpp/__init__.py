"""The ``cpp`` backend: one C++17 source and its CMakeLists.txt, a YARP
module that reads YARP ports or ROS 1 topics and writes a Bottle on a YARP
port or a ROS 1 topic (YARP's topic@node ports, with the type promised).

The source is made of two templates: ``_runtime.cpp.j2`` (inputs, layout
checks, freshness, converters, timing, connections, shutdown; the same in
every module) and ``module.cpp.j2`` (this bridge's description, its muxes,
the message builder and the places for custom code). :mod:`.lower` makes
every decision and escapes every value with :mod:`.escape`; the templates
only print.
"""

from __future__ import annotations

import functools
from pathlib import Path

import jinja2

from ybg.backends import Backend, RenderOptions, code_filter, indent_line_filter, template_environment
from ybg.backends.cpp.lower import LoweringError, lower

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"


@functools.lru_cache(maxsize=None)
def environment() -> jinja2.Environment:
    return template_environment([TEMPLATE_DIR], {
        "code": code_filter,
        "indent_line": indent_line_filter,
    })


class CppBackend(Backend):
    name = "cpp"
    description = "a C++17 YARP module (one source and its CMakeLists.txt)"
    output_kinds = frozenset({"yarp", "ros1"})
    input_kinds = frozenset({"yarp", "ros1"})

    def render(self, program, options: RenderOptions = RenderOptions()) -> dict[str, str]:
        view = lower(program)
        env = environment()
        return {
            view.filename: env.get_template("module.cpp.j2").render(m=view),
            "CMakeLists.txt": env.get_template("CMakeLists.txt.j2").render(m=view),
        }


__all__ = ["CppBackend", "LoweringError", "TEMPLATE_DIR", "environment"]
