"""Pass ``message``: the entries of [message] by field path.

A key may index an element of an array of messages: `transforms[0].child_frame_id`
is the path ``("transforms", 0, "child_frame_id")``.
Checks: keys that are not field paths (E302), fields given twice (E206), a
field set both as a whole and in parts (E215: the later line is dropped), a
[message] that sets nothing while the type gives no fields either (E204).
Reads ``sections`` and ``msgdef``. Sets ``message_entries`` and ``below``,
which the ``typed`` or the ``bottles`` pass builds the message from.
"""

from __future__ import annotations

import re

from ybg.compiler import ast
from ybg.compiler.passes.context import Context, FieldPath


def run(ctx: Context) -> None:
    sec = ctx.sections.get("message")
    if sec is None:
        return
    s = ctx.sink
    entries: dict[FieldPath, ast.Entry] = {}
    for e in sec.entries:
        path = field_path(e.key)
        if path is None:
            s.error("E302", f"`{e.key}` is not a field path", e.key_span,
                    "e.g. `header.frame_id`, or `transforms[0].child_frame_id` for an element of an array")
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
                s.error("E215", f"`{written(short)}` is set as a whole and `{written(path)}` by itself",
                        later.key_span, "set either the whole field or its parts")
                del entries[path if later is b else short]
                break
    if not entries and ctx.msgdef is None:
        s.error("E204", "[message] sets no field", sec.span, "e.g. `position = arm`")
        return
    ctx.message_entries = entries
    ctx.below = index_below(entries)


_PART = re.compile(r"([^.\[\]]+)((?:\[[0-9]+\])?)\Z")


def field_path(key: str) -> FieldPath | None:
    """``a.b[2].c`` -> ``("a", "b", 2, "c")``; None when ``key`` is not a
    field path (an empty part, an index without a name, two indices)."""
    path: list[str | int] = []
    for part in key.split("."):
        m = _PART.match(part)
        if m is None:
            return None
        path.append(m.group(1))
        if m.group(2):
            path.append(int(m.group(2)[1:-1]))
    return tuple(path)


def written(path: FieldPath) -> str:
    """A field path as the config writes it: ``transforms[0].child_frame_id``."""
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out


def index_below(entries: dict[FieldPath, ast.Entry]) -> dict[FieldPath, dict[FieldPath, ast.Entry]]:
    """prefix -> the entries strictly below it."""
    index: dict[FieldPath, dict[FieldPath, ast.Entry]] = {}
    for p, e in entries.items():
        for k in range(len(p)):
            index.setdefault(p[:k], {})[p] = e
    return index
