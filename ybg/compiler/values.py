"""Readers of entry values, shared by the legacy conversion and the checker.

Each reads one ``key = value`` entry as what its key takes (one word, a
number, a choice, true or false), or reports E208 and gives None; and
:func:`check_keys` indexes a section's entries by key, reporting unknown and
duplicate keys. They know the syntax tree and the diagnostics, nothing of a
form of the config.
"""

from __future__ import annotations

import math
from typing import Callable

from ybg.compiler import ast
from ybg.compiler.diagnostics import Sink, did_you_mean


def one(entry: ast.Entry, sink: Sink, what: str) -> ast.Item | None:
    """The one item of ``entry`` (``what`` names it in the diagnostic)."""
    if len(entry.items) != 1:
        sink.error("E208", f"`{entry.key}` takes one {what}, not {len(entry.items) or 'no'} values",
                   entry.span, f"write `{entry.key} = <{what}>`")
        return None
    return entry.items[0]


def word(entry: ast.Entry, sink: Sink, what: str = "name") -> str | None:
    """One word or quoted text."""
    item = one(entry, sink, what)
    if item is None:
        return None
    if isinstance(item, (ast.Word, ast.Str)):
        return item.text if isinstance(item, ast.Word) else item.value
    sink.error("E208", f"`{entry.key}` takes a {what}", item.span)
    return None


def choice(entry: ast.Entry, sink: Sink, choices: tuple[str, ...]) -> str | None:
    """One of the words ``choices``."""
    value = word(entry, sink, "word")
    if value is None:
        return None
    if value not in choices:
        sink.error("E208", f"`{entry.key}` is one of {', '.join(choices)}, not `{value}`",
                   entry.items[0].span, did_you_mean(value, choices))
        return None
    return value


def number(entry: ast.Entry, sink: Sink, minimum: float = 0.0, allow_zero: bool = False) -> float | None:
    """A finite number greater than ``minimum`` (or equal, with ``allow_zero``)."""
    item = one(entry, sink, "number")
    if item is None:
        return None
    num = item.number() if isinstance(item, ast.Word) else None
    if num is None or isinstance(num, bool) or math.isnan(num) or math.isinf(num):
        sink.error("E208", f"`{entry.key}` takes a number", item.span)
        return None
    if num < minimum or (num == 0 and not allow_zero):
        sink.error("E208", f"`{entry.key}` must be {'at least' if allow_zero else 'greater than'} {minimum:g}",
                   item.span)
        return None
    return float(num)


def whole(entry: ast.Entry, sink: Sink, minimum: int, maximum: int | None = None,
          hint: str | None = None) -> int | None:
    """A whole number from ``minimum`` (to ``maximum``), or None (reported)."""
    num = number(entry, sink, float(minimum))
    if num is None:
        return None
    if num != int(num) or (maximum is not None and num > maximum):
        where = f" from {minimum} to {maximum}" if maximum is not None else ""
        sink.error("E208", f"`{entry.key}` is a whole number{where}", entry.items[0].span, hint)
        return None
    return int(num)


def boolean(entry: ast.Entry, sink: Sink) -> bool | None:
    """true or false."""
    item = one(entry, sink, "true or false")
    if item is None:
        return None
    b = item.boolean() if isinstance(item, ast.Word) else None
    if b is None:
        sink.error("E208", f"`{entry.key}` takes true or false", item.span)
    return b


def check_keys(section: ast.Section, allowed: tuple[str, ...], sink: Sink,
               extra: Callable[[str], bool] | None = None) -> dict[str, ast.Entry]:
    """Entries of ``section`` by key; unknown keys (neither ``allowed`` nor
    accepted by ``extra``) and duplicate keys reported. Empty ``allowed`` and
    no ``extra``: any key."""
    out: dict[str, ast.Entry] = {}
    for e in section.entries:
        if (allowed or extra) and e.key not in allowed and not (extra and extra(e.key)):
            sink.error("E202", f"unknown key `{e.key}` in [{section.title}]", e.key_span,
                       did_you_mean(e.key, allowed) or f"keys of [{section.name}]: {', '.join(allowed)}")
            continue
        if e.key in out:
            sink.error("E206", f"`{e.key}` is given twice in [{section.title}]", e.key_span,
                       f"first given on line {out[e.key].span.line}")
            continue
        out[e.key] = e
    return out
