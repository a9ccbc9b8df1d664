"""The syntax tree of a config file, as written (both forms).

Frozen dataclasses built by :mod:`ybg.compiler.parser`. Every node carries the
:class:`~ybg.compiler.diagnostics.Span` it came from, excluded from equality so
that ``parse(fmt(parse(s))) == parse(s)`` compares meaning, not layout.
Comments are kept (``Document.comments``) so that ``ybgc fmt`` loses none.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Union

from ybg.compiler.diagnostics import NOWHERE, Span

_INT = re.compile(r"[+-]?[0-9]+\Z")
_FLOAT = re.compile(r"[+-]?(?:[0-9]+\.[0-9]*|\.[0-9]+|[0-9]+)(?:[eE][+-]?[0-9]+)?\Z")
_SPECIAL_FLOATS = {"nan": float("nan"), "inf": float("inf"), "+inf": float("inf"), "-inf": float("-inf")}


@dataclass(frozen=True)
class Str:
    """A double-quoted string; ``value`` is unescaped."""

    value: str
    span: Span = field(default=NOWHERE, compare=False)


@dataclass(frozen=True)
class Word:
    """A bare word: a name, a port, a number, ``true``..."""

    text: str
    span: Span = field(default=NOWHERE, compare=False)

    def number(self) -> int | float | None:
        t = self.text
        if _INT.match(t):
            return int(t)
        if _FLOAT.match(t):
            return float(t)
        return _SPECIAL_FLOATS.get(t.lower())

    def boolean(self) -> bool | None:
        return {"true": True, "false": False}.get(self.text.lower())


Atom = Union[Str, Word]


@dataclass(frozen=True)
class Call:
    """``func(args)``: a converter with parameters, or a port with its
    declaration (``/port:o (float64 x6, int32 x3)``). Each argument is a
    sequence of atoms (``float64 x6``)."""

    func: "Item"
    args: tuple[tuple[Atom, ...], ...]
    span: Span = field(default=NOWHERE, compare=False)


@dataclass(frozen=True)
class Subscript:
    """``base[i]`` (``stop`` is None, ``is_slice`` False) or ``base[start:stop]``."""

    base: "Item"
    start: int | None
    stop: int | None
    is_slice: bool
    span: Span = field(default=NOWHERE, compare=False)


@dataclass(frozen=True)
class Bracket:
    """``[a, b]``: an explicit list (``[]`` is the empty list)."""

    items: tuple["Item", ...]
    span: Span = field(default=NOWHERE, compare=False)


@dataclass(frozen=True)
class Number:
    """A number in an expression, as written (``0.5``, ``1e-3``)."""

    text: str
    span: Span = field(default=NOWHERE, compare=False)

    @property
    def value(self) -> float:
        return float(self.text)


@dataclass(frozen=True)
class Name:
    """A name in an expression: ``x`` (the element), ``pi``."""

    name: str
    span: Span = field(default=NOWHERE, compare=False)


@dataclass(frozen=True)
class Negate:
    """``-operand``."""

    operand: "Node"
    span: Span = field(default=NOWHERE, compare=False)


@dataclass(frozen=True)
class Binary:
    """``left op right``, ``op`` one of ``+ - * /``."""

    op: str
    left: "Node"
    right: "Node"
    span: Span = field(default=NOWHERE, compare=False)


@dataclass(frozen=True)
class Function:
    """``name(args)`` in an expression: ``clamp(x, -1, 1)``."""

    name: str
    args: tuple["Node", ...]
    span: Span = field(default=NOWHERE, compare=False)
    name_span: Span = field(default=NOWHERE, compare=False)


#: a node of an expression
Node = Union[Number, Name, Negate, Binary, Function]


@dataclass(frozen=True)
class Expr:
    """``expr(body)``: an element-wise expression of the element ``x``, as a
    converter (``convert = expr(clamp(x, -1, 1) * 0.5)[0:3]``)."""

    body: Node
    span: Span = field(default=NOWHERE, compare=False)


Item = Union[Str, Word, Call, Subscript, Bracket, Expr]


@dataclass(frozen=True)
class Entry:
    """``key = items``; ``items`` is empty for ``key =``. ``trailing_comma``:
    where a comma after the last item is (``a, b,``), which the value
    ignores; None when there is none."""

    key: str
    items: tuple[Item, ...]
    span: Span = field(default=NOWHERE, compare=False)
    key_span: Span = field(default=NOWHERE, compare=False)
    trailing_comma: Span | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Section:
    """``[name label]`` and its entries."""

    name: str
    label: str | None
    entries: tuple[Entry, ...]
    span: Span = field(default=NOWHERE, compare=False)

    @property
    def title(self) -> str:
        return self.name if self.label is None else f"{self.name} {self.label}"

    def get(self, key: str) -> Entry | None:
        for e in self.entries:
            if e.key == key:
                return e
        return None


@dataclass(frozen=True)
class Comment:
    """A comment, kept for the formatter. ``own_line``: nothing else is on its
    line (it belongs before the next entry or section); else it trails
    the entry or header on its line."""

    text: str
    line: int
    own_line: bool
    blank_after: bool = False  # a blank line follows it (kept by the formatter)


@dataclass(frozen=True)
class Document:
    """A parsed config file. ``loose`` holds entries before any section."""

    sections: tuple[Section, ...]
    loose: tuple[Entry, ...] = ()
    comments: tuple[Comment, ...] = field(default=(), compare=False)

    def section(self, name: str, label: str | None = None) -> Section | None:
        for s in self.sections:
            if s.name == name and s.label == label:
                return s
        return None


def item_span(item: Item) -> Span:
    return item.span
