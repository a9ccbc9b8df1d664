"""The ``ros2`` backend: an rclpy node between YARP ports and ROS 2 topics.

``<module>_node.py`` (``node.py.j2``) holds this bridge's data and message
builder; it runs on the runtime library (:mod:`ybg.runtime`: ``core``,
``yarp_io`` and ``ros2_io``, the node's side: topics as inputs, typed
messages, the node's clock and parameters), written beside it as
``ybgc_runtime/`` or inlined with ``--single-file``. With
``RenderOptions(package=True)`` the files of an ament_python package are
generated around it, the runtime inside the package. :mod:`.lower` makes
every decision; the templates only print.

A config of commands (:class:`~ybg.compiler.ir.Commands`: YARP RPC ports and
ROS 2 services, docs/services.md) is lowered by :mod:`.services` and printed
by ``services_node.py.j2``; it runs on the runtime's ``services`` module. A
config of actions (:class:`~ybg.compiler.ir.Actions`, docs/actions.md) is
lowered by :mod:`.actions` and printed by ``actions_node.py.j2``, on the
runtime's ``actions`` module.
"""

from __future__ import annotations

import functools
import re
from pathlib import Path

import jinja2

from ybg.backends.base import Backend, BridgeKind, RenderOptions
from ybg.backends.ros2 import actions, services
from ybg.backends.ros2.lower import lower, lower_package
from ybg.backends.runtime import (PY_ACTIONS_MODULES, PY_COMMANDS_MODULES, PY_NODE_MODULES, PY_PACKAGE,
                                  python_files, runtime_text_filter, runtime_view)
from ybg.lower.errors import LoweringError
from ybg.lower.package import launch_file
from ybg.lower.python import PYTHON_FILTERS
from ybg.lower.rosnames import ros2_type_name
from ybg.lower.templates import py_comment_filter, template_environment, xml_comment_filter, xml_filter

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"
#: the runtime modules a node inlines with --single-file: a stream node's,
#: and a node of commands'
STREAM_MODULES = PY_NODE_MODULES
COMMANDS_MODULES = PY_COMMANDS_MODULES


def _package_name(text) -> str:
    """A ROS package name, checked (it is printed unquoted in setup.cfg)."""
    if not isinstance(text, str) or not re.fullmatch(r"[a-z][a-z0-9_]*", text):
        raise ValueError(f"{text!r} is not a ROS package name")
    return text


@functools.lru_cache(maxsize=None)
def environment() -> jinja2.Environment:
    """The templates of this backend and their filters."""
    return template_environment([TEMPLATE_DIR], {
        **PYTHON_FILTERS,
        "runtime_text": runtime_text_filter,
        "xml": xml_filter,
        "xml_comment": xml_comment_filter,
        "py_comment": py_comment_filter,
        "package_name": _package_name,
    })


def _render(view, pkg, template: str, modules: tuple[str, ...], options: RenderOptions) -> dict[str, str]:
    """The node ``view`` printed by ``template``, on the runtime's ``modules``:
    a script with the runtime beside it, or (``pkg``) an ament_python
    package around it."""
    env = environment()
    rt = runtime_view("py", options.single_file, modules)
    node = env.get_template(template)
    if not options.package:
        # a script: the runtime package beside it, on its sys.path
        files = {view.filename: node.render(m=view, rt=rt, rt_import=f"import {PY_PACKAGE}",
                                            rt_package=PY_PACKAGE)}
        if not options.single_file:
            files.update(python_files())
        return files
    files = {
        # a module of the package: the runtime a subpackage of it
        f"{pkg.package}/{view.filename}": node.render(m=view, rt=rt, rt_import=f"from . import {PY_PACKAGE}",
                                                      rt_package=f".{PY_PACKAGE}"),
        f"{pkg.package}/__init__.py": env.get_template("package_init.py.j2").render(p=pkg),
        "package.xml": env.get_template("package.xml.j2").render(p=pkg),
        "setup.py": env.get_template("setup.py.j2").render(
            p=pkg, runtime_package=None if options.single_file else PY_PACKAGE),
        "setup.cfg": env.get_template("setup.cfg.j2").render(p=pkg),
        f"resource/{pkg.package}": env.get_template("resource_marker.j2").render(p=pkg),
        f"launch/{pkg.launch_file}": launch_file(pkg),
    }
    if not options.single_file:
        files.update(python_files(f"{pkg.package}/{PY_PACKAGE}"))
    return files


class StreamNode(BridgeKind):
    """A stream bridge's node (``node.py.j2``, :mod:`.lower`)."""

    template = "node.py.j2"
    modules = STREAM_MODULES

    @staticmethod
    def view(program):
        return lower(program)

    @staticmethod
    def package(program, view):
        return lower_package(program, view)

    @staticmethod
    def describe(program) -> str:
        """What it publishes, for a comment."""
        out = program.output
        if out.kind == "ros2":
            return f"{ros2_type_name(out.msg_type or program.message.msg_type or '')} on {out.name}"
        return f"the YARP port {out.name}"

    def render(self, bridge, options: RenderOptions) -> dict[str, str]:
        view = self.view(bridge)
        return _render(view, self.package(bridge, view) if options.package else None, self.template, self.modules,
                       options)

    def lower(self, bridge) -> None:
        self.package(bridge, self.view(bridge))  # the node's and the package's lowering, without the templates


class CommandsNode(StreamNode):
    """A node of commands (``services_node.py.j2``, :mod:`.services`)."""

    template = "services_node.py.j2"
    modules = COMMANDS_MODULES

    @staticmethod
    def view(commands):
        return services.lower(commands)

    @staticmethod
    def package(commands, view):
        return services.lower_package(commands, view)

    @staticmethod
    def describe(commands) -> str:
        """What it serves, for a comment."""
        return "commands: " + ", ".join(s.service if s.serves == "ros2" else f"{s.name} on {s.port}"
                                        for s in commands.services)


class ActionsNode(StreamNode):
    """A node of actions (``actions_node.py.j2``, :mod:`.actions`)."""

    template = "actions_node.py.j2"
    modules = PY_ACTIONS_MODULES

    @staticmethod
    def view(bridge):
        return actions.lower(bridge)

    @staticmethod
    def package(bridge, view):
        return actions.lower_package(bridge, view)

    @staticmethod
    def describe(bridge) -> str:
        """What it serves, for a comment."""
        return "actions: " + ", ".join(a.action for a in bridge.actions)


class Ros2Backend(Backend):
    name = "ros2"
    bridge_kinds = {"stream": StreamNode(), "commands": CommandsNode(), "actions": ActionsNode()}

    def compose(self, programs, name: str, options: RenderOptions = RenderOptions()) -> dict[str, str]:
        """One process of the programs' nodes (.compose, docs/compose.md)."""
        from ybg.backends.ros2.compose import compose

        return compose(programs, name, options)


__all__ = ["Ros2Backend", "LoweringError", "TEMPLATE_DIR", "environment"]
