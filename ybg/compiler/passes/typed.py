"""Pass ``typed``: the message tree of an output of a known message type.

Every field of the definition gets a value: what [message] sets (a literal,
a mux or a part of one, `counter`, `time`, `timestamp`), or its default; a
nested message is a struct of its own fields.
An array of messages has the elements the config indexes
(`transforms[0].child_frame_id = ...`): each a struct of its own fields, or a
mux filling its numbers (`points[0] = goal`).
Checks: unknown fields (E302), fields of the other ROS version (E311), each
value against its field's type (E304 to E310, E317), sequences that must be
of one length (E312), indices (E330 on a field that is not an array of
messages, E331 beyond its size, E332 a gap), a value given to a whole
array of messages (E333).
Reads ``msgdef``, ``message_entries``, ``below``, ``store``, ``ros``,
``stores`` and (through :mod:`~ybg.compiler.passes.muxrefs`) the muxes.
Sets ``message`` and adds to ``used_muxes``.
"""

from __future__ import annotations

import math

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import Edit, Fix, Span, did_you_mean
from ybg.compiler.names import converted_name
from ybg.compiler.msgtypes import MsgDef, numeric_leaves
from ybg.compiler.names import identifier_problem
from ybg.compiler.passes.context import Context, FieldPath
from ybg.compiler.passes.message import written
from ybg.compiler.passes.muxrefs import (image_misplaced, is_mux_ref, is_timestamp, mux_slice, slice_types, timestamp,
                                         unknown_mux)

#: sequences of a message that must be empty or of one length
SAME_LENGTH = {
    "sensor_msgs/JointState": ("name", "position", "velocity", "effort"),
    "sensor_msgs/MultiDOFJointState": ("joint_names", "transforms", "twists", "wrench"),
}

INT_RANGE = {
    "int8": (-2**7, 2**7 - 1), "uint8": (0, 2**8 - 1), "byte": (0, 255), "char": (0, 255),
    "int16": (-2**15, 2**15 - 1), "uint16": (0, 2**16 - 1),
    "int32": (-2**31, 2**31 - 1), "uint32": (0, 2**32 - 1),
    "int64": (-2**63, 2**63 - 1), "uint64": (0, 2**64 - 1),
}

Entries = dict[FieldPath, ast.Entry]


def run(ctx: Context) -> None:
    if ctx.message_entries is None or ctx.msgdef is None:
        return
    struct = _struct(ctx, ctx.msgdef, (), ctx.message_entries, ctx.below)
    _check_lengths(ctx, ctx.msgdef, struct, ctx.message_entries)
    if ctx.msgdef.name == ir.IMAGE_TYPE:
        struct = _image_message(ctx, struct, ctx.message_entries)
    ctx.message = struct


def build_struct(ctx: Context, msgdef: MsgDef, entries: Entries, below: dict[FieldPath, Entries]) -> ir.Struct:
    """The message of type ``msgdef`` that ``entries`` set (another section
    than [message]: [camera_info])."""
    return _struct(ctx, msgdef, (), entries, below)


def _struct(ctx: Context, msgdef: MsgDef, prefix: FieldPath, entries: Entries,
            below: dict[FieldPath, Entries]) -> ir.Struct:
    s = ctx.sink
    mine = below.get(prefix, {})
    names = [f.name for f in msgdef.fields]
    for p, e in mine.items():
        head = p[len(prefix)]
        if msgdef.field(head) is None:
            other = _other_dialect_field(ctx, msgdef.name, head)
            if other:
                s.error("E311", f"`{written(p)}`: {other}", e.key_span, _other_dialect_hint(ctx, msgdef.name, head),
                        ctx.fix(Edit(Span(e.span.line, 1, e.span.end_line + 1, 1), "")))
            else:
                s.error("E302", f"`{msgdef.name}` has no field `{head}`", e.key_span,
                        did_you_mean(head, names) or f"fields: {', '.join(names)}")
    fields = []
    for f in msgdef.fields:
        path = prefix + (f.name,)
        if path in entries:
            fields.append(ir.Field(f.name, _value(ctx, entries[path], f.type), f.type))
        elif path in below:
            fields.append(ir.Field(f.name, _below(ctx, f.type, path, entries, below), f.type))
        else:
            fields.append(ir.Field(f.name, _default(ctx, f, path), f.type))
    return ir.Struct(tuple(fields), msgdef.name)


def _below(ctx: Context, t: ir.TypeRef, path: FieldPath, entries: Entries,
           below: dict[FieldPath, Entries]):
    """The value of the field of type ``t`` at ``path`` set in parts: a
    nested message by its fields, an array of messages by its elements."""
    s = ctx.sink
    p, e = next(iter(below[path].items()))
    part = p[len(path)]
    is_message_array = t.is_message and t.array is not None
    if isinstance(part, int) and not is_message_array:
        s.error("E330", f"`{written(path)}` is {t}, not an array of messages: it has no "
                f"element `{written(p[:len(path) + 1])}` to set", e.key_span,
                f"give the whole field: `{written(path)} = ...`" if t.array else None)
        return ir.Default()
    if is_message_array and not isinstance(part, int):
        s.error("E302", f"`{written(path)}` is {t}, an array: it has no field `{part}`",
                e.key_span, f"set a field of one element: `{written(path)}[0].{written(p[len(path):])}`")
        return ir.Default()
    if is_message_array:
        return _message_array(ctx, t, path, entries, below)
    if not t.is_message or t.array is not None:
        s.error("E302", f"`{written(path)}` is a {t}, it has no field `{part}`", e.key_span)
        return ir.Default()
    sub = ctx.store.resolve(t.base)
    if sub is None:
        return ir.Default()
    return _struct(ctx, sub, path, entries, below)


def _message_array(ctx: Context, t: ir.TypeRef, path: FieldPath, entries: Entries,
                   below: dict[FieldPath, Entries]) -> ir.MessageArray | ir.Default:
    """The elements of the array of messages at ``path`` that the config
    indexes. A sequence has elements 0 to the highest index, each given; a
    fixed-size array has its size, an element not given its defaults."""
    s = ctx.sink
    sub = ctx.store.resolve(t.base)
    if sub is None:
        return ir.Default()
    first: dict[int, ast.Entry] = {}
    for p, e in sorted(below[path].items(), key=lambda pe: (pe[1].span.line, pe[1].span.column)):
        first.setdefault(p[len(path)], e)
    ok = True
    if t.size is not None:
        for k, e in sorted(first.items()):
            if k >= t.size:
                s.error("E331", f"`{written(path + (k,))}` is beyond `{written(path)}`, which is {t}: "
                        f"its elements are {written(path)}[0] to {written(path)}[{t.size - 1}]", e.key_span)
                ok = False
    if not ok:
        return ir.Default()
    count = t.size if t.array == "fixed" else max(first) + 1
    if t.array != "fixed":
        missing = [k for k in range(count) if k not in first]
        if missing:
            k = missing[0]
            after = min(j for j in first if j > k)
            s.error("E332", f"`{written(path + (after,))}` is given but `{written(path + (k,))}` is not: "
                    f"the elements of `{written(path)}` are numbered from 0 without gaps",
                    first[after].key_span, f"set `{written(path + (k,))}`, or number the elements from 0")
            return ir.Default()
    elements = []
    for k in range(count):
        elem = path + (k,)
        if elem in entries:
            value = _value(ctx, entries[elem], t.element())
            if isinstance(value, ir.Default):  # reported
                value = _struct(ctx, sub, elem, {}, {})
            elements.append(value)
        else:
            elements.append(_struct(ctx, sub, elem, entries, below))
    return ir.MessageArray(tuple(elements), t.base)


def _default(ctx: Context, f, path: FieldPath):
    """The default of an unset field: a nested message becomes a struct of
    its own defaults, so that backends see the layout."""
    t = f.type
    if t.is_message and t.array is None:
        sub = ctx.store.resolve(t.base)
        if sub is not None:
            return _struct(ctx, sub, path, {}, {})
    if t.is_message and t.array == "fixed":
        sub = ctx.store.resolve(t.base)
        if sub is not None:
            return ir.MessageArray(tuple(_struct(ctx, sub, path + (k,), {}, {}) for k in range(t.size or 0)),
                                   t.base)
    return ir.Default(f.default)


def _other_dialect_field(ctx: Context, msg: str, field_name: str) -> str | None:
    other = "ros1" if ctx.ros == "ros2" else "ros2"
    try:
        store = ctx.stores.get(other, None)
    except ValueError:
        return None
    d = store.resolve(msg)
    if d is not None and d.field(field_name) is not None:
        here = "ROS 2" if ctx.ros == "ros2" else "ROS 1"
        there = "ROS 1" if other == "ros1" else "ROS 2"
        return f"`{msg}` has no field `{field_name}` in {here}; it exists only in {there}"
    return None


def _other_dialect_hint(ctx: Context, msg: str, field_name: str) -> str:
    if msg == "std_msgs/Header" and field_name == "seq":
        if ctx.ros == "ros2":
            return ("ROS 2 headers have no sequence number: remove the line (the stamp and "
                    "frame_id remain); a legacy file converts with "
                    f"`ybgc fmt --to named --ros2 FILE -o {converted_name(ctx.sink.file)}`")
        return "for ROS 1 add `header.seq = counter`"
    return "remove the line, or compile for the other ROS version"


def _value(ctx: Context, e: ast.Entry, t: ir.TypeRef):
    """The value of the field of type ``t`` that entry ``e`` sets."""
    s = ctx.sink
    items = e.items
    span = e.span
    image = _image_mux(ctx, items)
    if image is not None:
        if ctx.msgdef is not None and ctx.msgdef.name == ir.IMAGE_TYPE and e.key == "data":
            ctx.used_muxes.add(image.name)
            return ir.ImageFrame(image.name, image.image or "")
        image_misplaced(ctx, image.name, items[0].span)
        return ir.Default()
    if t.is_message and t.array is not None and not any(is_mux_ref(ctx, i) for i in items):
        return _whole_message_array(ctx, e, t)
    if t.is_message and t.array is None and t.base not in ("builtin_interfaces/Time",):
        # a whole nested message: only a mux of the same width
        if len(items) == 1 and is_mux_ref(ctx, items[0]):
            return _mux_into_message(ctx, items[0], t, e)
        s.error("E308", f"`{e.key}` is a {t.base}: set its fields one by one", span,
                f"e.g. `{e.key}.<field> = ...`, or give a mux of its width")
        return ir.Default()
    if len(items) == 1 and isinstance(items[0], ast.Word) and items[0].text == "counter":
        if t.base not in ir.INTEGER_TYPES or t.array is not None:
            s.error("E306", f"`counter` is an integer, but `{e.key}` is {t}", items[0].span,
                    "use counter for an integer field such as header.seq (ROS 1)")
        return ir.Counter(t.base if t.base in ir.INTEGER_TYPES else "uint32")
    if len(items) == 1 and is_timestamp(items[0]):
        ts = timestamp(ctx, items[0])
        if t.array is not None or t.base not in ("time", "builtin_interfaces/Time"):
            s.error("E307", f"`timestamp` is a time, but `{e.key}` is {t}", items[0].span,
                    "use it for a time field such as header.stamp")
        return ts
    if len(items) == 1 and isinstance(items[0], ast.Word) and items[0].text == "time":
        if t.array is not None or t.base not in ir.FLOAT_TYPES:
            s.error("E304", f"`time` is seconds as float64, but `{e.key}` is {t}", items[0].span)
        return ir.Seconds()
    if t.base in ("time", "duration", "builtin_interfaces/Time", "builtin_interfaces/Duration") and t.array is None:
        s.error("E307", f"`{e.key}` is a {t.base}: give `timestamp` or `timestamp(<mux>)`", span)
        return ir.Default()
    if any(is_mux_ref(ctx, i) for i in items):
        if len(items) != 1:
            s.error("E305", "a field takes one mux reference, not a list mixing muxes and values",
                    span, "concatenate inputs in one mux instead")
            return ir.Default()
        return _mux_into_field(ctx, items[0], t, e)
    # literals
    if len(items) == 1 and isinstance(items[0], ast.Bracket):
        items = items[0].items
        as_list = True
    else:
        as_list = t.array is not None
    if t.is_message:
        s.error("E304", f"`{e.key}` is a list of {t.base} messages; only muxes and literals of "
                "primitive types are supported", span)
        return ir.Default()
    values = []
    for it in items:
        v = _literal(ctx, it, t.base, e.key)
        if v is None:
            return ir.Default()
        values.append(v)
    if t.array is None:
        if as_list or len(values) != 1:
            if len(values) == 0 and t.base == "string":
                return ir.Literal(("",), "string", False)
            s.error("E304", f"`{e.key}` is one {t.base}, not {len(values) or 'no'} values", span,
                    f"write `{e.key} = <one {t.base}>`")
            return ir.Default()
        return ir.Literal(tuple(values), t.base, False)
    if t.array == "fixed" and len(values) != t.size:
        s.error("E310", f"`{e.key}` is {t}: it needs exactly {t.size} values, not {len(values)}", span)
    if t.array == "sequence" and t.size is not None and len(values) > t.size:
        s.error("E310", f"`{e.key}` is {t}: at most {t.size} values, not {len(values)}", span)
    return ir.Literal(tuple(values), t.base, True)


def _image_mux(ctx: Context, items) -> ir.Mux | None:
    """The image mux that ``items`` name on their own (`data = eye`), if any."""
    if len(items) != 1 or not isinstance(items[0], ast.Word):
        return None
    mux = ctx.muxes.get(items[0].text)
    return mux if mux is not None and mux.image is not None else None


def _image_message(ctx: Context, struct: ir.Struct, entries: Entries) -> ir.Struct:
    """A sensor_msgs/Image whose `data` is a frame: the frame gives `height`,
    `width`, `encoding`, `is_bigendian` and `step` (E343 when the config sets
    them; `encoding` may be written, and must then be the frame's: E342), and
    `header.stamp`, unless set, is the frame's envelope (`timestamp(<mux>)`)."""
    fields = {f.name: f for f in struct.fields}
    frame = fields["data"].source if "data" in fields else None
    if not isinstance(frame, ir.ImageFrame):
        return struct
    out = []
    for f in struct.fields:
        e = entries.get((f.name,))
        if f.name in ir.FRAME_FIELDS and e is not None:
            if f.name == "encoding" and isinstance(f.source, ir.Literal):
                if f.source.values[0] != frame.encoding:
                    ctx.sink.error("E342", f"`encoding = \"{f.source.values[0]}\"`, but mux `{frame.mux}` reads "
                                   f"{frame.encoding} frames", e.span,
                                   f"declare the port `(image {f.source.values[0]})`, or remove the line: the "
                                   "frame gives the encoding")
            elif f.name != "encoding" or not isinstance(f.source, ir.Default):
                ctx.sink.error("E343", f"`{f.name}` comes from the frame of mux `{frame.mux}`: a "
                               "sensor_msgs/Image is its frame, with a header", e.span,
                               "remove the line (set only `header.frame_id`, `header.stamp`)")
            f = ir.Field(f.name, ir.Default(), f.type)
        if f.name == "header" and isinstance(f.source, ir.Struct):
            f = ir.Field(f.name, _stamped(ctx, f.source, frame.mux), f.type)
        out.append(f)
    return ir.Struct(tuple(out), struct.msg_type)


def _stamped(ctx: Context, header: ir.Struct, mux: str) -> ir.Struct:
    """``header`` with the envelope of ``mux``'s frames as its stamp, unless set."""
    return ir.Struct(tuple(
        ir.Field(f.name, ir.Timestamp("envelope", mux, "ros2" if ctx.ros == "ros2" else "ros1"), f.type)
        if f.name == "stamp" and (isinstance(f.source, ir.Default) or isinstance(f.source, ir.Struct) and all(
            isinstance(x.source, ir.Default) for x in f.source.fields)) else f
        for f in header.fields), header.msg_type)


def _whole_message_array(ctx: Context, e: ast.Entry, t: ir.TypeRef):
    """An array of messages given as a whole: only empty (`[]`, or nothing)."""
    items = e.items
    if len(items) == 1 and isinstance(items[0], ast.Bracket):
        items = items[0].items
    if items:
        ctx.sink.error("E333", f"`{e.key}` is {t}, an array of messages: it takes no value but its "
                       "elements' fields", items[0].span,
                       f"set the fields of each element: `{e.key}[0].<field> = ...`, `{e.key}[1].<field> = ...`")
        return ir.Default()
    if t.array == "fixed" and t.size:
        ctx.sink.error("E310", f"`{e.key}` is {t}: it needs exactly {t.size} elements, not 0", e.span)
        return ir.Default()
    return ir.MessageArray((), t.base)


def _literal(ctx: Context, item: ast.Item, base: str, key: str):
    """One literal element of type ``base``, or None (reported)."""
    s = ctx.sink
    if base in ("string", "wstring"):
        if isinstance(item, ast.Str):
            return item.value
        s.error("E304", f"`{key}` takes text: quote it", item.span,
                f'write `"{item.text}"`' if isinstance(item, ast.Word) else None)
        return None
    if isinstance(item, ast.Str):
        s.error("E304", f"`{key}` is {base}, not text", item.span,
                "remove the quotes" if ast.Word(item.value).number() is not None else None)
        return None
    if not isinstance(item, ast.Word):
        s.error("E304", f"`{key}` takes {base} values", item.span)
        return None
    if base == "bool":
        b = item.boolean()
        n = item.number()
        if b is None and n in (0, 1) and isinstance(n, int):
            b = bool(n)
        if b is None:
            s.error("E304", f"`{key}` is bool: true or false, not `{item.text}`", item.span)
        return b
    n = item.number()
    if n is None:
        if item.text in ("counter", "timestamp", "time"):
            s.error("E304", f"`{item.text}` cannot be an item of a list", item.span)
        elif identifier_problem(item.text) is None:
            unknown_mux(ctx, item.text, item.span)
        else:
            s.error("E304", f"`{key}` is {base}, not `{item.text}`", item.span)
        return None
    if base in ir.FLOAT_TYPES:
        return float(n)
    if isinstance(n, float):
        if n.is_integer() and math.isfinite(n):
            n = int(n)
        else:
            s.error("E304", f"`{key}` is {base}, an integer, not `{item.text}`", item.span)
            return None
    lo, hi = INT_RANGE.get(base, (-2**63, 2**64))
    if not lo <= n <= hi:
        s.error("E317", f"{n} is out of range for {base} ({lo}..{hi})", item.span)
        return None
    return n


def _rows_into_typed(ctx: Context, mux: ir.Mux, item: ast.Item, e: ast.Entry) -> bool:
    """A mux of rows (one per element of an array of messages) fills an
    untyped Bottle only: reported, True."""
    if not mux.rows:
        return False
    each = next(i.each for i in mux.inputs if i.each)
    ctx.sink.error("E305", f"`{e.key}` is a field of a typed message, but mux `{mux.name}` holds one row per "
                   f"element of `{each}`", item.span,
                   "a mux of rows fills an untyped Bottle: a YARP port without `type`, one list per row")
    return True


def _mux_into_field(ctx: Context, item: ast.Item, t: ir.TypeRef, e: ast.Entry):
    s = ctx.sink
    got = mux_slice(ctx, item)
    if got is None:
        return ir.Default()
    mux, start, stop, index = got
    if _rows_into_typed(ctx, mux, item, e):
        return ir.Default()
    types = slice_types(mux, start, stop, index)
    if index is None and t.array is None:
        s.error("E305", f"`{e.key}` is one {t.base}, but `{mux.name}` is a list of elements", item.span,
                f"take one element: `{mux.name}[0]`")
        return ir.Default()
    if index is not None and t.array is not None:
        s.error("E305", f"`{e.key}` is {t}, but `{mux.name}[{index}]` is one element", item.span,
                f"take a range: `{mux.name}[{index}:{index + 1}]`")
        return ir.Default()
    if t.is_message or t.base in ("time", "duration"):
        s.error("E305", f"`{e.key}` is {t}, a list of {t.base}: a mux fills a list of numbers, bool or text",
                item.span, "a mux of its width fills one nested message (`pose = m`), not a list of them; "
                f"index the element it fills (`{e.key}[0] = {written((mux.name,))}`)" if t.is_message else
                "a mux of its width fills one nested message (`pose = m`), not a list of them")
        return ir.Default()
    if types is not None:
        bad = sorted({x for x in types if not _fits(x, t.base)})
        if bad:
            s.error("E305", f"`{e.key}` is {t}, but mux `{mux.name}` gives {', '.join(bad)}", item.span,
                    "declare the port element types to match, or convert them (`none_double`)")
            return ir.Default()
    # the number of elements, when known before run time: the mux's declared
    # width, or the range written
    n = len(types) if types is not None else (stop - start if stop is not None else None)
    if n is not None and t.array == "fixed" and n != t.size:
        s.error("E310", f"`{e.key}` is {t}: it needs exactly {t.size} elements, `{_written(mux.name, start, stop)}`"
                f" gives {n}", item.span, f"take {t.size}: `{mux.name}[{start}:{start + (t.size or 0)}]`")
    if n is not None and t.array == "sequence" and t.size is not None and n > t.size:
        s.error("E310", f"`{e.key}` is {t}: at most {t.size} elements, `{_written(mux.name, start, stop)}`"
                f" gives {n}", item.span, f"take at most {t.size}: `{mux.name}[{start}:{start + t.size}]`")
    return ir.MuxRef(mux.name, start, stop, index, False, t.base)


def _written(mux: str, start: int, stop: int | None) -> str:
    """A part of a mux as the config writes it."""
    if start == 0 and stop is None:
        return mux
    return f"{mux}[{start}:{'' if stop is None else stop}]"


def _mux_into_message(ctx: Context, item: ast.Item, t: ir.TypeRef, e: ast.Entry):
    s = ctx.sink
    got = mux_slice(ctx, item)
    if got is None:
        return ir.Default()
    mux, start, stop, index = got
    if _rows_into_typed(ctx, mux, item, e):
        return ir.Default()
    leaves = numeric_leaves(ctx.store, t.base)
    if leaves is None:
        s.error("E309", f"`{e.key}` is a {t.base}, which is not all numbers: a mux cannot fill it",
                item.span, f"set its fields one by one: `{e.key}.<field> = ...`")
        return ir.Default()
    if index is not None:
        s.error("E309", f"`{e.key}` is a {t.base} of {len(leaves)} numbers, not one element", item.span)
        return ir.Default()
    types = slice_types(mux, start, stop, None)
    n = len(types) if types is not None else (stop - start if stop is not None else None)
    if n is not None and n != len(leaves):
        s.error("E309", f"`{e.key}` is a {t.base} of {len(leaves)} numbers "
                f"({', '.join(p for p, _ in leaves)}), but `{_written(mux.name, start, stop)}` gives {n}",
                item.span, *_width_hint(ctx, mux, start, stop, n, [p for p, _ in leaves], t, item, e))
        return ir.Default()
    if types is not None:
        bad = sorted({x for x, (_, ft) in zip(types, leaves) if not _fits(x, ft)})
        if bad:
            s.error("E305", f"`{e.key}` holds {', '.join(sorted({ft for _, ft in leaves}))}, "
                    f"mux `{mux.name}` gives {', '.join(bad)}", item.span)
            return ir.Default()
    if n is None:
        _silent_cut(ctx, item, e, t, mux, start, leaves)
    _check_quaternions(ctx, mux, start, [p for p, _ in leaves], t, item, e)
    return ir.MuxRef(mux.name, start, stop, None, False, "float64",
                     tuple(p for p, _ in leaves), tuple(ft for _, ft in leaves))


def _width_hint(ctx: Context, mux: ir.Mux, start: int, stop: int | None, n: int, leaves: list[str],
                t: ir.TypeRef, item: ast.Item, e: ast.Entry) -> tuple[str, Fix | None]:
    """The hint and fix of E309 for a part of ``mux`` of ``n`` numbers into a
    nested message of the numbers ``leaves``: the range it takes, when the
    mux has it; Euler angles converted, when one number is missing where a
    quaternion goes; else what gives the numbers."""
    need = len(leaves)
    width = mux.width
    euler = _euler_at(mux, start, n, leaves)
    if euler is not None:
        conv = f"euler_to_quat(rpy, deg)[{euler}:{euler + 3}]"
        key, section = ("function", f"[{mux.name}]") if ctx.legacy else ("convert", f"[mux {mux.name}]")
        hint = (f"if elements {euler}..{euler + 2} of `{mux.name}` are Euler angles, make them the quaternion "
                f"(4 numbers) in {section}: `{key} = {conv}` (roll, pitch, yaw in degrees; `rad` for "
                f"radians; the other axis orders in docs/config.md)")
        if stop is not None and stop < width:
            # the elements after the range move by one: which lines to change is the user's choice
            return (hint + f"; then take `{mux.name}[{start}:{stop + 1}]`, and the elements after it one "
                    "place on"), None
        edits = [_add_converter(ctx, mux.name, conv)]
        if stop is not None:
            edits.append(Edit(item.span, f"{mux.name}[{start}:{stop + 1}]"))
            hint += f", and `{e.key} = {mux.name}[{start}:{stop + 1}]`"
        return hint, ctx.fix(*edits)
    if width is None or start + need <= width:
        taken = f"{mux.name}[{start}:{start + need}]"
        return f"take a range: `{taken}`", ctx.fix(Edit(item.span, taken))
    return (f"`{mux.name}` has {width - start} elements from {start}, and a {t.base} takes {need}: read them "
            f"all in the mux (declare what its ports send: `(float64 x<N>)`), or set the fields one by one "
            f"(`{e.key}.{leaves[0]} = {mux.name}[{start}]`)"), None


def _euler_at(mux: ir.Mux, start: int, n: int, leaves: list[str]) -> int | None:
    """Where in ``mux`` three Euler angles begin that, made a quaternion,
    give the part of ``n`` numbers from ``start`` the ``leaves`` it fills:
    one number short of them, the missing one in a quaternion, and the
    three numbers that come as they are from YARP ports; else None."""
    if n != len(leaves) - 1 or mux.element_types is None:
        return None
    k = _quaternion_leaf(leaves)
    known = quaternion_elements(mux)
    if k is None or known is None:
        return None
    a = start + k
    if any(known[a:a + 3]) or not all(x in ir.NUMERIC_TYPES for x in mux.element_types[a:a + 3]):
        return None
    return a


def _quaternion_leaf(leaves: list[str]) -> int | None:
    """The index of the first leaf of a quaternion (`x y z w` of one prefix) in ``leaves``."""
    for k in range(len(leaves) - 3):
        prefix = leaves[k][:-1]
        if prefix[-1:] in ("", ".") and leaves[k:k + 4] == [prefix + c for c in "xyzw"]:
            return k
    return None


def _add_converter(ctx: Context, mux: str, conv: str) -> Edit:
    """The edit that appends the converter ``conv`` to [mux <mux>]: to its
    `convert`, or in a `convert` line of its own after its last line."""
    entry = ctx.mux_keys.get(mux, {}).get("convert")
    if entry is not None:
        end = entry.span
        return Edit(Span(end.end_line, end.end_column, end.end_line, end.end_column),
                    f", {conv}" if entry.items else f" {conv}")
    sec = ctx.mux_sections[mux]
    last = sec.entries[-1].span if sec.entries else sec.span
    return Edit(Span(last.end_line + 1, 1, last.end_line + 1, 1), f"convert = {conv}\n")


def _silent_cut(ctx: Context, item: ast.Item, e: ast.Entry, t: ir.TypeRef, mux: ir.Mux, start: int,
                leaves: list) -> None:
    """W511: a nested message takes its numbers from a mux of unknown width,
    without a range, so whatever a Bottle brings beyond them is dropped."""
    ctx.silent_cuts.add(mux.name)
    undeclared = [i.name for i in mux.inputs if i.layout is None]
    stop = start + len(leaves)
    port = undeclared[0] if undeclared else "<port>"
    ctx.sink.warning(
        "W511", f"`{e.key}` is a {t.base} of {len(leaves)} numbers ({', '.join(p for p, _ in leaves)}): it takes "
        f"values {start} to {stop - 1} of mux `{mux.name}`, whose port{'s' if len(undeclared) > 1 else ''} "
        f"{', '.join(f'`{p}`' for p in undeclared)} declare{'' if len(undeclared) > 1 else 's'} no elements; "
        f"a Bottle's values beyond those are dropped (the module says so once)", item.span,
        f"declare what the port sends (`{port} (float64 x<N>)`) and take the range "
        f"(`{e.key} = {mux.name}[{start}:{stop}]`); the range alone says the cut is meant")


def _check_quaternions(ctx: Context, mux: ir.Mux, start: int, leaves: list[str], t: ir.TypeRef,
                       item: ast.Item, e: ast.Entry) -> None:
    """W520: a quaternion (``x y z w`` leaves of a geometry_msgs/Quaternion)
    filled with elements that come as they are from YARP ports: nothing says
    they are a quaternion and not an axis-angle or Euler angles."""
    known = quaternion_elements(mux)
    if known is None:
        return
    for k in range(len(leaves) - 3):
        prefix = leaves[k][:-1]
        if [leaf[len(prefix):] for leaf in leaves[k:k + 4]] != ["x", "y", "z", "w"] or \
                not all(leaf.startswith(prefix) for leaf in leaves[k:k + 4]) or prefix[-1:] not in ("", "."):
            continue
        a = start + k
        if all(known[a:a + 4]):
            continue
        ports = ", ".join(i.name for i in mux.inputs if i.kind == "yarp")
        field = f"{e.key}.{prefix[:-1]}" if prefix else e.key
        ctx.sink.warning(
            "W520", f"`{field}` is a quaternion (x y z w): elements {a}..{a + 3} of mux `{mux.name}` come as "
            f"they are from {ports or 'its inputs'}", item.span,
            f"an axis-angle (iCub's Cartesian controller: x y z ax ay az theta) needs "
            f"`convert = axis_angle_to_quat[{a}:{a + 4}]`, Euler angles `euler_to_quat(rpy, deg)[{a}:{a + 3}]`; "
            f"if the port sends a quaternion, say so: `convert = quat_normalize[{a}:{a + 4}]`")


def quaternion_elements(mux: ir.Mux) -> list[bool] | None:
    """For each element of ``mux`` after its converters: is it known to be
    part of a quaternion? A typed ROS topic's fields are what they say; a
    converter that makes a quaternion makes its last four results one; the
    elements of a YARP port are not known to be anything. None: the width is
    known only at run time."""
    known: list[bool] = []
    for inp in mux.inputs:
        if inp.width is None:
            return None
        known.extend([inp.kind != "yarp"] * inp.width)
    for c in mux.converters:
        if isinstance(c, ir.GeometryConverter):
            out = [False] * c.width_out
            if c.name in ir.QUATERNION_RESULTS:
                out[-4:] = [True] * 4
            known[c.start:c.start + c.width_in] = out
    return known


def _check_lengths(ctx: Context, msgdef: MsgDef, struct: ir.Struct, entries: Entries) -> None:
    group = SAME_LENGTH.get(msgdef.name)
    if not group:
        return
    lengths: dict[str, int] = {}
    for f in struct.fields:
        if f.name not in group:
            continue
        n = _static_length(ctx, f.source)
        if n:
            lengths[f.name] = n
    if len(set(lengths.values())) > 1:
        first, n0 = next(iter(lengths.items()))
        for name, n in lengths.items():
            if n != n0:
                e = entries.get((name,))
                ctx.sink.error(
                    "E312", f"`{name}` has {n} elements but `{first}` has {n0}",
                    e.span if e else None,
                    f"in {msgdef.name}, {', '.join(group)} are empty or of one length")


def _static_length(ctx: Context, src) -> int | None:
    """The number of elements of a field's value when known before run time."""
    if isinstance(src, ir.MessageArray):
        return len(src.elements)
    if isinstance(src, ir.Literal):
        return len(src.values) if src.is_list else None
    if isinstance(src, ir.MuxRef):
        if src.index is not None:
            return 1
        w = ctx.muxes[src.mux].width
        if w is None:
            if src.stop is not None:
                return src.stop - src.start
            return None
        stop = w if src.stop is None else src.stop
        return stop - src.start
    return None


def _fits(elem: str, field_base: str) -> bool:
    """Can a mux element of type ``elem`` go into a field element of ``field_base``?"""
    if elem == field_base:
        return True
    if field_base in ir.FLOAT_TYPES:
        return elem in ir.NUMERIC_TYPES
    if field_base in ir.INTEGER_TYPES:
        if elem not in ir.INTEGER_TYPES:
            return False
        lo, hi = INT_RANGE[field_base]
        elo, ehi = INT_RANGE[elem]
        return lo <= elo and ehi <= hi
    if field_base == "bool":
        return elem == "bool"
    if field_base in ("string", "wstring"):
        return elem == "string"
    return False
