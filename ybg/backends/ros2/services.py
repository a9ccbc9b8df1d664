"""Lowering of a checked config of commands (:class:`~ybg.compiler.ir.Commands`)
to the view-model that ``templates/services_node.py.j2`` prints: an rclpy
node on the runtime's ``services`` module (docs/services.md).

For each service the node holds its functions, written here line by line:

- serves ros2: ``<name>_command(request)``, the command Bottle sent to the
  YARP port; ``<name>_response(reply, e, response)``, the response filled
  from the reply and its checked, converted elements ``e``;
  ``<name>_failure(response, reason)``, the failure answer;
- serves yarp: ``<name>_request(args, request)``, the request filled from
  the command's arguments; ``<name>_reply(response)``, the reply Bottle;
  ``<name>_failure(response, reason)``, the failure reply;

and its entry of ``SERVICES`` (what it serves and calls, its timeout, the
reply's or the arguments' declaration and converters, the reasons of a
failed call from :mod:`ybg.lower.services`). Every value of the config
reaches the source through :func:`~ybg.lower.python.py_literal`; every
name made from a config name is checked or made an identifier.
"""

from __future__ import annotations

import keyword
import os
import re
from dataclasses import dataclass

from ybg.compiler import ir
from ybg.lower import services as texts
from ybg.lower.errors import Line, LoweringError
from ybg.lower.package import PackageView
from ybg.lower.python import py_literal, py_types
from ybg.lower.rosnames import identifier, node_name, node_parameters, package_name, split_srv, srv_type_name, used_packages
from ybg.lower.wire import WIRE_YARP

#: the runtime's names the node imports (none of them is a name the node
#: gives a service class or a function)
RUNTIME_NAMES = ("CommandsSpec", "Conv", "PortSpec", "ServeRos2", "ServeYarp", "add_converted", "add_value",
                 "add_values", "run_commands")
#: names of the node's own module a service class or function must not take
_TAKEN = frozenset(RUNTIME_NAMES) | {
    "os", "signal", "sys", "yarp", "RUNTIME", "SPEC", "SERVICES", "PORTS", "NODE_NAME", "DEFAULT_PREFIX",
    "UNKNOWN_COMMAND", "main", "ybgc_runtime"}

_FLOAT = ("float32", "float64")
_INTS = ("int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64", "char")


# --------------------------------------------------------------------------
# view-model


@dataclass(frozen=True)
class SrvImport:
    """``from <module> import <name>`` (``as <alias>`` when another name is taken)."""

    module: str
    name: str
    alias: str


@dataclass(frozen=True)
class ServiceView:
    """One service: a comment saying what it does, its functions (lines,
    the ``def`` at indent 0), the runtime class of its entry and the
    entry's keyword arguments (name, code)."""

    comment: str
    functions: tuple[tuple[Line, ...], ...]
    kind: str
    fields: tuple[tuple[str, str], ...]
    converters: tuple[str, ...]
    reasons: tuple[tuple[str, str], ...]
    description: str


@dataclass(frozen=True)
class PortView:
    """A YARP RPC port the node serves, and what `help` answers there."""

    name: str
    help: tuple[str, ...]


@dataclass(frozen=True)
class CommandsView:
    """Everything the node template prints."""

    filename: str
    config: str
    module: str
    node_name: str
    default_prefix: str
    summary: tuple[str, ...]
    imports: tuple[SrvImport, ...]
    services: tuple[ServiceView, ...]
    ports: tuple[PortView, ...]
    unknown_command: str
    runtime_names: str
    uses: tuple[str, ...]  # what the header comment says the node does, one line each


# --------------------------------------------------------------------------
# names


def _python_name(text: str) -> str:
    """A Python identifier from a service's name (``look-at`` -> ``look_at``)."""
    name = re.sub(r"\W", "_", text, flags=re.ASCII)
    if not name or name[0].isdigit() or keyword.iskeyword(name):
        name = "service_" + name
    return name


def _attr(expr: str, name: str) -> str:
    if name.isidentifier() and name.isascii() and not keyword.iskeyword(name):
        return f"{expr}.{name}"
    return f"getattr({expr}, {py_literal(name)})"


def _get(var: str, ref: ir.FieldRef) -> str:
    expr = var
    for part in ref.path:
        expr = _attr(expr, part)
    return expr


def _set(var: str, ref: ir.FieldRef, value: str) -> str:
    *parents, last = ref.path
    expr = var
    for part in parents:
        expr = _attr(expr, part)
    if last.isidentifier() and last.isascii() and not keyword.iskeyword(last):
        return f"{expr}.{last} = {value}"
    return f"setattr({expr}, {py_literal(last)}, {value})"


def _doc(text: str) -> str:
    """A one-line docstring of ``text`` (any text: escaped)."""
    text = " ".join(text.splitlines()).replace("\\", "\\\\").replace('"', '\\"')
    return f'"""{text}"""'


# --------------------------------------------------------------------------
# Bottles written by the node


class _BottleWriter:
    """The lines that add ``items`` to a Bottle: constants, a message's
    fields (``msg``: the variable of the request or response), nested lists,
    the reason of a failure (``reason``)."""

    def __init__(self, msg: str, failure: bool):
        self.msg = msg
        self.failure = failure
        self.lines: list[Line] = []
        self.lists = 0
        self.runtime: set[str] = set()

    def items(self, bottle: str, items, indent: int = 1) -> None:
        for item in items:
            try:
                self.item(bottle, item, indent)
            except LoweringError as e:
                raise e.at(item.span)

    def item(self, bottle: str, item: ir.BottleItem, indent: int) -> None:
        emit = lambda text: self.lines.append(Line(indent, text))  # noqa: E731
        if item.kind == "literal":
            emit(self.literal(bottle, item))
        elif item.kind == "field":
            if item.ref is None:
                raise LoweringError("a field item names its field")
            emit(self.field(bottle, item))
        elif item.kind == "list":
            self.lists += 1
            name = f"items{self.lists}" if self.lists > 1 else "items"
            emit(f"{name} = {bottle}.addList()")
            self.items(name, item.items, indent)
        elif item.kind == "error":
            if not self.failure:
                raise LoweringError("`error` is the reason of a failed call: only in the failure reply")
            emit(f"{bottle}.addString(reason)")
        else:
            raise LoweringError(f"unknown Bottle item {item.kind!r}")

    @staticmethod
    def literal(bottle: str, item: ir.BottleItem) -> str:
        v, t = item.value, item.type
        if isinstance(v, bool) or t == "bool":
            return f"{bottle}.addInt32({1 if v else 0:d})"
        if t == "string" or (t is None and isinstance(v, str)):
            return f"{bottle}.addString({py_literal(str(v))})"
        if t == "float64" or (t is None and isinstance(v, float)):
            return f"{bottle}.addFloat64({py_literal(float(v))})"
        if t in ("int32", "int64", None) and isinstance(v, int):
            if t == "int32" and not -2**31 <= v < 2**31:
                raise LoweringError(f"{v} is beyond an int32")
            if t is None:
                t = "int32" if -2**31 <= v < 2**31 else "int64"
            if not -2**63 <= v < 2**63:
                raise LoweringError(f"{v} is beyond an int64")
            return f"{bottle}.add{'Int32' if t == 'int32' else 'Int64'}({v:d})"
        raise LoweringError(f"a constant {v!r} of type {t!r} in a Bottle")

    def field(self, bottle: str, item: ir.BottleItem) -> str:
        ref = item.ref
        typ = ref.type
        expr = _get(self.msg, ref)
        if typ.is_message or typ.base in ("time", "duration"):
            raise LoweringError(f"the field {ref.dotted} is a {typ}: a Bottle item is a number, a string "
                                f"or a bool (name its fields)")
        conv = item.converter
        if conv is not None and not conv.is_identity:
            if typ.base not in _FLOAT + _INTS + ("byte",):
                raise LoweringError(f"the converter {conv.name} of the {typ.base} field {ref.dotted}")
            scale, offset = float(conv.scale), float(conv.offset)
            if typ.array is not None or typ.base == "byte":
                self.runtime.add("add_converted")
                return (f"add_converted({bottle}, {expr}, {py_literal(scale)}, {py_literal(offset)})"
                        f"  # {conv.name}")
            value = expr
            if scale != 1.0:
                value = f"{value} * {py_literal(scale)}"
            if offset != 0.0:
                value = f"{value} + {py_literal(offset)}"
            if scale == 1.0 and offset == 0.0:
                value = f"float({expr})"
            return f"{bottle}.addFloat64({value})  # {conv.name}"
        wire = WIRE_YARP.get(typ.base)
        if wire is None:
            raise LoweringError(f"no Bottle item for the {typ.base} field {ref.dotted}")
        if typ.array is not None:
            self.runtime.add("add_values")
            return f"add_values({bottle}, {py_literal(wire)}, {expr})"
        if typ.base == "bool":
            return f"{bottle}.addInt32(1 if {expr} else 0)"
        if typ.base == "string":
            return f"{bottle}.addString({expr})"
        if typ.base in _FLOAT:
            return f"{bottle}.addFloat64({expr})"
        if typ.base in ("byte", "uint64"):
            self.runtime.add("add_value")
            return f"add_value({bottle}, {py_literal(wire)}, {expr})"
        return f"{bottle}.add{'Int32' if wire == 'int32' else 'Int64'}({expr})"


# --------------------------------------------------------------------------
# fields filled by the node


def _coerce(value, base: str):
    if base in _FLOAT:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise LoweringError(f"{value!r} is not a number, for a {base} field")
        return float(value)
    if base == "bool":
        return bool(value)
    if base == "string":
        return str(value)
    if base in _INTS or base == "byte":
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or (isinstance(value, float) and not value.is_integer()):
            raise LoweringError(f"{value!r} is not an integer, for a {base} field")
        return int(value)
    raise LoweringError(f"no constant of type {base!r}")


def _constant(value, typ: ir.TypeRef) -> str:
    def one(v) -> str:
        c = _coerce(v, typ.base)
        if typ.base == "byte":
            if not 0 <= c <= 255:
                raise LoweringError(f"{c} is not a byte")
            return f"bytes(({c:d},))"
        return py_literal(c)

    if typ.array is None:
        if isinstance(value, tuple):
            raise LoweringError(f"a list for the scalar field of type {typ}")
        return one(value)
    values = value if isinstance(value, tuple) else (value,)
    if typ.array == "fixed" and typ.size is not None and len(values) != typ.size:
        raise LoweringError(f"{len(values)} values for a field of type {typ}")
    if typ.array == "sequence" and typ.size is not None and len(values) > typ.size:
        raise LoweringError(f"{len(values)} values for a field of type {typ}")
    return "[" + ", ".join(one(v) for v in values) + "]"


_ONE = {"float32": "float", "float64": "float", "bool": "bool", "string": "str", "byte": "byte",
        **{t: "int" for t in _INTS}}
_MANY = {"float32": "floats", "float64": "floats", "bool": "bools", "string": "strs", "byte": "bytes",
         **{t: "ints" for t in _INTS}}


def _fill(fill: ir.Fill, msg: str, elements: str, text: str, failure: bool) -> str:
    """The assignment of one field: ``msg`` the request or response,
    ``elements`` the Elements variable, ``text`` the whole Bottle's text."""
    ref = fill.ref
    typ = ref.type
    if typ is None:
        raise LoweringError(f"the field {ref.dotted} needs its type")
    if typ.is_message or typ.base in ("time", "duration"):
        raise LoweringError(f"the field {ref.dotted} is a {typ}: fill its fields")
    if fill.source == "literal":
        return _set(msg, ref, _constant(fill.value, typ))
    if fill.source == "error":
        if not failure:
            raise LoweringError("`error` is the reason of a failed call: only in a failure answer")
        if typ.base != "string" or typ.array is not None:
            raise LoweringError(f"the reason of a failed call is a string, not a {typ} ({ref.dotted})")
        return _set(msg, ref, "reason")
    if failure:
        raise LoweringError(f"a failure answer is constants and `error`, not {fill.source} ({ref.dotted})")
    if fill.source == "text":
        if typ.base != "string" or typ.array is not None:
            raise LoweringError(f"a Bottle's text is a string, not a {typ} ({ref.dotted})")
        return _set(msg, ref, text)
    if fill.source != "element":
        raise LoweringError(f"unknown source {fill.source!r} of the field {ref.dotted}")
    if fill.start < 0 or (fill.stop is not None and fill.stop < fill.start):
        raise LoweringError(f"the elements [{fill.start}:{fill.stop}] of the field {ref.dotted}")
    if not fill.slice:
        if typ.array is not None:
            raise LoweringError(f"one element for the array field {ref.dotted} ({typ})")
        method = _ONE.get(typ.base)
        if method is None:
            raise LoweringError(f"no element fills the {typ.base} field {ref.dotted}")
        return _set(msg, ref, f"{elements}.{method}({fill.start:d})")
    if typ.array is None:
        raise LoweringError(f"elements [{fill.start}:{'' if fill.stop is None else fill.stop}] for the "
                            f"scalar field {ref.dotted}")
    method = _MANY.get(typ.base)
    if method is None:
        raise LoweringError(f"no element fills the {typ.base} field {ref.dotted}")
    args = [f"{fill.start:d}"]
    if fill.stop is not None:
        args.append(f"{fill.stop:d}")
    if typ.size is not None:
        if fill.stop is not None:
            n = fill.stop - fill.start
            if (typ.array == "fixed" and n != typ.size) or n > typ.size:
                raise LoweringError(f"{n} elements for the field {ref.dotted} ({typ})")
        else:
            args.append(f"{'fixed' if typ.array == 'fixed' else 'bound'}={typ.size:d}")
            args.append(f"field={py_literal(ref.dotted)}")
    return _set(msg, ref, f"{elements}.{method}({', '.join(args)})")


def _fills(fills, msg: str, elements: str, text: str, failure: bool) -> list[Line]:
    lines = []
    for f in fills:
        try:
            lines.append(Line(1, _fill(f, msg, elements, text, failure)))
        except LoweringError as e:
            raise e.at(f.span)
    return lines


# --------------------------------------------------------------------------
# one service


def _declared_types(service: ir.Service):
    if service.layout is None:
        return None
    return tuple(g.type for g in service.layout for _ in range(g.count))


def _converters(service: ir.Service) -> tuple[str, ...]:
    out = []
    for c in service.converters:
        if c.start < 0 or (c.stop is not None and c.stop < c.start):
            raise LoweringError(f"the converter {c.name} on [{c.start}:{c.stop}]", c.span)
        out.append(f"Conv({py_literal(c.name)}, scale={py_literal(float(c.scale))}, "
                   f"offset={py_literal(float(c.offset))}, to_float={py_literal(bool(c.to_float))}, "
                   f"start={c.start:d}, stop={py_literal(c.stop)})")
    return tuple(out)


def describe(service: ir.Service) -> str:
    """The start-up line of a service: what it serves and what it calls."""
    kind = srv_type_name(service.srv_type)
    timeout = texts.timeout_text(service.timeout)
    if service.serves == "ros2":
        return (f"service {service.name}: serves the ROS 2 service {service.service} ({kind}) and calls the "
                f"YARP RPC port {service.port} (timeout {timeout} s)")
    return (f"service {service.name}: serves `{texts.usage(service)}` on the YARP RPC port {service.port} and "
            f"calls the ROS 2 service {service.service} ({kind}) (timeout {timeout} s)")


def _function(signature: str, doc: str, body: list[Line], result: str) -> tuple[Line, ...]:
    return (Line(0, f"def {signature}:"), Line(1, _doc(doc)), *body, Line(1, f"return {result}"))


def _service(service: ir.Service, fn: str, srv_class: str, runtime: set[str]) -> ServiceView:
    if service.serves not in ("ros2", "yarp"):
        raise LoweringError(f"a service serves ros2 or yarp, not {service.serves!r}", service.span)
    if not service.timeout > 0:
        raise LoweringError(f"the timeout of service {service.name} is {service.timeout!r} s", service.span)
    type_name = srv_type_name(service.srv_type)
    # the reasons a call of this direction may fail for (no YARP call waits for another's)
    unused = "bad_arguments" if service.serves == "ros2" else "waited"
    reasons = tuple((py_literal(k), py_literal(v)) for k, v in texts.reasons(service).items() if k != unused)
    common = [
        ("name", py_literal(service.name)),
    ]
    if service.serves == "ros2":
        bw = _BottleWriter("request", failure=False)
        bw.lines.append(Line(1, "command = yarp.Bottle()"))
        bw.items("command", service.bottle)
        runtime |= bw.runtime
        command = _function(f"{fn}_command(request)",
                            f"The command Bottle sent to {service.port} for a request of {service.service}.",
                            bw.lines[:], "command")
        declared = "as it comes" if service.layout is None else \
            "declared " + ", ".join(f"{g.type} x{g.count}" for g in service.layout)
        response = _function(
            f"{fn}_response(reply, e, response)",
            f"The response from the reply of {service.port} ({declared}) and its elements e, converted; "
            f"an element that does not fit raises Unfit.",
            _fills(service.fills, "response", "e", "reply.toString()", failure=False), "response")
        failure = _function(f"{fn}_failure(response, reason)",
                            "The answer of a failed call (response: a new one), and why.",
                            _fills(service.failure_fills, "response", "e", "", failure=True), "response")
        fields = common + [
            ("service", py_literal(service.service)),
            ("srv_class", srv_class),
            ("type_name", py_literal(type_name)),
            ("port", py_literal(service.port)),
            ("timeout", py_literal(float(service.timeout))),
            ("types", py_types(_declared_types(service))),
            ("true_words", py_literal(tuple(service.true_words))),
            ("command", f"{fn}_command"),
            ("fill", f"{fn}_response"),
            ("failure", f"{fn}_failure"),
        ]
        functions = (command, response, failure)
        kind = "ServeRos2"
    else:
        request = _function(f"{fn}_request(args, request)",
                            f"The request of {service.service} from the arguments of `{texts.usage(service)}` "
                            f"(after the word), converted; an argument that does not fit raises Unfit.",
                            _fills(service.fills, "request", "args", "args.text()", failure=False), "request")
        bw = _BottleWriter("response", failure=False)
        bw.lines.append(Line(1, "reply = yarp.Bottle()"))
        bw.items("reply", service.bottle)
        reply = _function(f"{fn}_reply(response)", f"The reply Bottle from the response of {service.service}.",
                          bw.lines[:], "reply")
        fw = _BottleWriter("response", failure=True)
        fw.lines.append(Line(1, "reply = yarp.Bottle()"))
        fw.items("reply", service.failure_bottle)
        runtime |= bw.runtime | fw.runtime
        failure = _function(f"{fn}_failure(response, reason)",
                            "The reply of a failed call (response: a new one), and why.", fw.lines[:], "reply")
        fields = common + [
            ("port", py_literal(service.port)),
            ("service", py_literal(service.service)),
            ("srv_class", srv_class),
            ("type_name", py_literal(type_name)),
            ("timeout", py_literal(float(service.timeout))),
            ("types", py_types(_declared_types(service))),
            ("true_words", py_literal(tuple(service.true_words))),
            ("request", f"{fn}_request"),
            ("reply", f"{fn}_reply"),
            ("failure", f"{fn}_failure"),
        ]
        functions = (request, reply, failure)
        kind = "ServeYarp"
    return ServiceView(comment=describe(service), functions=functions, kind=kind, fields=tuple(fields),
                       converters=_converters(service), reasons=reasons, description=py_literal(describe(service)))


# --------------------------------------------------------------------------
# the node


def _imports(commands: ir.Commands) -> tuple[dict[str, str], tuple[SrvImport, ...]]:
    """The service classes: ``from pkg.srv import Name``, aliased
    ``pkg_Name`` where two packages have the name or the node has it."""
    types = {}
    for s in commands.services:
        try:
            types[s.srv_type] = split_srv(s.srv_type)
        except LoweringError as e:
            raise e.at(s.type_span or s.span)
    counts: dict[str, int] = {}
    for pkg, name in set(types.values()):
        counts[name] = counts.get(name, 0) + 1
    names: dict[str, str] = {}
    imports = {}
    for srv_type, (pkg, name) in types.items():
        alias = name if counts[name] == 1 and name not in _TAKEN else f"{pkg}_{name}"
        names[srv_type] = alias
        imports[(pkg, name)] = SrvImport(f"{pkg}.srv", name, alias)
    return names, tuple(imports[k] for k in sorted(imports))


def _function_names(commands: ir.Commands, classes: set[str]) -> dict[str, str]:
    taken = set(_TAKEN) | classes
    out: dict[str, str] = {}
    for s in commands.services:
        base = _python_name(s.name)
        name, k = base, 2
        suffixes = ("_command", "_response", "_failure", "_request", "_reply")
        while name in out.values() or any(name + x in taken for x in suffixes):
            name = f"{base}_{k}"
            k += 1
        out[s.name] = name
    return out


def lower(commands: ir.Commands) -> CommandsView:
    """The view-model of the node generated for ``commands``."""
    if not commands.services:
        raise LoweringError("a config of commands with no service")
    if commands.ros != "ros2":
        raise LoweringError("the ros2 backend serves and calls ROS 2 services, not ROS 1")
    filename = f"{identifier(commands.module, 'module name')}_node.py"
    classes, imports = _imports(commands)
    fnames = _function_names(commands, set(classes.values()))
    runtime: set[str] = set()
    services = []
    for s in commands.services:
        try:
            services.append(_service(s, fnames[s.name], classes[s.srv_type], runtime))
        except LoweringError as e:
            raise e.at(s.span)
    ports = tuple(PortView(py_literal(p), tuple(py_literal(line) for line in texts.help_lines(commands, p)))
                  for p in commands.served_ports)
    n_ros2 = sum(1 for s in commands.services if s.serves == "ros2")
    n_yarp = len(commands.services) - n_ros2
    summary = [f"ROS 2 node {commands.module}: {len(commands.services)} command(s) between YARP RPC ports "
               f"and ROS 2 services"]
    summary += [describe(s) for s in commands.services]
    uses = []
    for s in commands.services:
        if s.serves == "ros2":
            uses.append(f"{s.service} ({srv_type_name(s.srv_type)}): each call the command sent to the YARP "
                        f"RPC port {s.port}")
        else:
            uses.append(f"`{s.name} ...` on the YARP RPC port {s.port}: a call of {s.service} "
                        f"({srv_type_name(s.srv_type)})")
    config_name = os.path.basename(commands.source) if commands.source else commands.module
    names = sorted({"CommandsSpec", "PortSpec", "run_commands"}
                   | {"ServeRos2" if n_ros2 else "ServeYarp"} | ({"ServeYarp"} if n_ros2 and n_yarp else set())
                   | ({"Conv"} if any(s.converters for s in commands.services) else set()) | runtime)
    return CommandsView(
        filename=filename,
        config=py_literal(config_name),
        module=py_literal(commands.module),
        node_name=py_literal(node_name(commands)),
        default_prefix=py_literal("/" + commands.module),
        summary=tuple(py_literal(line) for line in summary),
        imports=imports,
        services=tuple(services),
        ports=ports,
        unknown_command=py_literal(texts.UNKNOWN_COMMAND),
        runtime_names=", ".join(names),
        uses=tuple(uses),
    )


def lower_package(commands: ir.Commands, view: CommandsView) -> PackageView:
    """The view-model of the ament_python package around the node."""
    config_name = os.path.basename(commands.source) if commands.source else commands.module
    what = ", ".join(s.service for s in commands.services)
    return PackageView(
        config=config_name,
        package=package_name(commands.module),
        node_module=view.filename[: -len(".py")],
        executable=view.filename[: -len(".py")],
        node_name=node_name(commands),
        description=f"Commands between YARP RPC ports and ROS 2 services ({what}), generated by ybgc from "
                    f"{config_name}.",
        depends=("rclpy", "diagnostic_msgs") + tuple(p for p in used_packages(commands)
                                                     if p not in ("rclpy", "diagnostic_msgs")),
        launch_file=f"{commands.module}.launch.py",
        parameters=node_parameters(commands),
    )


__all__ = ["CommandsView", "ServiceView", "PortView", "SrvImport", "lower", "lower_package", "describe",
           "RUNTIME_NAMES"]
