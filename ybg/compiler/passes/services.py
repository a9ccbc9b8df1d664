"""Pass ``services``: the [service <name>] sections of a config of commands.

Each section bridges one command between a YARP RPC port and a ROS 2
service (docs/services.md): ``serve`` is what the module serves, ``call``
what it calls; the side with a ``.srv`` type is the ROS 2 one.
Checks: the two sides (E352), the service type (E350), port and service
names (E401, E402), the keys of each direction (E202, E204), the fields of
the request and the response (E302) and what fills them (E304, E305, E310,
E316, E317), the converters (E208, E313, E314, E315), the failure answer
(E351), commands and services given twice, and the words a served port
answers by itself (E353).
Reads ``service_sections``, ``module``, ``store`` and ``distro``. Sets
``program`` to an :class:`~ybg.compiler.ir.Commands` when nothing is wrong.
"""

from __future__ import annotations

import math

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import closest, did_you_mean
from ybg.compiler.msgtypes import MsgDef, SrvDef
from ybg.compiler.names import identifier_problem, port_problem, sanitize_identifier, topic_problem
from ybg.compiler.passes import converters as converters_pass
from ybg.compiler.passes.context import Context
from ybg.compiler.passes.inputs import _layout
from ybg.compiler.values import check_keys, number

#: the keys of a [service] section, besides request.*, response.* and failure.*
SERVICE_KEYS = ("serve", "call", "send", "reply", "timeout", "convert", "true_words", "on_failure")
_FIELD_PREFIXES = ("request.", "response.", "failure.")
#: keys that only one direction takes: key -> (the direction, what it is)
_DIRECTION_KEYS = {
    "send": ("ros2", "the command sent to the YARP port the module calls"),
    "response.": ("ros2", "the response filled from the YARP reply"),
    "failure.": ("ros2", "the response answered when the call fails"),
    "reply": ("yarp", "the reply the module gives on the YARP port it serves"),
    "request.": ("yarp", "the request filled from the YARP command"),
    "on_failure": ("yarp", "the reply given when the call fails"),
}
_INT_RANGES = {
    "int8": (-(2**7), 2**7 - 1), "uint8": (0, 2**8 - 1), "byte": (0, 2**8 - 1), "char": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1), "uint16": (0, 2**16 - 1), "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1), "int64": (-(2**63), 2**63 - 1), "uint64": (0, 2**64 - 1),
}


def run(ctx: Context) -> None:
    services: list[ir.Service] = []
    for label, sec in ctx.service_sections.items():
        svc = _service(ctx, label, sec)
        if svc is not None:
            services.append(svc)
    _clashes(ctx, services)
    if not ctx.sink.has_errors and len(services) == len(ctx.service_sections):
        ctx.program = ir.Commands(ctx.module, ctx.source, tuple(services), ctx.distro, "ros2")


# --------------------------------------------------------------------------
# One service


class _Endpoint:
    """One side as written: a name, and in parentheses a `.srv` type or a declaration."""

    def __init__(self, name: str, span, srv_type: str | None = None, type_span=None, decl=None, decl_span=None):
        self.name, self.span = name, span
        self.srv_type, self.type_span = srv_type, type_span
        self.decl, self.decl_span = decl, decl_span


def _endpoint(ctx: Context, entry: ast.Entry) -> _Endpoint | None:
    s = ctx.sink
    if len(entry.items) != 1:
        s.error("E208", f"`{entry.key}` takes one port or service, not {len(entry.items) or 'no'} values",
                entry.span, f"e.g. `{entry.key} = /robot/home (std_srvs/Trigger)` or "
                            f"`{entry.key} = /module/rpc:i (string x1)`")
        return None
    item = entry.items[0]
    if isinstance(item, ast.Word):
        return _Endpoint(item.text, item.span)
    if isinstance(item, ast.Call) and isinstance(item.func, ast.Word):
        args = item.args
        if len(args) == 1 and len(args[0]) == 1 and isinstance(args[0][0], ast.Word) and "/" in args[0][0].text:
            return _Endpoint(item.func.text, item.func.span, args[0][0].text, args[0][0].span)
        return _Endpoint(item.func.text, item.func.span, decl=args, decl_span=item.span)
    s.error("E208", f"`{entry.key}` is a YARP port or a ROS 2 service", item.span,
            f"e.g. `{entry.key} = /robot/home (std_srvs/Trigger)` or `{entry.key} = /module/rpc:i`")
    return None


def _service(ctx: Context, label: str, sec: ast.Section) -> ir.Service | None:
    s = ctx.sink
    errors = s.error_count
    keys = check_keys(sec, SERVICE_KEYS, s, extra=lambda k: k.startswith(_FIELD_PREFIXES))
    problem = identifier_problem(label)
    if problem:
        s.error("E214", f"command name `{label}` {problem}", sec.span,
                f"e.g. `[service {sanitize_identifier(label)}]`")
    for need in ("serve", "call"):
        if need not in keys:
            s.error("E204", f"[service {label}] has no `{need}`", sec.span,
                    "`serve` is what the module serves, `call` what it calls: one a ROS 2 service with its "
                    "type, `/robot/home (std_srvs/Trigger)`, the other a YARP RPC port, `/module/rpc:i`")
    if "serve" not in keys or "call" not in keys:
        return None
    serve, call = _endpoint(ctx, keys["serve"]), _endpoint(ctx, keys["call"])
    if serve is None or call is None:
        return None
    if (serve.srv_type is None) == (call.srv_type is None):
        both = serve.srv_type is not None
        s.error("E352", f"[service {label}]: {'both sides are' if both else 'neither side is'} a ROS 2 service",
                keys["serve"].items[0].span if both else sec.span,
                "one of `serve` and `call` is a ROS 2 service with its type in parentheses "
                "(`/robot/home (std_srvs/Trigger)`), the other a YARP RPC port (`/module/rpc:i`, "
                "optionally with its declaration, `/module/rpc:i (string x1)`)")
        return None
    serves = "ros2" if serve.srv_type is not None else "yarp"
    ros, yarp = (serve, call) if serves == "ros2" else (call, serve)
    for key, (direction, what) in _DIRECTION_KEYS.items():
        for k, e in keys.items():
            if (k == key or (key.endswith(".") and k.startswith(key))) and direction != serves:
                side = "serves a ROS 2 service" if serves == "ros2" else "serves a YARP port"
                s.error("E202", f"`{k}` is {what}, but [service {label}] {side}", e.key_span,
                        _direction_hint(serves))
    problem = topic_problem(ros.name)
    if problem:
        s.error("E402", f"invalid ROS 2 service name `{ros.name}`: {problem}", ros.span)
    problem = port_problem(yarp.name)
    if problem:
        s.error("E401", f"invalid YARP port name `{yarp.name}`: {problem}", yarp.span,
                "a YARP port name starts with `/`, e.g. `/iKinGazeCtrl/rpc`")
    srv = _srv(ctx, ros)
    layout = None
    if yarp.decl is not None:
        layout = _layout(ctx, yarp.decl, yarp.decl_span)
        if layout is None:
            return None
    timeout = ir.SERVICE_TIMEOUT
    if "timeout" in keys:
        t = number(keys["timeout"], s)
        timeout = t if t is not None else timeout
    true_words = ir.TRUE_WORDS
    if "true_words" in keys:
        true_words = _words(ctx, keys["true_words"])
    bottle_name = "reply" if serves == "ros2" else "args"
    convs = _converters(ctx, keys.get("convert"), bottle_name, layout)
    if srv is None or convs is None:
        return None
    svc = ir.Service(label, serves, ros.name, srv.name, yarp.name, timeout, layout, tuple(convs),
                     true_words=true_words, span=sec.span, type_span=ros.type_span)
    if serves == "ros2":
        svc = _serve_ros2(ctx, svc, srv, keys, sec)
    else:
        svc = _serve_yarp(ctx, svc, srv, keys, sec)
        if svc.layout is None and not any(f.source in ("element", "text") for f in svc.fills):
            # a command that reads no argument and declares none takes none
            svc = ir.Service(**{**_fields(svc), "layout": ()})
    return svc if s.error_count == errors else None


def _direction_hint(serves: str) -> str:
    if serves == "ros2":
        return ("a ROS 2 service served: `send = ...` (the command, from `request.<field>`), "
                "`response.<field> = reply[i]`, `failure.<field> = ...`")
    return ("a YARP port served: `request.<field> = args[i]`, `reply = ...` (from `response.<field>`), "
            "`on_failure = ...`")


def _srv(ctx: Context, ros: _Endpoint) -> SrvDef | None:
    s = ctx.sink
    store = ctx.store
    name = ros.srv_type or ""
    srv = store.resolve_service(name) if store is not None else None
    if srv is not None:
        return srv
    where = store.service_path(name) if store is not None else None
    if where is not None:
        s.error("E350", f"service type `{name}` cannot be read: its definition has problems", ros.type_span,
                f"see {where}")
        return None
    bare = name.split("/")[-1]
    known = store.service_names() if store is not None else []
    guesses = store.service_candidates(bare) if store is not None else []
    guess = guesses[0] if guesses else closest(name, known)
    given = [p for p in (store.search_paths[:-1] if store is not None else [])]
    searched = f" (searched {', '.join(given)}, then ybgc's own)" if given else ""
    hint = (f"did you mean `{guess}`?" if guess else
            f"no `.srv` defines it for {ctx.distro}{searched}: give the folder of your package with "
            "`--msg-path DIR`, where it is DIR/<pkg>/srv/<Name>.srv")
    s.error("E350", f"unknown service type `{name}`", ros.type_span, hint)
    return None


def _words(ctx: Context, entry: ast.Entry) -> tuple[str, ...]:
    out = []
    for item in entry.items:
        if isinstance(item, ast.Word):
            out.append(item.text)
        elif isinstance(item, ast.Str):
            out.append(item.value)
        else:
            ctx.sink.error("E208", "`true_words` lists words, e.g. `true_words = ok, ack, done`", item.span)
    return tuple(out)


def _converters(ctx: Context, entry: ast.Entry | None, bottle: str, layout) -> list[ir.Converter] | None:
    """The linear converters of `convert`, on the reply's or the arguments' elements."""
    if entry is None:
        return []
    mux = ir.Mux(bottle, (ir.Input(bottle, layout=layout),))
    out: list[ir.Converter] = []
    for item in entry.items:
        current = ir.Mux(bottle, mux.inputs, tuple(out))
        ok, conv = converters_pass._converter(ctx, current, item, current.width, current.element_types, True)
        if not ok:
            return None
        if conv is None:
            continue
        if not isinstance(conv, ir.Converter):
            ctx.sink.error("E208", f"`{bottle}` is converted element by element: `{conv.name}` is not for "
                                   "commands", item.span,
                           "converters here: none_double, deg_to_rad, rad_to_deg, scale(k), offset(b)")
            return None
        out.append(ir.Converter(conv.name, conv.scale, conv.offset, conv.to_float, conv.start, conv.stop,
                                span=item.span))
    return out


# --------------------------------------------------------------------------
# A ROS 2 service served: request -> command Bottle, reply -> response


def _serve_ros2(ctx: Context, svc: ir.Service, srv: SrvDef, keys: dict[str, ast.Entry],
                sec: ast.Section) -> ir.Service:
    s = ctx.sink
    bottle: tuple[ir.BottleItem, ...] = ()
    if "send" not in keys:
        s.error("E204", f"[service {svc.name}] has no `send`: the command sent to {svc.port}", sec.span,
                'e.g. `send = "home", "all"` or `send = "look", "3D", [request.x, request.y, request.z]`')
    else:
        bottle = tuple(i for i in (_bottle_item(ctx, svc, item, srv.request, "request")
                                   for item in keys["send"].items) if i is not None)
    fills = _fills(ctx, svc, srv.response, keys, "response.", "reply")
    failure = _fills(ctx, svc, srv.response, keys, "failure.", None)
    if s.error_count:
        return svc
    failure = _failure_fills(ctx, svc, srv.response, fills, failure, sec)
    return ir.Service(**{**_fields(svc), "bottle": bottle, "fills": tuple(fills),
                         "failure_fills": tuple(failure)})


def _failure_fills(ctx: Context, svc: ir.Service, response: MsgDef, fills: list[ir.Fill],
                   failure: list[ir.Fill], sec: ast.Section) -> list[ir.Fill]:
    """The response's fields when a call fails: `failure.*`, and `success` false and
    `message` the reason where the config fills the response's `success`."""
    given = {f.ref.path for f in failure}
    success = next((f for f in fills if f.ref.path == ("success",) and f.ref.type == ir.TypeRef("bool")), None)
    if success is None:
        if not failure:
            ctx.sink.error("E351", f"[service {svc.name}] does not say what to answer when the call fails",
                           sec.span, _failure_hint(response))
        return failure
    out = list(failure)
    if ("success",) not in given:
        out.insert(0, ir.Fill(success.ref, "literal", value=False, span=success.span))
    message = response.fields and next((f for f in response.fields if f.name == "message"), None)
    if message is not None and message.type == ir.TypeRef("string") and ("message",) not in given:
        out.append(ir.Fill(ir.FieldRef(("message",), message.type), "error", span=success.span))
    return out


def _failure_hint(response: MsgDef) -> str:
    fields = ", ".join(f"{f.name} ({f.type})" for f in response.fields) or "no fields"
    return ("its response has no bool `success` filled from the reply; say what a failed call answers with "
            f"`failure.<field> = <constant>` (or `error`, the reason, into a string): the response has {fields}")


# --------------------------------------------------------------------------
# A YARP port served: command -> request, response -> reply Bottle


def _serve_yarp(ctx: Context, svc: ir.Service, srv: SrvDef, keys: dict[str, ast.Entry],
                sec: ast.Section) -> ir.Service:
    s = ctx.sink
    fills = _fills(ctx, svc, srv.request, keys, "request.", "args")
    reply: tuple[ir.BottleItem, ...] = ()
    if "reply" not in keys:
        s.error("E204", f"[service {svc.name}] has no `reply`: the Bottle answered on {svc.port}", sec.span,
                "e.g. `reply = response.success, response.message`")
    else:
        reply = tuple(i for i in (_bottle_item(ctx, svc, item, srv.response, "response")
                                  for item in keys["reply"].items) if i is not None)
    on_failure: tuple[ir.BottleItem, ...] = ()
    if "on_failure" in keys:
        on_failure = tuple(i for i in (_bottle_item(ctx, svc, item, None, None) for item in keys["on_failure"].items)
                           if i is not None)
    if s.error_count:
        return svc
    if not on_failure:
        if not _holds_success(reply):
            s.error("E351", f"[service {svc.name}] does not say what to reply when the call fails",
                    keys["reply"].items[0].span if "reply" in keys and keys["reply"].items else sec.span,
                    "its reply holds no bool `response.success`: say what a failed call replies with "
                    '`on_failure = <items>`, where `error` is the reason: `on_failure = "fail", error`')
            return svc
        on_failure = tuple(_failed(item, srv.response) for item in reply)
    return ir.Service(**{**_fields(svc), "bottle": reply, "fills": tuple(fills), "failure_bottle": on_failure})


def _holds_success(items) -> bool:
    for item in items:
        if item.kind == "field" and item.ref.path == ("success",) and item.ref.type == ir.TypeRef("bool"):
            return True
        if item.kind == "list" and _holds_success(item.items):
            return True
    return False


def _failed(item: ir.BottleItem, response: MsgDef) -> ir.BottleItem:
    """``item`` of the reply as a failed call gives it: `success` 0, `message` the
    reason, every other field its default."""
    if item.kind == "list":
        return ir.BottleItem("list", items=tuple(_failed(i, response) for i in item.items), span=item.span)
    if item.kind != "field":
        return item
    ref = item.ref
    if ref.path == ("success",) and ref.type == ir.TypeRef("bool"):
        return ir.BottleItem("literal", 0, "int32", span=item.span)
    if ref.path == ("message",) and ref.type == ir.TypeRef("string"):
        return ir.BottleItem("error", span=item.span)
    if ref.type.array is not None:
        # an array gives one item per element: none for a sequence, its default
        # elements for a fixed-size array (a list here: the reply's shape kept)
        n = ref.type.size if ref.type.array == "fixed" else 0
        return ir.BottleItem("list", items=(_default_item(ref.type.base, item.span),) * (n or 0), span=item.span)
    return _default_item(ref.type.base, item.span)


def _default_item(base: str, span) -> ir.BottleItem:
    if base == "string":
        return ir.BottleItem("literal", "", "string", span=span)
    if base in ir.FLOAT_TYPES:
        return ir.BottleItem("literal", 0.0, "float64", span=span)
    return ir.BottleItem("literal", 0, "int64" if base in ("int64", "uint64", "uint32") else "int32", span=span)


# --------------------------------------------------------------------------
# Fields


def _field(ctx: Context, msgdef: MsgDef, dotted: str, span, what: str) -> ir.FieldRef | None:
    """The field ``dotted`` (``target.x``) of ``msgdef``: a primitive or an array of
    primitives (E302 when there is none, E305 for a message)."""
    s = ctx.sink
    parts = dotted.split(".")
    current = msgdef
    for k, name in enumerate(parts):
        f = current.field(name)
        if f is None:
            names = [x.name for x in current.fields]
            s.error("E302", f"{_srv_part(msgdef)} has no field `{'.'.join(parts[:k + 1])}`", span,
                    did_you_mean(name, names) or (f"its fields: {', '.join(names)}" if names else "it has no fields"))
            return None
        if k == len(parts) - 1:
            if f.type.is_message:
                sub = ctx.store.resolve(f.type.base)
                inner = ", ".join(x.name for x in sub.fields) if sub is not None else ""
                s.error("E305", f"`{dotted}` is a {f.type}, not a number, a string or a bool", span,
                        f"name one of its fields: `{dotted}.<field>`" + (f" ({inner})" if inner else ""))
                return None
            return ir.FieldRef(tuple(parts), f.type, span)
        if not f.type.is_message or f.type.array is not None:
            s.error("E302", f"`{'.'.join(parts[:k + 1])}` of {_srv_part(msgdef)} is a {f.type}: it has no fields",
                    span, f"write `{what}.{'.'.join(parts[:k + 1])}`")
            return None
        current = ctx.store.resolve(f.type.base)
        if current is None:
            return None
    return None


def _srv_part(msgdef: MsgDef) -> str:
    pkg, name = msgdef.name.split("/", 1)
    base, _, part = name.rpartition("_")
    return f"the {part.lower()} of {pkg}/{base}"


def _fills(ctx: Context, svc: ir.Service, msgdef: MsgDef, keys: dict[str, ast.Entry], prefix: str,
           bottle: str | None) -> list[ir.Fill]:
    """The `prefix<field> = ...` lines: fields filled from the Bottle ``bottle`` (the
    reply or the arguments), constants, or (``bottle`` None: a failure) `error`."""
    out: list[ir.Fill] = []
    what = prefix[:-1] if prefix != "failure." else "response"
    for key, entry in keys.items():
        if not key.startswith(prefix):
            continue
        ref = _field(ctx, msgdef, key[len(prefix):], entry.key_span, what)
        if ref is None:
            continue
        fill = _fill(ctx, svc, ref, entry, bottle)
        if fill is not None:
            out.append(fill)
    return out


def _fill(ctx: Context, svc: ir.Service, ref: ir.FieldRef, entry: ast.Entry, bottle: str | None) -> ir.Fill | None:
    s = ctx.sink
    items = entry.items
    t = ref.type
    if len(items) == 1:
        item = items[0]
        if bottle is not None and isinstance(item, ast.Word) and item.text == bottle:
            if t != ir.TypeRef("string"):
                s.error("E305", f"`{bottle}` as text fills a string, not `{ref.dotted}` ({t})", item.span,
                        f"take an element: `{bottle}[0]`")
                return None
            return ir.Fill(ref, "text", span=entry.span)
        if bottle is not None and isinstance(item, ast.Subscript) and isinstance(item.base, ast.Word) \
                and item.base.text == bottle:
            return _element_fill(ctx, svc, ref, item, entry)
        if bottle is None and isinstance(item, ast.Word) and item.text == "error":
            if t != ir.TypeRef("string"):
                s.error("E305", f"`error` (why the call failed) is text: it fills a string, not "
                                f"`{ref.dotted}` ({t})", item.span, "give a constant")
                return None
            return ir.Fill(ref, "error", span=entry.span)
        if isinstance(item, (ast.Subscript, ast.Call, ast.Bracket)) or (
                isinstance(item, ast.Word) and item.text in ("reply", "args") and item.text != bottle):
            s.error("E208", f"`{_text(item)}` cannot fill `{ref.dotted}` here", item.span,
                    f"the {'reply' if bottle == 'reply' else 'arguments'} are `{bottle}`: `{bottle}[i]`, "
                    f"`{bottle}[a:b]`, `{bottle}`" if bottle else "a failure answer takes constants and `error`")
            return None
    value = _literal(ctx, ref, items, entry)
    if value is None:
        return None
    return ir.Fill(ref, "literal", value=value, span=entry.span)


def _text(item) -> str:
    from ybg.compiler.fmt import format_item
    return format_item(item)


def _element_fill(ctx: Context, svc: ir.Service, ref: ir.FieldRef, item: ast.Subscript,
                  entry: ast.Entry) -> ir.Fill | None:
    s = ctx.sink
    t = ref.type
    width = svc.width
    types = svc.element_types
    what = "the reply" if svc.serves == "ros2" else "the arguments"
    if item.is_slice:
        start, stop = item.start or 0, item.stop
        if t.array is None:
            s.error("E305", f"a slice of {what} fills an array, not `{ref.dotted}` ({t})", item.span,
                    f"take one element: `{item.base.text}[{start}]`")
            return None
        if width is not None:
            end = width if stop is None else stop
            if end > width or start > end:
                s.error("E316", f"{what} {'are' if svc.serves == 'yarp' else 'is'} declared with {width} "
                                f"element{'s' if width != 1 else ''}: `{_text(item)}` is beyond",
                        item.span, f"elements go from 0 to {width - 1}" if width else "declare more")
                return None
            if t.array == "fixed" and t.size is not None and end - start != t.size:
                s.error("E310", f"`{ref.dotted}` holds {t.size} elements, `{_text(item)}` gives {end - start}",
                        item.span)
                return None
            if types is not None:
                for k in range(start, end):
                    if not _fits(types[k], t.base):
                        s.error("E305", f"element {k} of {what} is {types[k]}: it cannot fill `{ref.dotted}` ({t})",
                                item.span)
                        return None
        return ir.Fill(ref, "element", start, stop, True, span=entry.span)
    k = item.start or 0
    if t.array is not None:
        s.error("E305", f"one element fills a scalar, not `{ref.dotted}` ({t})", item.span,
                f"take a slice: `{item.base.text}[{k}:]`")
        return None
    if k < 0:
        s.error("E316", f"`{_text(item)}`: elements are numbered from 0", item.span)
        return None
    if width is not None and k >= width:
        s.error("E316", f"{what} {'are' if svc.serves == 'yarp' else 'is'} declared with {width} "
                        f"element{'s' if width != 1 else ''}: `{_text(item)}` is beyond", item.span,
                f"elements go from 0 to {width - 1}")
        return None
    if types is not None and not _fits(types[k], t.base):
        s.error("E305", f"element {k} of {what} is {types[k]}: it cannot fill `{ref.dotted}` ({t})", item.span,
                "a word fills a string or a bool; a number fills a number or a bool")
        return None
    return ir.Fill(ref, "element", k, span=entry.span)


def _fits(element: str, field: str) -> bool:
    """Can an element of this type fill a field of this primitive type?"""
    if field == "bool":
        return True  # a word by true_words, a number by != 0
    if field in ("string", "wstring"):
        return element == "string"
    if field in ir.NUMERIC_TYPES:
        if element in ir.FLOAT_TYPES:
            return field in ir.FLOAT_TYPES
        return element in ir.NUMERIC_TYPES or element == "bool"
    return False


def _literal(ctx: Context, ref: ir.FieldRef, items, entry: ast.Entry):
    """A constant for ``ref``: its value (a tuple for an array), or None (reported)."""
    t = ref.type
    if t.array is None and len(items) != 1:
        ctx.sink.error("E304", f"`{ref.dotted}` ({t}) takes one value", entry.span)
        return None
    if t.array == "fixed" and t.size is not None and len(items) != t.size:
        ctx.sink.error("E310", f"`{ref.dotted}` holds {t.size} elements, {len(items)} given", entry.span)
        return None
    values = []
    for item in items:
        v = _scalar(ctx, t.base, item, ref)
        if v is None:
            return None
        values.append(v)
    return values[0] if t.array is None else tuple(values)


def _scalar(ctx: Context, base: str, item, ref: ir.FieldRef):
    s = ctx.sink
    if base in ("string", "wstring"):
        if isinstance(item, ast.Str):
            return item.value
        s.error("E304", f"`{ref.dotted}` is a string: write it in quotes", item.span,
                f'e.g. `"{_text(item)}"`' if isinstance(item, ast.Word) else None)
        return None
    if not isinstance(item, ast.Word):
        s.error("E304", f"`{_text(item)}` does not fit `{ref.dotted}` ({ref.type})", item.span)
        return None
    if base == "bool":
        b = item.boolean()
        if b is None:
            s.error("E304", f"`{ref.dotted}` is a bool: true or false", item.span)
        return b
    n = item.number()
    if n is None or isinstance(n, bool):
        s.error("E304", f"`{ref.dotted}` is {base}: `{item.text}` is not a number", item.span)
        return None
    if base in _INT_RANGES:
        if isinstance(n, float) and not n.is_integer():
            s.error("E304", f"`{ref.dotted}` is {base}: `{item.text}` is not a whole number", item.span)
            return None
        lo, hi = _INT_RANGES[base]
        if not lo <= int(n) <= hi:
            s.error("E317", f"{int(n)} is out of range for `{ref.dotted}` ({base}: {lo} to {hi})", item.span)
            return None
        return int(n)
    return float(n)


# --------------------------------------------------------------------------
# Bottles the module writes


def _bottle_item(ctx: Context, svc: ir.Service, item, msgdef: MsgDef | None, prefix: str | None
                 ) -> ir.BottleItem | None:
    """One item of `send` (from the request), `reply` (from the response) or
    `on_failure` (``msgdef`` None: constants and `error`)."""
    s = ctx.sink
    if isinstance(item, ast.Str):
        return ir.BottleItem("literal", item.value, "string", span=item.span)
    if isinstance(item, ast.Bracket):
        inner = [_bottle_item(ctx, svc, i, msgdef, prefix) for i in item.items]
        if any(i is None for i in inner):
            return None
        return ir.BottleItem("list", items=tuple(inner), span=item.span)  # type: ignore[arg-type]
    if isinstance(item, ast.Word):
        text = item.text
        if prefix is not None and text.startswith(prefix + "."):
            ref = _field(ctx, msgdef, text[len(prefix) + 1:], item.span, prefix)  # type: ignore[arg-type]
            if ref is None:
                return None
            return ir.BottleItem("field", ref=ref, span=item.span)
        if prefix is None and text == "error":
            return ir.BottleItem("error", span=item.span)
        b = item.boolean()
        if b is not None:
            return ir.BottleItem("literal", int(b), "int32", span=item.span)
        n = item.number()
        if n is not None and not isinstance(n, bool):
            if isinstance(n, int):
                if -(2**31) <= n < 2**31:
                    return ir.BottleItem("literal", n, "int32", span=item.span)
                if -(2**63) <= n < 2**63:
                    return ir.BottleItem("literal", n, "int64", span=item.span)
                s.error("E317", f"{n} does not fit a Bottle's int64", item.span)
                return None
            if not math.isfinite(n):
                s.error("E304", f"`{text}` is not a finite number", item.span)
                return None
            return ir.BottleItem("literal", float(n), "float64", span=item.span)
        where = {"request": "send", "response": "reply", None: "on_failure"}[prefix]
        hint = (f'a word sent as it is is quoted: `"{text}"`' if prefix != "request" or "." in text else
                f'a word sent as it is is quoted, `"{text}"`; a field of the request is `request.{text}`')
        if prefix is not None and text.startswith(("request.", "response.")):
            hint = f"`{where}` takes fields of the {prefix}: `{prefix}.<field>`"
        s.error("E208", f"`{text}` is not an item of `{where}`", item.span, hint)
        return None
    if isinstance(item, ast.Call) and prefix is not None and len(item.args) == 1 and len(item.args[0]) == 1 \
            and isinstance(item.args[0][0], ast.Word) and item.args[0][0].text.startswith(prefix + "."):
        field_word = item.args[0][0]
        ref = _field(ctx, msgdef, field_word.text[len(prefix) + 1:], field_word.span, prefix)  # type: ignore[arg-type]
        if ref is None:
            return None
        return _converted(ctx, ref, item.func, item.span)
    s.error("E208", f"`{_text(item)}` is not an item of a Bottle", item.span,
            "items: quoted words, numbers, true/false, `request.<field>` (in `send`), "
            "`response.<field>` (in `reply`), a converter of a field (`deg_to_rad(request.yaw)`), `[...]`")
    return None


def _converted(ctx: Context, ref: ir.FieldRef, func, span) -> ir.BottleItem | None:
    s = ctx.sink
    if ref.type.base not in ir.NUMERIC_TYPES:
        s.error("E314", f"a converter applied to `{ref.dotted}` ({ref.type}), which is not a number", span,
                "converters take numbers")
        return None
    width = ref.type.size if ref.type.array == "fixed" else (1 if ref.type.array is None else None)
    layout = None if width is None else (ir.ElementGroup(ref.type.base, width),)
    mux = ir.Mux(ref.dotted, (ir.Input(ref.dotted, layout=layout),))
    ok, conv = converters_pass._converter(ctx, mux, func, mux.width, mux.element_types, True)
    if not ok:
        return None
    if conv is not None and not isinstance(conv, ir.Converter):
        s.error("E208", f"`{conv.name}` is not for a field sent in a command", span,
                "converters here: none_double, deg_to_rad, rad_to_deg, scale(k), offset(b)")
        return None
    if conv is not None:
        conv = ir.Converter(conv.name, conv.scale, conv.offset, conv.to_float, span=span)
    return ir.BottleItem("field", ref=ref, converter=conv, span=span)


# --------------------------------------------------------------------------
# Across services


def _clashes(ctx: Context, services: list[ir.Service]) -> None:
    s = ctx.sink
    served: dict[str, ir.Service] = {}
    words: dict[tuple[str, str], ir.Service] = {}
    for svc in services:
        if svc.serves == "ros2":
            first = served.get(svc.service)
            if first is not None:
                s.error("E353", f"the ROS 2 service {svc.service} is served by [service {first.name}] and "
                                f"[service {svc.name}]", svc.span,
                        f"one module serves a service once: [service {first.name}] is on line "
                        f"{first.span.line if first.span else '?'}")
            served.setdefault(svc.service, svc)
            continue
        if svc.name in ir.RESERVED_COMMANDS:
            s.error("E353", f"`{svc.name}` is a command the port {svc.port} answers by itself", svc.span,
                    "the port answers `help` with the list of its commands: name the section after what the "
                    "command does (the section's name is the command's word)")
        key = (svc.port, svc.name)
        first = words.get(key)
        if first is not None:
            s.error("E353", f"the port {svc.port} has two commands `{svc.name}`", svc.span)
        words.setdefault(key, svc)


def _fields(svc: ir.Service) -> dict:
    return {f: getattr(svc, f) for f in svc.__dataclass_fields__}
