"""``ybgc compose --backend cpp``: several configs, one native executable
(docs/compose.md).

Each bridge is the module that ``ybgc generate`` makes for its config,
printed by the same lowering and template as alone (its kind's, a
:class:`~ybg.backends.base.BridgeKind` of the backend: ``module.cpp.j2`` for
a stream, ``services.cpp.j2`` for a config of commands), in
``bridges/<module>.cpp``: in a namespace of its own, ``bridge_<module>``,
its ``main()`` the entry ``bridge_<module>::run`` instead. The composed
module ``<name>.cpp`` (``compose.cpp.j2``) lists them and runs them on the
runtime (``ybgc_compose.*``: one YARP network, one rcl context with one
node per bridge, one RPC port ``/<name>/rpc:i``); ``CMakeLists.txt``
(``compose.CMakeLists.txt.j2``) builds one executable ``<name>`` of them
all, the runtime once, linking every message package the bridges use
once. Its yarpmanager application ``<name>.xml`` starts it and makes every
bridge's connections. With ``--package``: one ament_cmake package, one
executable, and a launch file that gives each bridge's node its parameters
from a parameter file keyed by node name (``config/<name>.yaml``).

A bridge of commands runs on the runtime's commands (``ybgc_services*``) in
the same process shell as a stream: its node on the process's rcl context,
its YARP ports served and called, its counts in the process's ``stats``.
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass

import jinja2

from ybg.backends.base import RenderOptions
from ybg.backends.runtime import CPP_COMPOSE_SOURCES, VERSION, cpp_files, runtime_view
from ybg.compiler import ir
from ybg.lower import yarpmanager
from ybg.lower.compose import BRIDGES, config_at, config_file, refusal
from ybg.lower.errors import LoweringError
from ybg.lower.package import YAML_FILTERS, NodeParameters
from ybg.lower.python import py_literal
from ybg.lower.rosnames import node_name, node_parameters, package_name
from ybg.lower.templates import (code_filter, indent_line_filter, py_comment_filter, template_environment,
                                 xml_comment_filter, xml_filter)

from .escape import comment, cpp_identifier, cpp_string



@dataclass(frozen=True)
class BridgeMember:
    """What a bridge's module file prints of the composed module it is part of."""

    namespace: str   # bridge_<module>
    composed: str    # the composed module's name (comment text)
    config: str      # its config file (comment text)


@dataclass(frozen=True)
class MemberView:
    """One bridge in the composed module's table; literals, but ``namespace``
    (an identifier) and ``summary`` (comment text)."""

    namespace: str
    module: str
    config: str
    at: str
    summary: str


@dataclass(frozen=True)
class BuildView:
    """What the CMakeLists.txt of a composed module reads (the names of the
    ROS 2 part, ``ros2.cmake.j2``, as a module's view has them)."""

    target: str
    executable: str
    filename: str
    config_comment: str
    bridges: tuple[str, ...]        # the bridges' sources
    ros2_packages: tuple[str, ...]  # every message package a bridge links, once
    images: bool
    ros1: bool
    uses_ros2: bool


@dataclass(frozen=True)
class ComposedView:
    filename: str
    name: str           # an identifier
    name_literal: str
    name_comment: str
    version: str
    version_literal: str
    config_count: int
    members: tuple[MemberView, ...]
    uses_ros2: bool


@dataclass(frozen=True)
class ComposedPackageView:
    """The ament_cmake package of a composed module (raw values: each
    template escapes them for its file)."""

    config: str
    package: str
    executable: str
    description: str
    depends: tuple[str, ...]
    launch_file: str
    params_file: str
    nodes: tuple[str, ...]
    node_parameters: tuple[NodeParameters, ...]


@functools.lru_cache(maxsize=None)
def environment() -> jinja2.Environment:
    from ybg.backends.cpp import TEMPLATE_DIR

    return template_environment([TEMPLATE_DIR], {
        "code": code_filter,
        "indent_line": indent_line_filter,
        "xml": xml_filter,
        "xml_comment": xml_comment_filter,
        "py_comment": py_comment_filter,
        "pyliteral": py_literal,
        **YAML_FILTERS,
    })


def compose(programs, name: str, options: RenderOptions = RenderOptions()) -> dict[str, str]:
    """The files of the composed module ``name`` of ``programs`` (docs/compose.md)."""
    from ybg.backends.cpp import ROS2_LINK, CppBackend, runtime_libraries

    cpp_identifier(name)
    env = environment()
    views = []
    nodes: dict[str, str] = {}
    CppBackend().check_composed(programs)
    for program in programs:
        try:
            view = CppBackend().kind(program).view(program)
        except LoweringError as e:
            if getattr(e, "module", None) is None:
                e.module = program.module
            raise
        if view.uses_ros2:
            node = node_name(program)
            if node in nodes:
                raise refusal(program, f"its node name {node} is also that of the bridge {nodes[node]}: two "
                                        "nodes of one name in one process (set `node` in its [output])",
                               program.output.span)
            nodes[node] = program.module
        views.append((program, view))

    ros2 = any(v.uses_ros2 for _, v in views)
    images = any(v.images for _, v in views)
    services = any(CppBackend().kind(p).services for p, _ in views)
    files: dict[str, str] = {}
    members = []
    rt = runtime_view("cpp", False)
    for program, view in views:
        kind = CppBackend().kind(program)
        namespace = cpp_identifier(f"bridge_{program.module}")
        member = BridgeMember(namespace=namespace, composed=comment(name), config=comment(config_file(program)))
        files[f"{BRIDGES}/{view.filename}"] = env.get_template(kind.template).render(m=view, rt=rt, member=member)
        members.append(MemberView(namespace=namespace, module=cpp_string(program.module),
                                  config=cpp_string(config_file(program)), at=cpp_string(config_at(program)),
                                  summary=comment(f"{program.module}: {kind.describe(program)}")))
    packages = sorted({p for _, v in views for p in v.ros2_packages})
    filename = f"{name}.cpp"
    composed = ComposedView(filename=filename, name=name, name_literal=cpp_string(name), name_comment=comment(name),
                            version=VERSION, version_literal='"' + VERSION + '"', config_count=len(programs),
                            members=tuple(members), uses_ros2=ros2)
    files[filename] = env.get_template("compose.cpp.j2").render(c=composed)

    pkg = None
    if options.package:
        pkg = _package(programs, name, [(p, v) for p, v in views], packages)
    build = BuildView(target=name, executable=name, filename=filename, config_comment=comment(f"{len(programs)} configs"),
                      bridges=tuple(f"{BRIDGES}/{v.filename}" for _, v in views), ros2_packages=tuple(packages),
                      images=images, ros1=any(v.ros1 for _, v in views), uses_ros2=ros2)
    files["CMakeLists.txt"] = env.get_template("compose.CMakeLists.txt.j2").render(
        m=build, libraries=runtime_libraries(ros2, images, services), ros2_link=ROS2_LINK,
        own_sources=list(CPP_COMPOSE_SOURCES),
        package=pkg, project=pkg.package if pkg is not None else name,
        launch_file=f"launch/{pkg.launch_file}" if pkg is not None and pkg.nodes else None,
        params_file=f"config/{pkg.params_file}" if pkg is not None and pkg.nodes else None)
    files.update(cpp_files(ros2=ros2, images=images, services=services, compose=True))
    workdir = options.extra.get("workdir")
    files[f"{name}.xml"] = application(programs, name, f"build/{name}" if workdir and pkg is None else name, workdir
                                       if pkg is None else None)
    if pkg is not None:
        files["package.xml"] = env.get_template("package.xml.j2").render(p=pkg)
        if pkg.nodes:
            files[f"launch/{pkg.launch_file}"] = env.get_template("compose_launch.py.j2").render(p=pkg)
            files[f"config/{pkg.params_file}"] = env.get_template("compose_params.yaml.j2").render(p=pkg)
    return files


def _package(programs, name: str, views, packages) -> ComposedPackageView:
    configs = ", ".join(config_file(p) for p in programs)
    with_node = [p for p, v in views if v.uses_ros2]
    return ComposedPackageView(
        config=f"{len(programs)} configs ({configs})",
        package=package_name(name),
        executable=name,
        description=f"{len(programs)} bridges between YARP and ROS 2 in one native process, generated by ybgc "
                    f"(ybgc compose) from {configs}.",
        depends=("rcl", "rosidl_runtime_c", *packages) if packages else (),
        launch_file=f"{name}.launch.py",
        params_file=f"{name}.yaml",
        nodes=tuple(node_name(p) for p in with_node),
        node_parameters=tuple(NodeParameters(node_name(p), node_parameters(p)) for p in with_node),
    )


def application(programs, name: str, command: str, workdir: str | None) -> str:
    """The yarpmanager application of the composed module: the executable,
    and every bridge's connections (ybg.lower.yarpmanager.connections)."""
    configs = ", ".join(config_file(p) for p in programs)
    app = ET.Element("application")

    def text(parent, tag, value):
        element = ET.SubElement(parent, tag)
        element.text = value
        return element

    text(app, "name", name)
    text(app, "description",
         f"The ybgc composed module {name}: {len(programs)} bridges in one native process, from {configs}. Start "
         f"`yarprun --server {yarpmanager.NODE}` where it runs, then `yarpmanager-console --application {name}.xml "
         f"--run --connect` (or open it in yarpmanager). Its RPC port /{name}/rpc:i answers help, stats, quit.")
    text(app, "version", VERSION)
    module = ET.SubElement(app, "module")
    text(module, "name", command)
    text(module, "node", yarpmanager.NODE)
    if workdir is not None:
        text(module, "workdir", workdir)
    for program in programs:
        if isinstance(program, ir.Commands):
            continue  # its callers connect at each call
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


__all__ = ["compose", "application", "environment"]
