"""Lowering of a checked config of commands (:class:`~ybg.compiler.ir.Commands`,
docs/services.md) for the ``cpp`` backend: a native module of YARP RPC ports
and ROS 2 services through rcl, on the runtime's ``ybgc_services.hpp``
(with its ROS 2 side, ``ybgc_ros2.hpp``). ``templates/services.cpp.j2``
prints the module, ``CMakeLists.txt.j2`` (a stream's too) its CMakeLists.txt.

Each service is a namespace of the module holding its C structs
(``<pkg>/srv/<name>.h``: ``Request``, ``Response``) and its functions,
written here line by line:

- serves ros2: ``buildCommand(request, command)``, the command Bottle sent
  to the YARP RPC port; ``fillResponse(reply, response, why)``, the response
  filled from the reply's checked, converted elements (false, with why, when
  one does not fit); ``fillFailure(reason, response)``, the failure answer;
- serves yarp: ``fillRequest(args, request, why)``, the request filled from
  the command's arguments; ``buildReply(response, reply)``, the reply Bottle;
  ``buildFailure(response, reason, reply)``, the failure reply;

and ``kService``, what the runtime needs of it (what it serves and calls, its
timeout, the declaration and converters of the reply or arguments, the
reasons of a failed call from :mod:`ybg.lower.services`). A value of the config
reaches the source only through :mod:`.escape`; the semantics are the rclpy
node's (:mod:`ybg.runtime.services`), so that both answer alike.
"""

from __future__ import annotations

from dataclasses import dataclass

from ybg.backends.cpp.escape import (comment, cpp_float, cpp_identifier, cpp_int, cpp_std_string, cpp_string,
                                     mangle)
from ybg.backends.cpp.lower import _executable  # (CMake target, executable name), as a stream module's
from ybg.backends.cpp.package import PackageView
from ybg.backends.cpp.rcl import RUNTIME_PACKAGES
from ybg.compiler import ir
from ybg.lower import services as texts
from ybg.lower.compose import config_file
from ybg.lower.errors import Line, LoweringError
from ybg.lower.fills import FILLED, FLOATS, BottleWriter, ItemPlan, plan_fill
from ybg.lower.package import PackageView as LaunchView
from ybg.lower.rosnames import node_name, node_parameters, package_name, snake_case, split_srv

#: the runtime's Wire of each Bottle tag
_WIRE = {"int32": "ybgc::Wire::Int32", "int64": "ybgc::Wire::Int64", "float64": "ybgc::Wire::Float64",
         "string": "ybgc::Wire::String"}
#: names a service's namespace must not take (the module's own, and those it uses)
_TAKEN = frozenset({"commands", "ybgc", "yarp", "std", "rosidl_runtime_c", "Request", "Response", "kService",
                    "kCommands", "buildCommand", "fillResponse", "fillFailure", "fillRequest", "buildReply",
                    "buildFailure", "main"})
#: the element types a Bottle item of a declaration may have
_DECLARED = FILLED


# --------------------------------------------------------------------------
# view-model


@dataclass(frozen=True)
class ServiceView:
    """One service: its namespace, the comment lines above it, the C structs
    of its type, its functions (each a tuple of lines, the signature at
    indent 0) and the lines of its ``kService``."""

    namespace: str
    comment: tuple[str, ...]
    request: str          # the C struct of a request
    response: str         # the C struct of a response
    functions: tuple[tuple[Line, ...], ...]
    spec: tuple[Line, ...]


@dataclass(frozen=True)
class PortView:
    """A YARP RPC port the module serves, and what `help` answers there."""

    port: str                 # string literal
    comment: str
    help: tuple[str, ...]     # string literals


@dataclass(frozen=True)
class CommandsView:
    """Everything the module's template and its CMakeLists print."""

    filename: str
    target: str
    executable: str
    config_comment: str
    header: tuple[str, ...]           # comment lines (already safe)
    includes: tuple[str, ...]         # <pkg>/srv/<name>.h
    services: tuple[ServiceView, ...]
    ports: tuple[PortView, ...]
    module: str                       # string literal
    config: str                       # string literal
    node: str                         # string literal
    default_prefix: str               # string literal
    description: tuple[str, ...]      # string literals (--help)
    unknown_command: str              # string literal
    ros2_packages: tuple[str, ...]    # the interface packages to link (the services', the runtime's)

    # what the shared CMake templates ask of a module
    ros1: bool = False
    images: bool = False
    uses_ros2: bool = True


# --------------------------------------------------------------------------
# names


def c_struct(srv_type: str, part: str) -> str:
    """The C struct of a request or response (``std_srvs__srv__Trigger_Request``)."""
    pkg, name = split_srv(srv_type)
    return f"{pkg}__srv__{name}_{part}"


def c_header(srv_type: str) -> str:
    """The header that declares a service's C structs, functions and type support."""
    pkg, name = split_srv(srv_type)
    return f"{pkg}/srv/{snake_case(name)}.h"


def _member(ref: ir.FieldRef) -> str:
    """A field of a request or response, as members of its C struct (``target.x``)."""
    try:
        return ".".join(cpp_identifier(part) for part in ref.path)
    except ValueError as e:
        raise LoweringError(f"field {ref.dotted!r} cannot be a member of a C struct ({e})") from None


def _namespaces(commands: ir.Commands) -> dict[str, str]:
    """A C++ namespace for each service: its name, else made one."""
    out: dict[str, str] = {}
    used: set[str] = set()
    for s in commands.services:
        try:
            name = cpp_identifier(s.name)
            if name in _TAKEN:
                raise ValueError(name)
        except ValueError:
            try:
                name = mangle("service_", s.name)
            except ValueError as e:
                raise LoweringError(f"service {s.name!r} cannot name a C++ namespace ({e})", s.span) from None
        base, k = name, 2
        while name in used:
            name = f"{base}_{k}"
            k += 1
        used.add(name)
        out[s.name] = name
    return out


# --------------------------------------------------------------------------
# constants


def _c_literal(v, base: str) -> str:
    """A constant already coerced to its field's element type (fills.coerce)."""
    if base in FLOATS:
        return cpp_float(v)
    if base == "bool":
        return "true" if v else "false"
    return cpp_int(v, 64)


def _constant(target: str, value, typ: ir.TypeRef) -> str:
    """The statement that sets a field to a constant of the config (coerced:
    fills.constant)."""
    if typ.array is None:
        if typ.base == "string":
            return f"ybgc::ros2::setString({target}, {cpp_std_string(value)});"
        return f"ybgc::ros2::assign({target}, {_c_literal(value, typ.base)});"
    if typ.base == "string":
        return f"ybgc::ros2::setStrings({target}, {{{', '.join(cpp_std_string(v) for v in value)}}});"
    if not value:
        return f"ybgc::ros2::resize({target}, 0);"
    kind = "double" if typ.base in FLOATS else "bool" if typ.base == "bool" else "std::int64_t"
    return f"ybgc::ros2::setValues<{kind}>({target}, {{{', '.join(_c_literal(v, typ.base) for v in value)}}});"


# --------------------------------------------------------------------------
# fields filled by the module


def _fill(fill: ir.Fill, msg: str, elements: str, failure: bool) -> list[str]:
    """The statements that fill one field (its plan: fills.plan_fill):
    ``msg`` the request or response, ``elements`` the Elements of the Bottle
    (none in a failure answer)."""
    plan = plan_fill(fill, failure)
    ref, typ = plan.ref, plan.type
    target = f"{msg}.{_member(ref)}"
    if plan.op == "constant":
        return [_constant(target, plan.value, typ)]
    if plan.op == "reason":
        return [f"ybgc::ros2::setString({target}, reason);"]
    if plan.op == "text":
        return [f"ybgc::ros2::setString({target}, {elements}.text());"]
    if plan.op == "element":
        call = f"{elements}.set({target}, {plan.start:d}, why)"
    else:
        stop = "ybgc::kToEnd" if plan.stop is None else f"{plan.stop:d}"
        bound = typ.size if typ.array == "sequence" and typ.size is not None else 0
        call = (f"{elements}.setRange({target}, {plan.start:d}, {stop}, {bound:d}, "
                f"{cpp_string(ref.dotted)}, why)")
    return [f"if (!{call}) {{", "    return false;", "}"]


def _what(fill: ir.Fill, bottle: str) -> str:
    """A comment saying what fills a field."""
    if fill.source == "element":
        if fill.slice:
            where = f"{bottle}[{fill.start}:{'' if fill.stop is None else fill.stop}]"
        else:
            where = f"{bottle}[{fill.start}]"
        if fill.ref.type is not None and fill.ref.type.base == "bool":
            where += ": a true word or a number not 0"
        return where
    if fill.source == "text":
        return f"the {bottle} as text"
    if fill.source == "error":
        return "why the call failed"
    return comment(str(fill.value) if not isinstance(fill.value, bool) else str(fill.value).lower())


def _fills(fills, msg: str, elements: str, failure: bool, bottle: str) -> list[Line]:
    lines: list[Line] = []
    for f in fills:
        try:
            statements = _fill(f, msg, elements, failure)
        except LoweringError as e:
            raise e.at(f.span)
        lines.append(Line(1, f"// {comment(f.ref.dotted)} ({comment(str(f.ref.type))}): {_what(f, bottle)}"))
        lines += [Line(1, s) for s in statements]
    return lines


# --------------------------------------------------------------------------
# Bottles written by the module


class _BottleWriter(BottleWriter):
    """The statements that add a Bottle's items: constants, a message's
    fields (``msg``: the request or response), nested lists (a block each),
    the reason of a failure (``reason``)."""

    def literal(self, bottle: str, plan: ItemPlan) -> list[str]:
        if plan.wire == "string":
            return [f"{bottle}.addString({cpp_std_string(plan.value)});"]
        if plan.wire == "float64":
            return [f"{bottle}.addFloat64({cpp_float(plan.value)});"]
        bits = 32 if plan.wire == "int32" else 64
        return [f"{bottle}.add{'Int32' if bits == 32 else 'Int64'}({cpp_int(plan.value, bits)});"]

    def field(self, bottle: str, plan: ItemPlan) -> list[str]:
        said = (f"// {comment(plan.ref.dotted)} ({comment(str(plan.ref.type))})"
                + (f", {comment(plan.converter)}" if plan.conversion is not None else ""))
        expr = f"{self.msg}.{_member(plan.ref)}"
        each = "Each" if plan.ref.type.array is not None else ""
        if plan.conversion is not None:
            scale, offset = plan.conversion
            return [said, f"ybgc::services::put{each}Converted({bottle}, {expr}, {cpp_float(scale)}, "
                          f"{cpp_float(offset)});"]
        return [said, f"ybgc::services::put{each}({bottle}, {expr}, {_WIRE[plan.wire]});"]

    def reason(self, bottle: str, plan: ItemPlan) -> list[str]:
        return [f"{bottle}.addString(reason);  // why the call failed"]

    def nested(self, bottle: str, name: str, items, indent: int) -> None:
        self.lines.append(Line(indent, "{"))
        self.lines.append(Line(indent + 1, f"yarp::os::Bottle& {name} = {bottle}.addList();"))
        self.items(name, items, indent + 1)
        self.lines.append(Line(indent, "}"))


# --------------------------------------------------------------------------
# one service


def _function(signature: tuple[str, ...], doc: tuple[str, ...], body: list[Line]) -> tuple[Line, ...]:
    return (*(Line(0, f"/// {d}") for d in doc), *(Line(0, s) for s in signature), Line(0, "{"), *body,
            Line(0, "}"))


def _declared(service: ir.Service) -> tuple[str, str]:
    """(the declared flag, the types' initializer) of the reply or arguments."""
    if service.layout is None:
        return "false", "{}"
    types = []
    for g in service.layout:
        if g.type not in _DECLARED or g.count < 0:
            raise LoweringError(f"a declaration of {g.count} {g.type}", service.span)
        types += [g.type] * g.count
    return "true", "{" + ", ".join(cpp_string(t) for t in types) + "}"


def _converters(service: ir.Service) -> str:
    out = []
    for c in service.converters:
        if c.start < 0 or (c.stop is not None and c.stop < c.start):
            raise LoweringError(f"the converter {c.name} on [{c.start}:{c.stop}]", c.span)
        stop = "ybgc::kToEnd" if c.stop is None else f"{c.stop:d}"
        out.append(f"{{{cpp_string(c.name)}, {cpp_float(float(c.scale))}, {cpp_float(float(c.offset))}, "
                   f"{'true' if c.to_float else 'false'}, {c.start:d}, {stop}}}")
    return "{" + ", ".join(out) + "}"


def _declaration_text(service: ir.Service) -> str:
    if service.layout is None:
        return "taken as it comes"
    return "declared " + ", ".join(f"{g.type} x{g.count}" for g in service.layout)


def _service(service: ir.Service, namespace: str) -> ServiceView:
    if service.serves not in ("ros2", "yarp"):
        raise LoweringError(f"a service serves ros2 or yarp, not {service.serves!r}", service.span)
    if not service.timeout > 0:
        raise LoweringError(f"the timeout of service {service.name} is {service.timeout!r} s", service.span)
    try:
        pkg, name = split_srv(service.srv_type)
    except LoweringError as e:
        raise e.at(service.type_span or service.span)
    type_name = f"{pkg}/srv/{name}"
    request, response = c_struct(service.srv_type, "Request"), c_struct(service.srv_type, "Response")
    reasons = texts.reasons(service)
    declared, types = _declared(service)
    what = _declaration_text(service)
    if service.serves == "ros2":
        bw = _BottleWriter("request", failure=False)
        bw.items("command", service.bottle)
        command = _function(
            ("void buildCommand([[maybe_unused]] const Request& request, yarp::os::Bottle& command)",),
            (f"The command Bottle sent to {comment(service.port)} for a request of {comment(service.service)}.",),
            bw.lines)
        fills = _fills(service.fills, "response", "reply", failure=False, bottle="reply")
        fill = _function(
            ("bool fillResponse([[maybe_unused]] const ybgc::services::Elements& reply, Response& response,",
             "                  [[maybe_unused]] std::string& why)"),
            (f"The response from the reply of {comment(service.port)} ({what}), its elements",
             "checked and converted; false, with why, when one does not fit its field."),
            fills + [Line(1, "return true;")])
        failure = _function(
            ("void fillFailure([[maybe_unused]] const std::string& reason, [[maybe_unused]] Response& response)",),
            ("The answer of a failed call (`response` a fresh one, its other fields at their defaults), and why.",),
            _fills(service.failure_fills, "response", "", failure=True, bottle="reply"))
        functions = (command, fill, failure)
        helper = f"ybgc::services::servesRos2<Request, Response, &buildCommand, &fillResponse, &fillFailure>()"
        served = f"the ROS 2 service {comment(service.service)} ({comment(type_name)})"
        called = f"the YARP RPC port {comment(service.port)}"
        spec_lines = [
            f"{cpp_string(service.service)},  // the ROS 2 service served",
            f"{cpp_string(service.port)},  // the YARP RPC port called",
        ]
    else:
        fills = _fills(service.fills, "request", "args", failure=False, bottle="args")
        fill = _function(
            ("bool fillRequest([[maybe_unused]] const ybgc::services::Elements& args, [[maybe_unused]] Request& "
             "request,", "                 [[maybe_unused]] std::string& why)"),
            (f"The request of {comment(service.service)} from the arguments of `{comment(texts.usage(service))}`",
             f"(after the word; {what}), checked and converted; false, with why, when one does not fit its field."),
            fills + [Line(1, "return true;")])
        bw = _BottleWriter("response", failure=False)
        bw.items("reply", service.bottle)
        reply = _function(
            ("void buildReply([[maybe_unused]] const Response& response, yarp::os::Bottle& reply)",),
            (f"The reply Bottle from the response of {comment(service.service)}.",), bw.lines)
        fw = _BottleWriter("response", failure=True)
        fw.items("reply", service.failure_bottle)
        failure = _function(
            ("void buildFailure([[maybe_unused]] const Response& response, [[maybe_unused]] const std::string& "
             "reason,", "                  yarp::os::Bottle& reply)"),
            ("The reply of a failed call (`response` a fresh one), and why.",), fw.lines)
        functions = (fill, reply, failure)
        helper = f"ybgc::services::servesYarp<Request, Response, &fillRequest, &buildReply, &buildFailure>()"
        served = f"`{comment(texts.usage(service))}` on the YARP RPC port {comment(service.port)}"
        called = f"the ROS 2 service {comment(service.service)} ({comment(type_name)})"
        spec_lines = [
            f"{cpp_string(service.service)},  // the ROS 2 service called",
            f"{cpp_string(service.port)},  // the YARP RPC port served",
        ]
    serves = "ybgc::services::Serves::Ros2" if service.serves == "ros2" else "ybgc::services::Serves::Yarp"
    reason_items = [
        (reasons["no_server"], "no server"),
        (reasons["timed_out"], "no answer in time"),
        (reasons["waited"] if service.serves == "ros2" else "", "waited its whole timeout for the calls before it"),
        (reasons["unfit_reply"], "a reply that does not fit: {reply} {why}"),
        (reasons["bad_arguments"] if service.serves == "yarp" else "", "arguments that do not fit: {why}"),
    ]
    words = "{" + ", ".join(cpp_string(w) for w in service.true_words) + "}"
    spec = [
        Line(0, "const ybgc::services::Service kService = {"),
        Line(1, "{"),
        Line(2, f"{cpp_string(service.name)},  // its name"),
        Line(2, f"{serves},"),
        *(Line(2, text) for text in spec_lines),
        Line(2, f"{cpp_float(float(service.timeout))},  // timeout, seconds from a call's arrival"),
        Line(2, f"{declared}, {types},  // the {'reply' if service.serves == 'ros2' else 'arguments'}: {what}"),
        Line(2, f"{_converters(service)},  // converters: {{name, scale, offset, to float, start, stop}}"),
        Line(2, f"{words},  // true words"),
        Line(2, "{"),
        *(Line(3, f"{cpp_string(text)},  // {why}") for text, why in reason_items),
        Line(2, "},"),
        Line(2, f"{cpp_string(texts.describe(service))},"),
        Line(1, "},"),
        Line(1, f"ybgc::services::srvType<Request, &{request}__create, &{request}__destroy,"),
        Line(1, f"                        Response, &{response}__create, &{response}__destroy>("),
        Line(2, f"{cpp_string(type_name)}, ROSIDL_GET_SRV_TYPE_SUPPORT({pkg}, srv, {name})),"),
        Line(1, helper + ","),
        Line(0, "};"),
    ]
    header = (
        f"Service {comment(service.name)}: serves {served} and calls {called},",
        f"within {texts.timeout_text(service.timeout)} s of each call's arrival.",
    )
    return ServiceView(namespace=namespace, comment=header, request=request, response=response,
                       functions=functions, spec=tuple(spec))


# --------------------------------------------------------------------------
# the module


def lower(commands: ir.Commands) -> CommandsView:
    """The view-model of the module generated for ``commands``."""
    if not commands.services:
        raise LoweringError("a config of commands with no service")
    if commands.ros != "ros2":
        raise LoweringError("the cpp backend serves and calls ROS 2 services, not ROS 1")
    target, executable = _executable(commands.module)
    namespaces = _namespaces(commands)
    services = []
    includes = set()
    packages = set(RUNTIME_PACKAGES)
    for s in commands.services:
        try:
            services.append(_service(s, namespaces[s.name]))
            includes.add(c_header(s.srv_type))
            packages.add(split_srv(s.srv_type)[0])
        except LoweringError as e:
            raise e.at(s.span)
    ports = tuple(PortView(cpp_string(p), comment(p), tuple(cpp_string(line) for line in texts.help_lines(commands, p)))
                  for p in commands.served_ports)
    config_name = config_file(commands)
    n_ros2 = sum(1 for s in commands.services if s.serves == "ros2")
    n_yarp = len(commands.services) - n_ros2
    description = [f"module {commands.module}: {len(commands.services)} command(s) between YARP RPC ports and "
                   f"ROS 2 services"] + [texts.describe(s) for s in commands.services]
    header = (f"Module {comment(commands.module)}: {len(commands.services)} command(s) between YARP RPC ports and "
              f"ROS 2 services ({n_ros2} ROS 2 service(s) served, {n_yarp} YARP command(s) served):",)
    for s in commands.services:
        if s.serves == "ros2":
            header += (f"  {comment(s.name)}: the ROS 2 service {comment(s.service)} -> the YARP RPC port "
                       f"{comment(s.port)}",)
        else:
            header += (f"  {comment(s.name)}: `{comment(texts.usage(s))}` on the YARP RPC port {comment(s.port)} -> "
                       f"the ROS 2 service {comment(s.service)}",)
    return CommandsView(
        filename=f"{executable}.cpp",
        target=target,
        executable=executable,
        config_comment=comment(config_name),
        header=header,
        includes=tuple(sorted(includes)),
        services=tuple(services),
        ports=ports,
        module=cpp_string(commands.module),
        config=cpp_string(config_name),
        node=cpp_string(node_name(commands)),
        default_prefix=cpp_string("/" + commands.module),
        description=tuple(cpp_string(d) for d in description),
        unknown_command=cpp_string(texts.UNKNOWN_COMMAND),
        ros2_packages=tuple(sorted(packages)),
    )


def lower_package(commands: ir.Commands, view: CommandsView) -> PackageView:
    """The view-model of package.xml: the module's interface packages."""
    config_name = config_file(commands)
    return PackageView(
        config=config_name,
        package=package_name(commands.module),
        description=f"{texts.summary(commands)}, a native module through rcl, generated by ybgc from {config_name}.",
        depends=("rcl", "rosidl_runtime_c") + view.ros2_packages,
    )


def lower_launch(commands: ir.Commands, package: PackageView, executable: str) -> LaunchView:
    """The view-model of the launch file: the module started by launch_ros with the node's parameters."""
    return LaunchView(config=package.config, package=package.package, node_module=executable,
                      executable=executable, node_name=node_name(commands), description=package.description,
                      depends=package.depends, launch_file=f"{commands.module}.launch.py",
                      parameters=node_parameters(commands))


__all__ = ["CommandsView", "PortView", "ServiceView", "c_header", "c_struct", "lower", "lower_launch",
           "lower_package"]
