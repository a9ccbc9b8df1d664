"""Pass ``inputs``: each [mux <name>], its inputs and their declarations.

Checks: mux names (E214), `ports` or `topics` and not both (E204, E208),
port and topic names (E401, E402), a port's element declaration
`(float64 x6, int32 x3)` and a topic's message type and field
`(pkg/Name field)` (E213, E301, E302, E309), ROS 2 topics without a type
(E319), inputs read twice (W506), `timeout` and `verbose`; `accept`, the
other ports an input takes Bottles from too (E208, E401, W506); the QoS of
a mux of ROS 2 topics (`reliability`, `durability`, `depth`; W506 on
another mux).
Reads ``mux_sections``, ``mux_keys``, ``mux_via``, ``output_keys``
(the default timeout), ``options`` (the distro) and ``stores``. Sets
``muxes``, without converters.
"""

from __future__ import annotations

import dataclasses

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import Sink, Span, did_you_mean
from ybg.compiler.msgtypes import DISTROS, MsgDef, field_positions, normalize_name, numeric_leaves
from ybg.compiler.names import identifier_problem, port_problem, sanitize_identifier, topic_problem
from ybg.compiler.passes.context import Context
from ybg.compiler.passes.sections import CHOICES
from ybg.compiler.values import boolean, choice, number, whole

#: the keys of a mux of ROS 2 topics that give its subscriptions' QoS
QOS_KEYS = ("reliability", "durability", "depth")

#: seconds without a new Bottle after which an input is stale
DEFAULT_TIMEOUT = 1.0


def run(ctx: Context) -> None:
    for name, sec in ctx.mux_sections.items():
        mux = _mux(ctx, name, sec, ctx.mux_keys[name])
        if mux is not None:
            ctx.muxes[name] = mux


def _mux(ctx: Context, name: str, sec: ast.Section, keys: dict[str, ast.Entry]) -> ir.Mux | None:
    s = ctx.sink
    problem = identifier_problem(name)
    if problem:
        s.error("E214", f"mux name `{name}` {problem}", sec.span, f"e.g. `[mux {sanitize_identifier(name)}]`")
        return None
    timeout = DEFAULT_TIMEOUT
    if "timeout" in ctx.output_keys:  # reported by the output pass
        timeout = number(ctx.output_keys["timeout"], Sink()) or DEFAULT_TIMEOUT
    if "timeout" in keys:
        timeout = number(keys["timeout"], s) or timeout
    if "ports" in keys and "topics" in keys:
        s.error("E208", "a mux reads either `ports` (YARP) or `topics` (ROS), not both",
                keys["topics"].key_span, "split them into two muxes")
        return None
    entry = keys.get("ports") or keys.get("topics")
    if entry is None:
        s.error("E204", f"[mux {name}] needs `ports = /port1, /port2` (or `topics = ...`)", sec.span)
        return None
    if not entry.items:
        s.error("E208", f"`{entry.key}` lists no input", entry.span)
        return None
    inputs = []
    ok = True
    for item in entry.items:
        inp = _input(ctx, item, entry.key == "topics", ctx.mux_via[name], timeout)
        if inp is None:
            ok = False
        else:
            inputs.append(inp)
    if len(inputs) > 1 and any(i.image for i in inputs):
        s.error("E343", f"mux `{name}` reads a camera image: it reads no other input", entry.span,
                "read the other inputs in a mux of their own")
        return None
    if len(inputs) > 1 and any(i.each for i in inputs):
        s.error("E208", f"mux `{name}` reads the elements of an array of messages, one row each: "
                "it reads no other input", entry.span, "read the other inputs in a mux of their own")
        return None
    seen: dict[str, int] = {}
    for inp, item in zip(inputs, entry.items):
        if inp.name in seen:
            s.warning("W506", f"`{inp.name}` is read twice by mux `{name}`", item.span)
        seen[inp.name] = 1
    if not ok:
        return None
    accepts = _accepts(ctx, name, keys.get("accept"), inputs)
    if accepts is None:
        return None
    inputs = [dataclasses.replace(i, accepts=accepts[i.name]) if accepts.get(i.name) else i for i in inputs]
    qos = _qos(ctx, keys, ctx.mux_via[name])
    if qos is not None:
        inputs = [dataclasses.replace(i, qos=qos) if i.kind == "ros2" else i for i in inputs]
    verbose = False
    if "verbose" in keys:
        verbose = bool(boolean(keys["verbose"], s))
    return ir.Mux(name, tuple(inputs), (), verbose)


def _qos(ctx: Context, keys: dict[str, ast.Entry], via: str) -> ir.QoS | None:
    """The QoS a mux of ROS 2 topics subscribes with, when its config gives
    one: ``reliability``, ``durability``, ``depth``, each defaulting to
    :data:`ir.INPUT_QOS`'s (a reliable input keeps 10 messages, as ROS's
    default profile). None when none is given (W506 for other muxes)."""
    s = ctx.sink
    given = [k for k in QOS_KEYS if k in keys]
    if not given:
        return None
    if via != "ros2":
        for k in given:
            s.warning("W506", f"`{k}` only applies to a mux of ROS 2 topics (`via = ros2`)", keys[k].key_span,
                      "a YARP port and a ROS 1 topic have no QoS: remove the key")
        return None
    rel = choice(keys["reliability"], s, CHOICES["reliability"]) if "reliability" in keys else None
    dur = choice(keys["durability"], s, CHOICES["durability"]) if "durability" in keys else None
    depth = whole(keys["depth"], s, 1) if "depth" in keys else None
    rel = rel or ir.INPUT_QOS.reliability
    return ir.QoS(rel, dur or ir.INPUT_QOS.durability,
                  depth if depth else (ir.RELIABLE_INPUT_DEPTH if rel == "reliable" else ir.INPUT_QOS.depth))


def _input(ctx: Context, item: ast.Item, is_topic: bool, via: str, timeout: float) -> ir.Input | None:
    s = ctx.sink
    decl: tuple[tuple[ast.Atom, ...], ...] | None = None
    head = item
    if isinstance(item, ast.Call):
        head, decl = item.func, item.args
    if not isinstance(head, (ast.Word, ast.Str)):
        s.error("E213", "an input is a name, optionally followed by its declaration `(float64 x6)`",
                item.span)
        return None
    name = head.text if isinstance(head, ast.Word) else head.value
    if is_topic:
        problem = topic_problem(name)
        if problem:
            s.error("E402", f"invalid ROS topic name `{name}`: {problem}", head.span)
            return None
        ros_type = None
        fields = None
        layout = None
        positions = None
        each = None
        if decl and _is_image_topic(decl):
            if via != "ros2":
                s.error("E341", "camera images are read from ROS 2 topics: set `via = ros2` in the mux",
                        item.span)
                return None
            return ir.Input(name, via, None, "sensor_msgs/Image", None, timeout, image=ir.ANY_ENCODING)
        if decl:
            ros_type, fields, layout, each = _topic_decl(ctx, name, decl, item.span, via)
            if ros_type is None:
                return None
            if via == "ros1" and fields:  # YARP gives a ROS 1 message as a Bottle laid out like its definition
                positions = field_positions(ctx.stores.get("ros1", None), ros_type, fields)
        elif via == "ros2":
            s.error("E319", f"ROS 2 topic `{name}` needs its message type", head.span,
                    f"write `{name} (geometry_msgs/Point)`, or `{name} (sensor_msgs/JointState position)` "
                    "to take one numeric field")
            return None
        return ir.Input(name, via, layout, ros_type, fields, timeout, positions, each=each)
    problem = port_problem(name)
    if problem:
        s.error("E401", f"invalid YARP port name `{name}`: {problem}", head.span,
                "e.g. `/icub/left_arm/state:o`")
        return None
    layout = None
    if decl and decl[0] and isinstance(decl[0][0], ast.Word) and decl[0][0].text == "image":
        encoding = _pixel_type(ctx, decl, item.span)
        if encoding is None:
            return None
        return ir.Input(name, "yarp", None, None, None, timeout, image=encoding)
    if decl is not None:
        layout = _layout(ctx, decl, item.span)
        if layout is None:
            return None
    return ir.Input(name, "yarp", layout, None, None, timeout)


def _is_image_topic(decl) -> bool:
    """Is the topic declared `(sensor_msgs/Image)`, the whole frame?"""
    return (len(decl) == 1 and len(decl[0]) == 1 and isinstance(decl[0][0], ast.Word)
            and decl[0][0].text in ("sensor_msgs/Image", "sensor_msgs/msg/Image"))


def _pixel_type(ctx: Context, decl, span: Span) -> str | None:
    """The encoding of a port declared `(image <pixel type>)`: a ROS encoding
    (`rgb8`, `mono16`, `32FC1` ...) or YARP's name for it (`rgb`, `PixelRgb`)."""
    s = ctx.sink
    words = decl[0]
    if len(decl) != 1 or len(words) != 2 or not isinstance(words[1], ast.Word):
        s.error("E341", "an image port is declared `(image <pixel type>)`, e.g. `(image rgb8)`",
                words[0].span if words else span, f"pixel types: {', '.join(ir.IMAGE_ENCODINGS)}")
        return None
    word = words[1]
    encoding = ir.PIXEL_NAMES.get(word.text)
    if encoding is None:
        s.error("E341", f"unknown pixel type `{word.text}`", word.span,
                did_you_mean(word.text, list(ir.IMAGE_ENCODINGS)) or did_you_mean(word.text, list(ir.PIXEL_NAMES)) or
                f"pixel types: {', '.join(ir.IMAGE_ENCODINGS)} (REP 118 depth: 16UC1 millimetres, 32FC1 metres)")
        return None
    return encoding


def _accepts(ctx: Context, mux: str, entry: ast.Entry | None,
             inputs: list[ir.Input]) -> dict[str, tuple[str, ...]] | None:
    """The other ports whose Bottles each input of the mux takes too, by
    input port: `accept = /other:o` (a mux of one port) or
    `accept = /input:o (/other:o, /another:o)`. None when reported."""
    if entry is None:
        return {}
    s = ctx.sink
    if any(i.kind != "yarp" for i in inputs):
        s.error("E208", f"`accept` names other YARP ports an input takes Bottles from: mux `{mux}` reads "
                "ROS topics, whose publishers are not YARP's to check", entry.key_span, "remove the line")
        return None
    if not entry.items:
        s.error("E208", "`accept` names no port", entry.span,
                "e.g. `accept = /replay/head/state:o`, or `accept = /icub/head/state:o (/replay/head/state:o)`")
        return None
    names = list(dict.fromkeys(i.name for i in inputs))
    out: dict[str, list[str]] = {}
    for item in entry.items:
        if isinstance(item, ast.Call) and isinstance(item.func, (ast.Word, ast.Str)):
            func = item.func
            target = func.text if isinstance(func, ast.Word) else func.value
            if target not in names:
                s.error("E208", f"`{target}` is not a port of mux `{mux}`", func.span,
                        did_you_mean(target, names) or f"its ports: {', '.join(names)}")
                return None
            if not item.args or any(len(arg) != 1 for arg in item.args):
                s.error("E208", f"`accept = {target} (...)` lists the other ports, separated by commas",
                        item.span, f"e.g. `accept = {target} (/replay{target})`")
                return None
            others = [arg[0] for arg in item.args]
        elif isinstance(item, (ast.Word, ast.Str)):
            if len(names) != 1:
                text = item.text if isinstance(item, ast.Word) else item.value
                s.error("E208", f"`accept = {text}`: mux `{mux}` reads {len(names)} ports; say which one takes "
                        "its Bottles", item.span, f"e.g. `accept = {names[0]} ({text})`")
                return None
            target, others = names[0], [item]
        else:
            s.error("E208", "`accept` takes ports: `/other:o`, or `/input:o (/other:o)`", item.span)
            return None
        for other in others:
            text = other.text if isinstance(other, ast.Word) else other.value if isinstance(other, ast.Str) else None
            problem = "it is not a name" if text is None else port_problem(text)
            if problem:
                s.error("E401", f"invalid YARP port name `{text if text is not None else other}`: {problem}",
                        other.span, "e.g. `/replay/icub/head/state:o`")
                return None
            if text == target:
                s.warning("W506", f"`{text}` is the port itself: its Bottles are always taken", other.span)
            elif text in out.get(target, ()):
                s.warning("W506", f"`{text}` is accepted twice for `{target}`", other.span)
            else:
                out.setdefault(target, []).append(text)
    return {k: tuple(v) for k, v in out.items()}


def _layout(ctx: Context, decl, span: Span) -> tuple[ir.ElementGroup, ...] | None:
    """The element groups a port declares: `(float64 x6, int32 x3)`."""
    s = ctx.sink
    groups = []
    if not decl:
        s.error("E213", "empty declaration `()`", span, "e.g. `(float64 x6)` or `(float64 x6, int32 x3)`")
        return None
    for arg in decl:
        words = [a.text if isinstance(a, ast.Word) else None for a in arg]
        if None in words or len(words) not in (1, 2):
            s.error("E213", "a declaration group is `<type> x<count>`, e.g. `float64 x6`", arg[0].span)
            return None
        typ = words[0]
        count = 1
        if len(words) == 2:
            w = words[1]
            if not (w.startswith("x") and w[1:].isdigit()):
                s.error("E213", f"`{w}` is not a count: write `x<count>`, e.g. `x6`", arg[1].span)
                return None
            count = int(w[1:])
            if count < 1:
                s.error("E213", "a count is at least 1", arg[1].span)
                return None
        if typ not in ir.ELEMENT_TYPES:
            s.error("E213", f"unknown element type `{typ}`", arg[0].span,
                    did_you_mean(typ, sorted(ir.ELEMENT_TYPES)) or
                    "element types: float64 float32 int8..int64 uint8..uint64 bool string")
            return None
        groups.append(ir.ElementGroup(typ, count))
    return tuple(groups)


def _topic_decl(ctx: Context, name: str, decl, span: Span, via: str):
    """(message type, fields read, their element groups, the array of
    messages whose elements give one row each) of a topic declared
    `(pkg/Name)`, `(pkg/Name field)` or `(pkg/Name array.field array.field...)`;
    (None, None, None, None) when it does not check."""
    s = ctx.sink
    if len(decl) != 1 or not all(isinstance(a, ast.Word) for a in decl[0]):
        s.error("E213", "a topic is declared with its type and optionally one numeric field: "
                "`(pkg/Name)` or `(pkg/Name field)`", span)
        return None, None, None, None
    if len(decl[0]) > 2 or (len(decl[0]) == 2 and _through_message_array(ctx, decl, via)):
        return _rows_decl(ctx, decl, span, via)
    return (*_one_field_decl(ctx, name, decl, span, via), None)


def _through_message_array(ctx: Context, decl, via: str) -> bool:
    """Does the one field of `(pkg/Name field)` name a part of the elements
    of an array of messages (`points.positions`)?"""
    msgdef, _ = _topic_type(ctx, decl, via, report=False)
    head, _, rest = decl[0][1].text.partition(".")
    f = msgdef.field(head) if msgdef is not None else None
    return f is not None and f.type.is_message and f.type.array is not None and bool(rest)


def _rows_decl(ctx: Context, decl, span: Span, via: str):
    """`(trajectory_msgs/JointTrajectory points.time_from_start points.positions)`:
    fields of each element of one array of messages, a row per element."""
    s = ctx.sink
    msgdef, store = _topic_type(ctx, decl, via)
    if msgdef is None:
        return None, None, None, None
    words = decl[0][1:]
    each = None
    fields: list[str] = []
    groups: list[ir.ElementGroup] | None = []
    for w in words:
        head, _, rest = w.text.partition(".")
        f = msgdef.field(head)
        if f is None or not f.type.is_message or f.type.array is None or not rest:
            s.error("E213", f"`{w.text}`: a topic declared with several fields reads fields of the "
                    f"elements of one array of messages of `{msgdef.name}`, each element a row",
                    w.span, f"e.g. `({msgdef.name} <array>.<field> <array>.<field>)`")
            return None, None, None, None
        if each is not None and head != each:
            s.error("E213", f"`{w.text}`: every field is of the elements of `{each}`", w.span)
            return None, None, None, None
        if via != "ros2":
            s.error("E213", "the elements of an array of messages are read from ROS 2 topics only",
                    w.span, "read the topic with `via = ros2` (the ros2 backend)")
            return None, None, None, None
        each = head
        got = _element_field(ctx, store, f.type.base, rest, w)
        if got is None:
            return None, None, None, None
        fields.append(rest)
        if got == "dynamic" or groups is None:
            groups = None
        else:
            groups.extend(got)
    return msgdef.name, tuple(fields), (tuple(groups) if groups is not None else None), each


def _element_field(ctx: Context, store, base: str, path: str, word: ast.Word):
    """The element groups of field ``path`` of message ``base`` (one row's
    part), "dynamic" for a variable-length array, None when reported."""
    s = ctx.sink
    cur = store.resolve(base)
    ftype = None
    for part in path.split("."):
        f = cur.field(part) if cur else None
        if f is None:
            s.error("E302", f"`{base}` has no field `{path}`", word.span,
                    did_you_mean(part, [x.name for x in (cur.fields if cur else ())]))
            return None
        ftype = f.type
        cur = store.resolve(f.type.base) if f.type.is_message else None
    assert ftype is not None
    if ftype.array is None and ftype.base in ("builtin_interfaces/Time", "builtin_interfaces/Duration"):
        return [ir.ElementGroup("float64", 1)]  # seconds
    if ftype.base in ir.NUMERIC_TYPES:
        if ftype.array == "sequence":
            return "dynamic"
        return [ir.ElementGroup(ftype.base, 1 if ftype.array is None else (ftype.size or 0))]
    s.error("E309", f"field `{path}` of `{base}` is not numeric (nor a time)", word.span)
    return None


def _topic_type(ctx: Context, decl, via: str, report: bool = True):
    """The message definition a topic declaration names, and its store (None: reported)."""
    s = ctx.sink
    words = [a.text for a in decl[0]]
    # the distro the dialect pass settled on ([module] distro, or --distro),
    # when the topic is of the config's ROS; else --distro if it is of the topic's
    distro = next((d for d in (ctx.distro, ctx.options.distro) if d and DISTROS.get(d) == via), None)
    store = ctx.stores.get(via, distro)
    norm = normalize_name(words[0])
    msgdef = store.resolve(norm) if norm else None
    if msgdef is None and report:
        s.error("E301", f"unknown message type `{words[0]}` ({via})", decl[0][0].span,
                did_you_mean(words[0], store.all_names()) or "write `pkg/Name`")
    return msgdef, store


def _one_field_decl(ctx: Context, name: str, decl, span: Span, via: str):
    """`(pkg/Name)` or `(pkg/Name field)`: (type, fields, groups) or Nones."""
    s = ctx.sink
    words = [a.text for a in decl[0]]
    msgdef, store = _topic_type(ctx, decl, via)
    if msgdef is None:
        return None, None, None
    norm = msgdef.name
    if len(words) == 2:
        path = words[1]
        cur: MsgDef | None = msgdef
        ftype = None
        for part in path.split("."):
            f = cur.field(part) if cur else None
            if f is None:
                s.error("E302", f"`{msgdef.name}` has no field `{path}`", decl[0][1].span,
                        did_you_mean(part, [x.name for x in (cur.fields if cur else ())]))
                return None, None, None
            ftype = f.type
            cur = store.resolve(f.type.base) if f.type.is_message else None
        assert ftype is not None
        if ftype.base not in ir.NUMERIC_TYPES or (ftype.array is None and ftype.is_message):
            leaves = numeric_leaves(store, ftype.base) if ftype.is_message and ftype.array is None else None
            if leaves is None:
                s.error("E309", f"field `{path}` of `{msgdef.name}` is not numeric", decl[0][1].span)
                return None, None, None
            return norm, tuple(f"{path}.{p}" for p, _ in leaves), tuple(ir.ElementGroup(t, 1) for _, t in leaves)
        if ftype.array is None:
            return norm, (path,), (ir.ElementGroup(ftype.base, 1),)
        if ftype.array == "fixed":
            return norm, (path,), (ir.ElementGroup(ftype.base, ftype.size or 0),)
        return norm, (path,), None
    leaves = numeric_leaves(store, msgdef)
    if leaves is None:
        example = next((f.name for f in msgdef.fields if f.type.base in ir.NUMERIC_TYPES), "field")
        s.error("E309", f"`{msgdef.name}` is not all numbers: name the numeric field to read",
                decl[0][0].span, f"e.g. `{name} ({msgdef.name} {example})`")
        return None, None, None
    return norm, tuple(p for p, _ in leaves), tuple(ir.ElementGroup(t, 1) for _, t in leaves)

