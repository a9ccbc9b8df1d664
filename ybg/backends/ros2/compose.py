"""``ybgc compose --backend ros2``: several configs, one process of rclpy
nodes (docs/compose.md).

Each bridge is the node that ``ybgc generate`` makes for its config, printed
by the same lowering and template, in ``bridges/`` (``<package>/bridges/``
with ``--package``); the composed module ``<name>_node.py`` imports each and
runs them all on the runtime (``ros2_io.run_composed``): one rclpy context,
one node per bridge with its own name, parameters and threads, one RPC port
``/<name>/rpc:i``. With ``--package``: one ament_python package, one
executable, and a launch file that gives each node its parameters from a
parameter file keyed by node name (``config/<name>.yaml``). A config of
commands is a bridge too: its node as ``services_node.py.j2`` prints it, run
by the runtime's ``services.ComposedCommands``.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import jinja2

from ybg.backends.base import RenderOptions
from ybg.backends.runtime import PY_PACKAGE, python_files, runtime_text_filter, runtime_view
from ybg.lower.compose import BRIDGES, config_at, config_file, refusal
from ybg.lower.errors import LoweringError
from ybg.lower.package import YAML_FILTERS, NodeParameters
from ybg.lower.python import PYTHON_FILTERS, py_literal
from ybg.lower.rosnames import node_name, node_parameters, package_name, used_packages
from ybg.lower.templates import py_comment_filter, template_environment, xml_comment_filter, xml_filter



@dataclass(frozen=True)
class MemberView:
    """One bridge of the composed module; literals, but ``node_name`` and
    ``summary`` (comment text)."""

    module: str
    config: str
    at: str
    where: str
    node_name: str
    summary: str


@dataclass(frozen=True)
class ComposedView:
    filename: str
    name: str          # a literal
    name_text: str     # for comments
    config_count: int
    bridge_count: int
    bridges_folder: str
    members: tuple[MemberView, ...]
    package: bool


@dataclass(frozen=True)
class ComposedPackageView:
    """The ament_python package of a composed module (raw values: each
    template escapes them for its file)."""

    config: str
    package: str
    node_module: str
    executable: str
    description: str
    depends: tuple[str, ...]
    launch_file: str
    params_file: str
    nodes: tuple[str, ...]
    node_parameters: tuple[NodeParameters, ...]


@functools.lru_cache(maxsize=None)
def environment() -> jinja2.Environment:
    from ybg.backends.ros2 import TEMPLATE_DIR, _package_name

    return template_environment([TEMPLATE_DIR], {
        **PYTHON_FILTERS,
        "runtime_text": runtime_text_filter,
        "xml": xml_filter,
        "xml_comment": xml_comment_filter,
        "py_comment": py_comment_filter,
        "package_name": _package_name,
        **YAML_FILTERS,
    })


def compose(programs, name: str, options: RenderOptions = RenderOptions()) -> dict[str, str]:
    """The files of the composed module ``name`` of ``programs`` (docs/compose.md)."""
    from ybg.backends.ros2 import Ros2Backend, environment as node_environment

    views = []
    nodes: dict[str, str] = {}
    for program in programs:
        try:
            view = Ros2Backend().kind(program).view(program)
        except LoweringError as e:
            if getattr(e, "module", None) is None:
                e.module = program.module
            raise
        node = node_name(program)
        if node in nodes:
            span = program.span
            raise refusal(program, f"its node name {node} is also that of the bridge {nodes[node]}: two nodes "
                                    "of one name in one process (set `node` in its [output])", span)
        nodes[node] = program.module
        views.append((program, view))

    env = node_environment()
    composed_env = environment()
    package = package_name(name) if options.package else None
    rt = runtime_view("py", False)
    if package is None:
        rt_import, rt_package, bridge_import, bridge_package = (f"import {PY_PACKAGE}", PY_PACKAGE,
                                                                f"import {PY_PACKAGE}", PY_PACKAGE)
        folder = ""
    else:
        rt_import, rt_package = f"from . import {PY_PACKAGE}", f".{PY_PACKAGE}"
        bridge_import, bridge_package = f"from .. import {PY_PACKAGE}", f"..{PY_PACKAGE}"
        folder = f"{package}/"

    files: dict[str, str] = {}
    members = []
    for program, view in views:
        template = env.get_template(Ros2Backend().kind(program).template)
        files[f"{folder}{BRIDGES}/{view.filename}"] = template.render(
            m=view, rt=rt, rt_import=bridge_import, rt_package=bridge_package)
        stem = view.filename[: -len(".py")]
        where = f"{BRIDGES}/{view.filename}" if package is None else f".{BRIDGES}.{stem}"
        config = config_file(program)
        members.append(MemberView(
            module=py_literal(program.module), config=py_literal(config), at=py_literal(config_at(program)),
            where=py_literal(where), node_name=node_name(program),
            summary=Ros2Backend().kind(program).describe(program)))
    filename = f"{name}_node.py"
    composed = ComposedView(filename=filename, name=py_literal(name), name_text=name,
                            config_count=len(programs), bridge_count=len(programs), bridges_folder=BRIDGES,
                            members=tuple(members), package=package is not None)
    files[f"{folder}{filename}"] = composed_env.get_template("compose_node.py.j2").render(
        c=composed, rt=rt, rt_import=rt_import, rt_package=rt_package)
    if package is None:
        files.update(python_files())
        return files

    configs = ", ".join(config_file(p) for p in programs)
    depends: list[str] = ["rclpy", "diagnostic_msgs"]
    for program in programs:
        used = used_packages(program)
        depends.extend(p for p in used if p not in depends)
    pkg = ComposedPackageView(
        config=f"{len(programs)} configs ({configs})",
        package=package,
        node_module=filename[: -len(".py")],
        executable=filename[: -len(".py")],
        description=f"{len(programs)} bridges between YARP and ROS 2 in one process, generated by ybgc "
                    f"(ybgc compose) from {configs}.",
        depends=tuple(depends),
        launch_file=f"{name}.launch.py",
        params_file=f"{name}.yaml",
        nodes=tuple(node_name(program) for program, _ in views),
        node_parameters=tuple(NodeParameters(node_name(program), node_parameters(program)) for program, _ in views),
    )
    files.update({
        f"{package}/__init__.py": env.get_template("package_init.py.j2").render(p=pkg),
        f"{package}/{BRIDGES}/__init__.py": composed_env.get_template("compose_bridges_init.py.j2").render(p=pkg),
        "package.xml": env.get_template("package.xml.j2").render(p=pkg),
        "setup.py": composed_env.get_template("compose_setup.py.j2").render(p=pkg, runtime_package=PY_PACKAGE),
        "setup.cfg": env.get_template("setup.cfg.j2").render(p=pkg),
        f"resource/{package}": env.get_template("resource_marker.j2").render(p=pkg),
        f"launch/{pkg.launch_file}": composed_env.get_template("compose_launch.py.j2").render(p=pkg),
        f"config/{pkg.params_file}": composed_env.get_template("compose_params.yaml.j2").render(p=pkg),
    })
    files.update(python_files(f"{package}/{PY_PACKAGE}"))
    return files


__all__ = ["compose", "environment"]
