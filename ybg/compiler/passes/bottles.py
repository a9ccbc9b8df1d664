"""Pass ``bottles``: the message tree when the output's type gives no
fields (a YARP port, or a ROS type whose definition was not found).

The tree follows [message]: each field path is a nested list in the order
the lines first name it, indexed elements (`points[0].x`, `points[1].x`) in
the order of their indices; a value is a literal, a list, a mux or a part of
one, `counter`, `time` or `timestamp`.
Checks: lists of mixed types (E304), words that are neither numbers nor
muxes (E304, E212), unexpected values (E105), indexed and named parts of
one label (E330), a gap in the indices (E332).
Reads ``msgdef`` (None), ``message_entries``, ``below``, ``output``,
``type_known`` and (through :mod:`~ybg.compiler.passes.muxrefs`) the
muxes. Sets ``message`` and adds to ``used_muxes``.
"""

from __future__ import annotations

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import did_you_mean
from ybg.compiler.names import identifier_problem
from ybg.compiler.passes.context import Context, FieldPath
from ybg.compiler.passes.message import written
from ybg.compiler.passes.muxrefs import is_mux_ref, is_timestamp, mux_slice, slice_types, timestamp, unknown_mux


def run(ctx: Context) -> None:
    if ctx.message_entries is None or ctx.msgdef is not None:
        return
    output = ctx.output
    ctx.message = _struct(ctx, (), output.msg_type if (output and not ctx.type_known) else None)


def _splice(ctx: Context) -> bool:
    """Does a whole mux go into a YARP Bottle as its elements, not as one list?"""
    return ctx.output is None or ctx.output.kind == "yarp"


def _struct(ctx: Context, prefix: FieldPath, msg_type: str | None) -> ir.Struct:
    entries = ctx.message_entries
    order: dict[str | int, ast.Entry] = {}
    for p, e in ctx.below.get(prefix, {}).items():
        order.setdefault(p[len(prefix)], e)
    indices = sorted(k for k in order if isinstance(k, int))
    if indices:
        if len(indices) != len(order):
            name = next(k for k in order if not isinstance(k, int))
            ctx.sink.error("E330", f"`{written(prefix)}` has both indexed elements and a part `{name}`",
                           order[name].key_span, f"name its parts `{written(prefix)}.<label>` or index "
                           f"its elements `{written(prefix)}[0]`, not both")
            return ir.Struct((), msg_type)
        missing = [k for k in range(indices[-1] + 1) if k not in order]
        if missing:
            after = min(j for j in indices if j > missing[0])
            ctx.sink.error("E332", f"`{written(prefix + (after,))}` is given but `{written(prefix + (missing[0],))}`"
                           f" is not: the elements of `{written(prefix)}` are numbered from 0 without gaps",
                           order[after].key_span, "number the elements from 0")
            return ir.Struct((), msg_type)
        order = {k: order[k] for k in indices}
    fields = []
    for name in order:
        path = prefix + (name,)
        if path in entries:
            fields.append(ir.Field(str(name), _value(ctx, entries[path]), None))
        else:
            fields.append(ir.Field(str(name), _struct(ctx, path, None), None))
    return ir.Struct(tuple(fields), msg_type)


def _value(ctx: Context, e: ast.Entry):
    items = e.items
    if len(items) == 1:
        return _item(ctx, items[0], e)
    if not items:
        return ir.Literal((), "float64", True)
    return _list(ctx, items, e)


def _list(ctx: Context, items, e: ast.Entry):
    # a list of sources: literals only, or sources like [counter, time]
    if all(isinstance(i, (ast.Str, ast.Word)) and not is_mux_ref(ctx, i)
           and not (isinstance(i, ast.Word) and i.text in ("counter", "time", "timestamp")) for i in items):
        values = []
        types = set()
        for i in items:
            v, t = _literal(ctx, i)
            if v is None:
                return ir.Default()
            values.append(v)
            types.add(t)
        if len(types) > 1:
            if types <= {"int32", "int64", "float64"}:
                values = [float(v) for v in values]
                types = {"float64"}
            else:
                ctx.sink.error("E304", "a list holds values of one type", e.span,
                               "quote all items for text, or write only numbers")
                return ir.Default()
        return ir.Literal(tuple(values), types.pop(), True)
    fields = []
    for k, i in enumerate(items):
        fields.append(ir.Field(str(k), _item(ctx, i, e), None))
    return ir.Struct(tuple(fields), None)


def _item(ctx: Context, item: ast.Item, e: ast.Entry):
    if isinstance(item, ast.Bracket):
        if not item.items:
            return ir.Literal((), "float64", True)
        if len(item.items) == 1 and is_mux_ref(ctx, item.items[0]):
            got = mux_slice(ctx, item.items[0])
            if got is None:
                return ir.Default()
            mux, start, stop, index = got
            if _part_of_rows(ctx, mux, start, stop, index, item.items[0].span):
                return ir.Default()
            return ir.MuxRef(mux.name, start, stop, index, False, _common_type(slice_types(mux, start, stop, index)))
        return _list(ctx, item.items, e)
    if isinstance(item, ast.Word) and item.text == "counter":
        return ir.Counter("int32")
    if isinstance(item, ast.Word) and item.text == "time":
        return ir.Seconds()
    if is_timestamp(item):
        return timestamp(ctx, item)
    if is_mux_ref(ctx, item):
        got = mux_slice(ctx, item)
        if got is None:
            return ir.Default()
        mux, start, stop, index = got
        if _part_of_rows(ctx, mux, start, stop, index, item.span):
            return ir.Default()
        return ir.MuxRef(mux.name, start, stop, index, index is None and _splice(ctx),
                         _common_type(slice_types(mux, start, stop, index)))
    if isinstance(item, (ast.Str, ast.Word)):
        v, t = _literal(ctx, item)
        if v is None:
            return ir.Default()
        return ir.Literal((v,), t, False)
    ctx.sink.error("E105", "unexpected value in [message]", item.span,
                   "values are text, numbers, lists `[a, b]`, mux names, counter, time or timestamp")
    return ir.Default()


def _part_of_rows(ctx: Context, mux: ir.Mux, start: int, stop: int | None, index: int | None, span) -> bool:
    """A part of a mux of rows (one per element of an array of messages),
    which goes into a Bottle whole: reported, True."""
    if mux.rows and (index is not None or start != 0 or stop is not None):
        ctx.sink.error("E305", f"mux `{mux.name}` holds one row per element of an array of messages: "
                       "it goes whole into the Bottle, one list per row", span,
                       f"write `{mux.name}` (the rows one by one) or `[{mux.name}]` (in one list)")
        return True
    return False


def _literal(ctx: Context, item):
    """(value, element type), or (None, None) when reported."""
    if isinstance(item, ast.Str):
        return item.value, "string"
    b = item.boolean()
    if b is not None:
        return b, "bool"
    n = item.number()
    if n is None:
        if identifier_problem(item.text) is None and did_you_mean(item.text, list(ctx.mux_sections)):
            unknown_mux(ctx, item.text, item.span)
        else:
            ctx.sink.error("E304", f"`{item.text}` is neither a number nor a mux", item.span,
                           f'quote text: `"{item.text}"`')
        return None, None
    if isinstance(n, float):
        return n, "float64"
    return n, "int32" if -2**31 <= n < 2**31 else "int64"


def _common_type(types) -> str:
    """The element type of a part of a mux in an untyped Bottle: "number"
    for an undeclared port's elements (each goes on as it came: an integer
    stays an integer), "mixed" when the declared types differ."""
    if types is None:
        return ir.NUMBER
    if not types:
        return "float64"
    ts = set(types)
    return ts.pop() if len(ts) == 1 else "mixed"
