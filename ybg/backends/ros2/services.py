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
import re
from dataclasses import dataclass

from ybg.compiler import ir
from ybg.lower import services as texts
from ybg.lower.compose import config_file
from ybg.lower.errors import Line, LoweringError
from ybg.lower.fills import FLOATS, INTEGERS, BottleWriter, ItemPlan, plan_fill
from ybg.lower.package import PackageView, node_package
from ybg.lower.python import py_literal, py_types
from ybg.lower.rosnames import identifier, node_name, split_srv, srv_type_name

#: the runtime's names the node imports (none of them is a name the node
#: gives a service class or a function)
RUNTIME_NAMES = ("CommandsSpec", "Conv", "PortSpec", "ServeRos2", "ServeYarp", "add_converted", "add_value",
                 "add_values", "run_commands")
#: names of the node's own module a service class or function must not take
_TAKEN = frozenset(RUNTIME_NAMES) | {
    "os", "signal", "sys", "yarp", "RUNTIME", "SPEC", "SERVICES", "PORTS", "NODE_NAME", "DEFAULT_PREFIX",
    "UNKNOWN_COMMAND", "main", "ybgc_runtime"}



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


class _BottleWriter(BottleWriter):
    """The lines that add a Bottle's items: constants, a message's fields
    (``msg``: the variable of the request or response), nested lists, the
    reason of a failure (``reason``); ``runtime``: the runtime's helpers
    they call."""

    def __init__(self, msg: str, failure: bool):
        super().__init__(msg, failure)
        self.runtime: set[str] = set()

    def literal(self, bottle: str, plan: ItemPlan) -> list[str]:
        if plan.wire == "string":
            return [f"{bottle}.addString({py_literal(plan.value)})"]
        if plan.wire == "float64":
            return [f"{bottle}.addFloat64({py_literal(plan.value)})"]
        return [f"{bottle}.add{'Int32' if plan.wire == 'int32' else 'Int64'}({plan.value:d})"]

    def field(self, bottle: str, plan: ItemPlan) -> list[str]:
        return [self._field(bottle, plan)]

    def _field(self, bottle: str, plan: ItemPlan) -> str:
        ref = plan.ref
        typ = ref.type
        expr = _get(self.msg, ref)
        if plan.conversion is not None:
            scale, offset = plan.conversion
            if typ.array is not None or typ.base == "byte":
                self.runtime.add("add_converted")
                return (f"add_converted({bottle}, {expr}, {py_literal(scale)}, {py_literal(offset)})"
                        f"  # {plan.converter}")
            value = expr
            if scale != 1.0:
                value = f"{value} * {py_literal(scale)}"
            if offset != 0.0:
                value = f"{value} + {py_literal(offset)}"
            if scale == 1.0 and offset == 0.0:
                value = f"float({expr})"
            return f"{bottle}.addFloat64({value})  # {plan.converter}"
        wire = plan.wire
        if typ.array is not None:
            self.runtime.add("add_values")
            return f"add_values({bottle}, {py_literal(wire)}, {expr})"
        if typ.base == "bool":
            return f"{bottle}.addInt32(1 if {expr} else 0)"
        if typ.base == "string":
            return f"{bottle}.addString({expr})"
        if typ.base in FLOATS:
            return f"{bottle}.addFloat64({expr})"
        if typ.base in ("byte", "uint64"):
            self.runtime.add("add_value")
            return f"add_value({bottle}, {py_literal(wire)}, {expr})"
        return f"{bottle}.add{'Int32' if wire == 'int32' else 'Int64'}({expr})"

    def reason(self, bottle: str, plan: ItemPlan) -> list[str]:
        return [f"{bottle}.addString(reason)"]

    def nested(self, bottle: str, name: str, items, indent: int) -> None:
        self.lines.append(Line(indent, f"{name} = {bottle}.addList()"))
        self.items(name, items, indent)


# --------------------------------------------------------------------------
# fields filled by the node


def _constant(value, typ: ir.TypeRef) -> str:
    """A constant already coerced to its field's type (fills.constant)."""
    def one(c) -> str:
        if typ.base == "byte":
            return f"bytes(({c:d},))"
        return py_literal(c)

    if typ.array is None:
        return one(value)
    return "[" + ", ".join(one(v) for v in value) + "]"


_ONE = {"float32": "float", "float64": "float", "bool": "bool", "string": "str", "byte": "byte",
        **{t: "int" for t in INTEGERS if t != "byte"}}
_MANY = {"float32": "floats", "float64": "floats", "bool": "bools", "string": "strs", "byte": "bytes",
         **{t: "ints" for t in INTEGERS if t != "byte"}}


def _fill(fill: ir.Fill, msg: str, elements: str, text: str, failure: bool) -> str:
    """The assignment of one field (its plan: fills.plan_fill): ``msg`` the
    request or response, ``elements`` the Elements variable, ``text`` the
    whole Bottle's text."""
    plan = plan_fill(fill, failure)
    ref, typ = plan.ref, plan.type
    if plan.op == "constant":
        return _set(msg, ref, _constant(plan.value, typ))
    if plan.op == "reason":
        return _set(msg, ref, "reason")
    if plan.op == "text":
        return _set(msg, ref, text)
    if plan.op == "element":
        return _set(msg, ref, f"{elements}.{_ONE[typ.base]}({plan.start:d})")
    args = [f"{plan.start:d}"]
    if plan.stop is not None:
        args.append(f"{plan.stop:d}")
    elif typ.size is not None:
        args.append(f"{'fixed' if typ.array == 'fixed' else 'bound'}={typ.size:d}")
        args.append(f"field={py_literal(ref.dotted)}")
    return _set(msg, ref, f"{elements}.{_MANY[typ.base]}({', '.join(args)})")


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
    return ServiceView(comment=texts.describe(service), functions=functions, kind=kind, fields=tuple(fields),
                       converters=_converters(service), reasons=reasons, description=py_literal(texts.describe(service)))


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
    return class_imports(types, "srv", _TAKEN)


def class_imports(types: dict[str, tuple[str, str]], submodule: str, taken
                  ) -> tuple[dict[str, str], tuple[SrvImport, ...]]:
    """The classes of the interface types ``types`` (type -> (pkg, Name)):
    each type's name in the node, and ``from pkg.<submodule> import Name``,
    aliased ``pkg_Name`` where two packages have the name or it is ``taken``."""
    counts: dict[str, int] = {}
    for pkg, name in set(types.values()):
        counts[name] = counts.get(name, 0) + 1
    names: dict[str, str] = {}
    imports = {}
    for type_name, (pkg, name) in types.items():
        alias = name if counts[name] == 1 and name not in taken else f"{pkg}_{name}"
        names[type_name] = alias
        imports[(pkg, name)] = SrvImport(f"{pkg}.{submodule}", name, alias)
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
    summary += [texts.describe(s) for s in commands.services]
    uses = []
    for s in commands.services:
        if s.serves == "ros2":
            uses.append(f"{s.service} ({srv_type_name(s.srv_type)}): each call the command sent to the YARP "
                        f"RPC port {s.port}")
        else:
            uses.append(f"`{s.name} ...` on the YARP RPC port {s.port}: a call of {s.service} "
                        f"({srv_type_name(s.srv_type)})")
    config_name = config_file(commands)
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
    return node_package(commands, view.filename, texts.summary(commands))


__all__ = ["CommandsView", "ServiceView", "PortView", "SrvImport", "lower", "lower_package",
           "RUNTIME_NAMES"]
