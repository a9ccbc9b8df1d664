"""The ``py`` backend: a Python module (``yarp`` and the standard library
only) that reads YARP ports or ROS 1 topics and writes a Bottle on a YARP
port or a ROS 1 topic.

The module (``module.py.j2``) holds this bridge's data, the message builder
and the places for custom code; it runs on the runtime library
(:mod:`ybg.runtime`: ``core`` and ``yarp_io``), written beside it as
``ybgc_runtime/`` or inlined with ``--single-file``
(:mod:`ybg.backends.runtime`); its yarpmanager application ``<module>.xml``
beside it (:mod:`ybg.lower.yarpmanager`). :mod:`.lower` makes every decision; the
templates only print.
"""

from __future__ import annotations

import functools
from pathlib import Path

import jinja2

from ybg.backends.base import Backend, BridgeKind, RenderOptions
from ybg.backends.py.lower import lower
from ybg.backends.runtime import PY_STREAM_MODULES, python_files, runtime_text_filter, runtime_view
from ybg.lower import yarpmanager
from ybg.lower.errors import LoweringError
from ybg.lower.python import PYTHON_FILTERS
from ybg.lower.templates import template_environment

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"


#: the template filters of the Python module
FILTERS = {**PYTHON_FILTERS, "runtime_text": runtime_text_filter}


@functools.lru_cache(maxsize=None)
def environment() -> jinja2.Environment:
    return template_environment([TEMPLATE_DIR], FILTERS)


class StreamModule(BridgeKind):
    """A stream bridge's Python module on the runtime library, and its
    yarpmanager application."""

    def render(self, program, options: RenderOptions) -> dict[str, str]:
        view = lower(program)
        rt = runtime_view("py", options.single_file, PY_STREAM_MODULES)
        files = {view.filename: environment().get_template("module.py.j2").render(m=view, rt=rt)}
        if not options.single_file:
            files.update(python_files())
        files[yarpmanager.filename(program)] = yarpmanager.application(
            program, "python3", view.filename, options.extra.get("workdir"))
        return files

    def lower(self, program) -> None:
        lower(program)  # the module's lowering (ybg.backends.py.lower), without the templates


class PyBackend(Backend):
    name = "py"
    bridge_kinds = {"stream": StreamModule()}

    def compose(self, programs, name: str, options: RenderOptions = RenderOptions()) -> dict[str, str]:
        """One process of the programs' bridges (.compose, docs/compose.md)."""
        from ybg.backends.py.compose import compose

        return compose(programs, name, options)


__all__ = ["PyBackend", "LoweringError", "TEMPLATE_DIR", "FILTERS", "environment"]
