"""The ``cpp`` backend: a C++17 YARP module and its CMakeLists.txt, which
reads YARP ports or ROS 1 topics and writes a Bottle on a YARP port or a
ROS 1 topic (YARP's topic@node ports, with the type promised), or publishes
a ROS 2 message through rcl (:mod:`.ros2`: its C struct filled field by
field; the runtime's ROS 2 side ``ybgc_ros2.*`` beside it), and camera
images both ways (the runtime's ``ybgc_images.*``).

The module (``module.cpp.j2``) holds this bridge's description, its muxes,
the message builder and the places for custom code; it runs on the runtime
library (``ybg/runtime/cpp/``: inputs, layout checks, freshness, matching,
converters, timing, connections, the RPC port, shutdown), written beside it as
``ybgc_runtime.hpp`` and its sources (``ybgc_*.cpp``) or inlined with
``--single-file`` (:mod:`ybg.backends.runtime`); its yarpmanager
application ``<module>.xml`` beside it (:mod:`ybg.lower.yarpmanager`);
with ``--package``, a ROS 2 package around it (:mod:`.package`). :mod:`.lower` makes every
decision and escapes every value with :mod:`.escape`; the templates only
print.

A config of commands (:class:`~ybg.compiler.ir.Commands`: YARP RPC ports and
ROS 2 services, docs/services.md) is lowered by :mod:`.services` and printed
by ``services.cpp.j2`` and ``CMakeLists.txt.j2``; it runs on the
runtime's ``ybgc_services*`` with its ROS 2 side. Each kind of bridge is a
:class:`~ybg.backends.base.BridgeKind` here (:class:`StreamModule`,
:class:`CommandsModule`): its view, its template, what it says of itself,
whether it needs the runtime's commands; the composed module (:mod:`.compose`)
asks the same ones.
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from pathlib import Path

import jinja2

from ybg.backends.base import Backend, BridgeKind, RenderOptions
from ybg.backends.cpp.lower import lower
from ybg.backends.cpp.package import lower_launch, lower_package
from ybg.backends.runtime import (CPP_IMAGES_SOURCES, CPP_ROS2_SOURCES, CPP_SERVICES_SOURCES, CPP_SOURCES, cpp_files,
                                  runtime_text_filter, runtime_view)
from ybg.lower import yarpmanager
from ybg.lower.errors import LoweringError
from ybg.lower.package import launch_file
from ybg.lower.templates import code_filter, indent_line_filter, template_environment, xml_comment_filter, xml_filter
from ybg.runtime import VERSION

TEMPLATE_DIR = Path(__file__).resolve().parent / "templates"


@functools.lru_cache(maxsize=None)
def environment() -> jinja2.Environment:
    return template_environment([TEMPLATE_DIR], {
        "code": code_filter,
        "indent_line": indent_line_filter,
        "runtime_text": runtime_text_filter,
        "xml": xml_filter,
        "xml_comment": xml_comment_filter,
    })


#: ybgc's version as it stands in a CMake name (``0.2.0`` -> ``0_2_0``)
_VERSION_ID = re.sub(r"[^0-9A-Za-z]", "_", VERSION)


def runtime_library(part: str = "runtime") -> str:
    """The CMake target of a part of the runtime library beside a module
    (``runtime``, ``ros2``, ``images``, ``services``), named with ybgc's
    version: the modules of one version in one CMake project build it once,
    and those of another version do not take it for theirs."""
    return f"ybgc_{part}_{_VERSION_ID}"


#: the CMake macro, named with ybgc's version, that gives a target rcl and
#: message packages (``ros2.cmake.j2``)
ROS2_LINK = f"ybgc_link_ros2_{_VERSION_ID}"
#: the message packages the runtime's ROS 2 side uses (/diagnostics, /clock, stamps)
RUNTIME_ROS2_PACKAGES = ("builtin_interfaces", "diagnostic_msgs", "rosgraph_msgs")


@dataclass(frozen=True)
class RuntimeLibrary:
    """A static library of the runtime beside a module, as its CMakeLists.txt
    builds it (``runtime.cmake.j2``)."""
    target: str
    what: str                          # what it holds, for a comment
    sources: tuple[str, ...]
    links: tuple[str, ...]             # PUBLIC: the libraries below it
    ros2_packages: tuple[str, ...] = ()  # rcl and these, when it speaks ROS 2


def runtime_libraries(ros2: bool = False, images: bool = False, services: bool = False) -> tuple:
    """The runtime's libraries a module (or a composed module) links, each
    on those before it: the core; its ROS 2 side; camera images; commands."""
    libs = [RuntimeLibrary(runtime_library(), "the core", CPP_SOURCES,
                           ("YARP::YARP_os", "YARP::YARP_init", "Threads::Threads"))]
    if ros2 or images or services:
        libs.append(RuntimeLibrary(runtime_library("ros2"), "its ROS 2 side", CPP_ROS2_SOURCES,
                                   (runtime_library(),), RUNTIME_ROS2_PACKAGES))
    if images:
        libs.append(RuntimeLibrary(runtime_library("images"), "camera images", CPP_IMAGES_SOURCES,
                                   (runtime_library("ros2"), "YARP::YARP_sig"),
                                   RUNTIME_ROS2_PACKAGES + ("sensor_msgs",)))
    if services:
        libs.append(RuntimeLibrary(runtime_library("services"), "commands", CPP_SERVICES_SOURCES,
                                   (runtime_library("ros2"),), RUNTIME_ROS2_PACKAGES))
    return tuple(libs)


def runtime_folder() -> dict[str, str]:
    """Every part of the runtime library, alone in a folder of its own: its
    sources and a CMakeLists.txt that defines each part's library (as a
    module's does, no project of its own). A CMake project of many modules of
    one ybgc version that adds this folder before theirs (``add_subdirectory``)
    builds each part from here, whatever the modules; the modules' own
    definitions see the target and skip. The project finds YARP (``os`` and
    ``sig``) and Threads first."""
    libraries = runtime_libraries(ros2=True, images=True, services=True)
    cmake = environment().get_template("runtime.cmake.j2").render(
        m={"uses_ros2": True}, libraries=libraries, ros2_link=ROS2_LINK)
    files = {"CMakeLists.txt": f"# ybgc's runtime library {VERSION}, every part (generated by ybgc; do not edit)\n\n"
                               + cmake}
    files.update(cpp_files(ros2=True, images=True, services=True))
    return files


class StreamModule(BridgeKind):
    """A stream bridge's module: ``module.cpp.j2`` on the runtime library,
    its CMakeLists.txt, its yarpmanager application; with ``package``, an
    ament_cmake package around it."""

    #: the template of its module file (a bridge of a composed module's too)
    template = "module.cpp.j2"
    #: it runs on the runtime's commands (ybgc_services*)
    services = False

    def render(self, program, options: RenderOptions) -> dict[str, str]:
        view = self.lower(program)
        ros2 = view.uses_ros2
        env = environment()
        rt = runtime_view("cpp", options.single_file, ros2=ros2, images=view.images)
        beside = not options.single_file
        pkg = lower_package(program, view.ros2_packages) if options.package else None
        launch = lower_launch(program, pkg, view.executable) if pkg is not None and ros2 else None
        files = {
            view.filename: env.get_template("module.cpp.j2").render(m=view, rt=rt),
            "CMakeLists.txt": env.get_template("CMakeLists.txt.j2").render(
                m=view, commands=False, uses_ros2=ros2, images=view.images, ros1=view.ros1, ros2_link=ROS2_LINK,
                libraries=runtime_libraries(ros2, view.images) if beside else (), package=pkg,
                project=pkg.package if pkg is not None else view.target,
                launch_file=f"launch/{launch.launch_file}" if launch else None,
                launch_file_name=launch.launch_file if launch else None),
        }
        if pkg is not None:
            files["package.xml"] = env.get_template("package.xml.j2").render(p=pkg)
            if launch is not None:
                files[f"launch/{launch.launch_file}"] = launch_file(launch)
        if not options.single_file:
            files.update(cpp_files(ros2, view.images))
        # run from the folder it was generated into, built as its header says
        workdir = options.extra.get("workdir")
        files[yarpmanager.filename(program)] = yarpmanager.application(
            program, f"build/{view.executable}" if workdir else view.executable, "", workdir)
        return files

    @staticmethod
    def lower(program):
        """ybg.backends.cpp.lower; for a ROS 2 output, with its message builder (.ros2)."""
        if program.output.kind == "ros2":
            from ybg.backends.cpp import ros2
            return ros2.lower(program)
        return lower(program)

    view = lower

    @staticmethod
    def describe(program) -> str:
        """What it does, for a comment: what it publishes."""
        from ybg.lower.rosnames import ros2_type_name

        out = program.output
        if out.kind == "ros2":
            return f"{ros2_type_name(out.msg_type or program.message.msg_type or '')} on {out.name}"
        if out.kind == "ros1":
            return f"the ROS 1 topic {out.name}"
        return f"the YARP port {out.name}"


class CommandsModule(BridgeKind):
    """A module of commands (.services): the module, its CMakeLists.txt, and
    the runtime with its ROS 2 side and commands beside it (or inlined)."""

    template = "services.cpp.j2"
    services = True

    @staticmethod
    def view(commands):
        from ybg.backends.cpp import services

        return services.lower(commands)

    @staticmethod
    def describe(commands) -> str:
        """What it does, for a comment: what each command serves and calls."""
        return "commands " + ", ".join(
            f"{s.service} -> {s.port}" if s.serves == "ros2" else f"{s.port} ({s.name}) -> {s.service}"
            for s in commands.services)

    def render(self, commands, options: RenderOptions) -> dict[str, str]:
        from ybg.backends.cpp import services

        view = services.lower(commands)
        env = environment()
        rt = runtime_view("cpp", options.single_file, ros2=True, services=True)
        beside = not options.single_file
        pkg = services.lower_package(commands, view) if options.package else None
        launch = services.lower_launch(commands, pkg, view.executable) if pkg is not None else None
        files = {
            view.filename: env.get_template("services.cpp.j2").render(m=view, rt=rt),
            "CMakeLists.txt": env.get_template("CMakeLists.txt.j2").render(
                m=view, commands=True, uses_ros2=True, images=False, ros1=False, ros2_link=ROS2_LINK,
                libraries=runtime_libraries(ros2=True, services=True) if beside else (), package=pkg, project=pkg.package if pkg is not None else view.target,
                launch_file=f"launch/{launch.launch_file}" if launch else None,
                launch_file_name=launch.launch_file if launch else None),
        }
        if pkg is not None:
            files["package.xml"] = env.get_template("package.xml.j2").render(p=pkg)
            files[f"launch/{launch.launch_file}"] = launch_file(launch)
        if beside:
            files.update(cpp_files(ros2=True, services=True))
        return files

    def lower(self, commands) -> None:
        from ybg.backends.cpp import services
        services.lower(commands)  # the module's lowering, without the templates


class CppBackend(Backend):
    name = "cpp"
    bridge_kinds = {"stream": StreamModule(), "commands": CommandsModule()}

    def compose(self, programs, name: str, options: RenderOptions = RenderOptions()) -> dict[str, str]:
        """One native executable running every program's bridge, of either
        kind (.compose, docs/compose.md)."""
        from ybg.backends.cpp.compose import compose

        return compose(programs, name, options)


__all__ = ["CppBackend", "LoweringError", "TEMPLATE_DIR", "environment"]
