"""Pass ``message``: the entries of [message] by field path.

Checks: keys that are not field paths (E302), fields given twice (E206), a
field set both as a whole and in parts (E215: the later line is dropped), a
[message] that sets nothing while the type gives no fields either (E204).
Reads ``sections`` and ``msgdef``. Sets ``message_entries`` and ``below``,
which the ``typed`` or the ``bottles`` pass builds the message from.
"""

from __future__ import annotations

from ybg.compiler import ast
from ybg.compiler.passes.context import Context, FieldPath


def run(ctx: Context) -> None:
    sec = ctx.sections.get("message")
    if sec is None:
        return
    s = ctx.sink
    entries: dict[FieldPath, ast.Entry] = {}
    for e in sec.entries:
        path = tuple(e.key.split("."))
        if any(not p for p in path):
            s.error("E302", f"`{e.key}` is not a field path", e.key_span, "e.g. `header.frame_id`")
            continue
        if path in entries:
            s.error("E206", f"`{e.key}` is given twice in [message]", e.key_span,
                    f"first given on line {entries[path].span.line}")
            continue
        entries[path] = e
    # a field set as a whole and in parts: report the later line
    for path in sorted(entries, key=lambda p: entries[p].span.line):
        for k in range(1, len(path)):
            short = path[:k]
            if short in entries and path in entries:
                a, b = entries[short], entries[path]
                later = b if b.span.line >= a.span.line else a
                s.error("E215", f"`{'.'.join(short)}` is set as a whole and `{'.'.join(path)}` by itself",
                        later.key_span, "set either the whole field or its parts")
                del entries[path if later is b else short]
                break
    if not entries and ctx.msgdef is None:
        s.error("E204", "[message] sets no field", sec.span, "e.g. `position = arm`")
        return
    ctx.message_entries = entries
    ctx.below = index_below(entries)


def index_below(entries: dict[FieldPath, ast.Entry]) -> dict[FieldPath, dict[FieldPath, ast.Entry]]:
    """prefix -> the entries strictly below it."""
    index: dict[FieldPath, dict[FieldPath, ast.Entry]] = {}
    for p, e in entries.items():
        for k in range(len(p)):
            index.setdefault(p[:k], {})[p] = e
    return index
