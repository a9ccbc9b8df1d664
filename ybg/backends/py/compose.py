"""``ybgc compose --backend py``: several configs, one process of YARP
bridges (docs/compose.md).

Each bridge is the module that ``ybgc generate`` makes for its config,
printed by the same lowering and template, in ``bridges/``; the composed
module ``<name>.py`` loads each and runs them all on the runtime
(``compose.run_bridges``), with one RPC port ``/<name>/rpc:i``; its
yarpmanager application ``<name>.xml`` beside it starts it and makes every
bridge's connections.
"""

from __future__ import annotations

import functools
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import jinja2

from ybg.backends.base import RenderOptions
from ybg.backends.runtime import VERSION, python_files, runtime_view
from ybg.lower import yarpmanager
from ybg.lower.errors import LoweringError
from ybg.lower.python import py_literal
from ybg.lower.templates import py_comment_filter, template_environment

from .lower import lower

#: the folder of the bridges' modules, beside the composed module
BRIDGES = "bridges"


@dataclass(frozen=True)
class MemberView:
    module: str
    config: str
    at: str
    where: str
    summary: str


@dataclass(frozen=True)
class ComposedView:
    filename: str
    name: str
    name_text: str
    config_count: int
    bridge_count: int
    bridges_folder: str
    members: tuple[MemberView, ...]


@functools.lru_cache(maxsize=None)
def composed_environment() -> jinja2.Environment:
    from ybg.backends.py import FILTERS, TEMPLATE_DIR

    return template_environment([TEMPLATE_DIR], {**FILTERS, "py_comment": py_comment_filter})


def _config(program) -> str:
    return os.path.basename(program.source) if program.source else program.module


def _at(program) -> str:
    span = program.output.span
    return f"{_config(program)}:{span.line}:{span.column}" if span is not None else _config(program)


def compose(programs, name: str, options: RenderOptions = RenderOptions()) -> dict[str, str]:
    """The files of the composed module ``name`` of ``programs``."""
    from ybg.backends.py import environment

    if options.package:
        e = LoweringError("the py backend makes no package (--package is the ros2 and cpp backends')")
        e.module = programs[0].module
        raise e
    env = environment()
    rt = runtime_view("py", False, ("geometry", "core", "yarp_io"))
    files: dict[str, str] = {}
    members = []
    template = env.get_template("module.py.j2")
    for program in programs:
        try:
            view = lower(program)
        except LoweringError as e:
            if getattr(e, "module", None) is None:
                e.module = program.module
            raise
        files[f"{BRIDGES}/{view.filename}"] = template.render(m=view, rt=rt)
        out = program.output
        what = f"{out.msg_type or 'untyped'} Bottles on {'the ROS 1 topic' if out.kind == 'ros1' else 'the YARP port'} " \
               f"{out.name}"
        members.append(MemberView(py_literal(program.module), py_literal(_config(program)), py_literal(_at(program)),
                                  py_literal(f"{BRIDGES}/{view.filename}"), f"{program.module}: {what}"))
    filename = f"{name}.py"
    view = ComposedView(filename, py_literal(name), name, len(programs), len(programs), BRIDGES, tuple(members))
    files[filename] = composed_environment().get_template("compose_module.py.j2").render(c=view, rt=rt)
    files.update(python_files())
    files[f"{name}.xml"] = application(programs, name, filename, options.extra.get("workdir"))
    return files


def application(programs, name: str, filename: str, workdir: str | None) -> str:
    """The yarpmanager application of the composed module: the module, and
    every bridge's connections (ybg.lower.yarpmanager.connections)."""
    configs = ", ".join(_config(p) for p in programs)
    app = ET.Element("application")

    def text(parent, tag, value):
        element = ET.SubElement(parent, tag)
        element.text = value
        return element

    text(app, "name", name)
    text(app, "description",
         f"The ybgc composed module {name}: {len(programs)} bridges in one process, from {configs}. Start "
         f"`yarprun --server {yarpmanager.NODE}` where it runs, then `yarpmanager-console --application {name}.xml "
         f"--run --connect` (or open it in yarpmanager). Its RPC port /{name}/rpc:i answers help, stats, quit.")
    text(app, "version", VERSION)
    module = ET.SubElement(app, "module")
    text(module, "name", "python3")
    text(module, "parameters", filename)
    text(module, "node", yarpmanager.NODE)
    if workdir is not None:
        text(module, "workdir", workdir)
    for program in programs:
        for source, destination in yarpmanager.connections(program):
            link = ET.SubElement(app, "connection")
            text(link, "from", source)
            text(link, "to", destination)
            text(link, "protocol", "tcp")
    ET.indent(app, space="    ")
    configs = configs.replace("--", "-")
    return ('<?xml version="1.0" encoding="UTF-8"?>\n'
            f"<!-- Generated by ybgc {VERSION} from {configs}; do not edit: generating the module again "
            "rewrites it. -->\n"
            + ET.tostring(app, encoding="unicode") + "\n")


__all__ = ["compose", "application", "BRIDGES"]
