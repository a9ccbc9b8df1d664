"""Stage 1: text -> :class:`~ybg.compiler.ast.Document`.

The lark grammar (``ybg/grammar/config.lark``, LALR, strict) gives a parse
tree; :class:`_ToAst` turns it into AST dataclasses with spans. A syntax error
does not stop the stage: it becomes a diagnostic (E1xx), the offending line is
set aside and parsing goes on, so one run reports every broken line.
"""

from __future__ import annotations

import functools
import re
import unicodedata
from importlib import resources

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedInput, UnexpectedToken

from ybg.compiler import ast
from ybg.compiler.diagnostics import Sink, Span

MAX_SYNTAX_ERRORS = 50


@functools.cache
def grammar_text() -> str:
    return resources.files("ybg.grammar").joinpath("config.lark").read_text(encoding="utf-8")


@functools.cache
def lark_parser(cache: bool = True) -> Lark:
    """The grammar, loaded once per process.

    Strict mode (no LALR conflicts, no terminal collisions) is checked when the
    parser is built; lark keeps the built parser in its cache (keyed by the
    grammar, the options and lark's version), so later runs skip the build.
    ``cache=False`` always builds it."""
    return Lark(
        grammar_text(),
        parser="lalr",
        strict=True,
        propagate_positions=True,
        maybe_placeholders=True,
        cache=cache,
    )


def _tok_span(t: Token) -> Span:
    return Span(t.line, t.column, t.end_line, t.end_column)


def _join(a: Span, b: Span) -> Span:
    return Span(a.line, a.column, b.end_line, b.end_column)


_ESCAPES = {'"': '"', "\\": "\\", "n": "\n", "t": "\t", "r": "\r", "0": "\0", "/": "/"}


def unescape(raw: str, span: Span, sink: Sink) -> str:
    """The value of a quoted string token (quotes included in ``raw``)."""
    body = raw[1:-1]
    if "\\" not in body:
        return body
    out: list[str] = []
    i = 0
    while i < len(body):
        c = body[i]
        if c != "\\":
            out.append(c)
            i += 1
            continue
        nxt = body[i + 1] if i + 1 < len(body) else ""
        if nxt in _ESCAPES:
            out.append(_ESCAPES[nxt])
            i += 2
            continue
        if nxt in ("u", "U", "x"):
            n = {"u": 4, "U": 8, "x": 2}[nxt]
            digits = body[i + 2 : i + 2 + n]
            if len(digits) == n and all(ch in "0123456789abcdefABCDEF" for ch in digits):
                cp = int(digits, 16)
                if cp <= 0x10FFFF and not 0xD800 <= cp <= 0xDFFF:
                    out.append(chr(cp))
                    i += 2 + n
                    continue
        col = span.column + 1 + i
        sink.error(
            "E106",
            f"invalid escape `\\{nxt}` in a string",
            Span(span.line, col, span.line, col + 2),
            'use \\" \\\\ \\n \\t \\r \\0 \\xHH \\uXXXX or \\UXXXXXXXX',
        )
        out.append(nxt)
        i += 2
    return "".join(out)


class _ToAst:
    """Parse tree -> AST, by a plain dispatch on rule names (lark's
    ``Transformer`` rebuilds a wrapper at every node: three times slower)."""

    def __init__(self, sink: Sink):
        self.sink = sink
        self.rules = {
            "args": self.args, "arg": self.arg,
            "call": self.call, "at": self.at, "slice": self.slice, "subscript": self.subscript,
            "bracket": self.bracket, "value": self.value, "entry": self.entry,
            "header": self.header, "section": self.section, "start": self.start,
            "expression": self.expression, "binary": self.binary, "negate": self.negate,
            "number": self.number, "name": self.name, "function": self.function,
        }

    def transform(self, tree: Tree):
        children = [self.transform(c) if isinstance(c, Tree) else self.atom(c) for c in tree.children]
        return self.rules[tree.data](tree.meta, children)

    def atom(self, tok):
        """WORD and STRING tokens become AST atoms; other tokens stay tokens."""
        if tok is None:
            return None
        if tok.type == "WORD":
            return ast.Word(str(tok), _tok_span(tok))
        if tok.type == "STRING":
            span = _tok_span(tok)
            return ast.Str(unescape(str(tok), span, self.sink), span)
        return tok

    def args(self, meta, children):
        return tuple(c for c in children if c is not None)

    def arg(self, meta, children):
        return tuple(children)

    def call(self, meta, children):
        func, args = children
        return ast.Call(func, args, _meta_span(meta))

    def at(self, meta, children):
        (tok,) = children
        return (int(tok), None, False)

    def slice(self, meta, children):
        a, b = children
        return (None if a is None else int(a), None if b is None else int(b), True)

    def subscript(self, meta, children):
        base, (start, stop, is_slice) = children
        return ast.Subscript(base, start, stop, is_slice, _meta_span(meta))

    def expression(self, meta, children):
        _, body = children
        return ast.Expr(body, _meta_span(meta))

    def binary(self, meta, children):
        left, op, right = children
        return ast.Binary(str(op), left, right, _meta_span(meta))

    def negate(self, meta, children):
        (operand,) = children
        return ast.Negate(operand, _meta_span(meta))

    def number(self, meta, children):
        (tok,) = children
        return ast.Number(str(tok), _tok_span(tok))

    def name(self, meta, children):
        (tok,) = children
        return ast.Name(str(tok), _tok_span(tok))

    def function(self, meta, children):
        name, *args = children
        args = tuple(a for a in args if a is not None)
        return ast.Function(str(name), args, _meta_span(meta), _tok_span(name))

    def bracket(self, meta, children):
        (value,) = children
        items = () if value is None else tuple(value)
        return ast.Bracket(items, _meta_span(meta))

    def value(self, meta, children):
        items = _Items(children)
        last = children[-1].span
        if (meta.end_line, meta.end_column) > (last.end_line, last.end_column):  # `a, b,`
            items.trailing_comma = Span(meta.end_line, meta.end_column - 1, meta.end_line, meta.end_column)
        return items

    def entry(self, meta, children):
        key, value = children
        items = () if value is None else value
        key_span = _tok_span(key)
        end = items[-1].span if items else key_span
        return ast.Entry(str(key), tuple(items), _join(key_span, end), key_span,
                         getattr(items, "trailing_comma", None))

    def header(self, meta, children):
        name, label = children
        return (name.text, None if label is None else label.text, _meta_span(meta))

    def section(self, meta, children):
        (name, label, span), *entries = children
        return ast.Section(name, label, tuple(entries), span)

    def start(self, meta, children):
        loose = tuple(c for c in children if isinstance(c, ast.Entry))
        sections = tuple(c for c in children if isinstance(c, ast.Section))
        return ast.Document(sections, loose)


class _Items(tuple):
    """The items of a value, and where a comma after the last one is."""

    trailing_comma: Span | None = None


def _meta_span(meta) -> Span:
    return Span(meta.line, meta.column, meta.end_line, meta.end_column)


def _classify(e: UnexpectedInput, lines: list[str]) -> tuple[str, str, str | None, int]:
    """(code, message, hint, width) for a lark error."""
    line = lines[e.line - 1] if 0 < e.line <= len(lines) else ""
    col = max(e.column, 1)
    ch = line[col - 1] if col - 1 < len(line) else ""
    stripped = line.strip()
    if isinstance(e, UnexpectedCharacters):
        if ch and ch.isspace():
            name = unicodedata.name(ch, f"U+{ord(ch):04X}").lower()
            return ("E101", f"unexpected character U+{ord(ch):04X} ({name})",
                    "replace it with a plain space (copied text often holds such characters)", 1)
        if ch == '"':
            return ("E102", "string is not closed on this line", 'end it with `"`; write a quote inside a string as `\\"`', len(line) - col + 1)
        if stripped.startswith("["):
            return ("E104", "malformed section header", "a header is `[name]` or `[name label]`, e.g. `[mux arm]`", 1)
        if col == len(line) - len(line.lstrip()) + 1 and "=" not in stripped:
            return ("E103", f"`{stripped}` is not `key = value`", "write `key = value`, or start a section with `[name]`", len(stripped) or 1)
        if ch in ")]":
            return ("E108", f"`{ch}` closes nothing", None, 1)
        if ch == "=" and col == len(line) - len(line.lstrip()) + 1:
            return ("E103", "`=` without a key", "write `key = value`", 1)
        if ch == "=":
            return ("E105", "unexpected `=` in a value", 'quote a value that holds `=`: `"a=b"`', 1)
        return ("E101", f"unexpected character `{ch}`", None, 1)
    if isinstance(e, UnexpectedToken):
        tok = e.token
        tt = tok.type
        if stripped.startswith("[") and e.line == tok.line and not re.match(r"^\[\s*\]", stripped):
            return ("E104", "malformed section header", "a header is `[name]` or `[name label]`, e.g. `[mux arm]`", max(len(str(tok)), 1))
        indent = len(line) - len(line.lstrip())
        # a word the lexer took for an expression's name or number is still a word here
        if tok.line == e.line and tok.column == indent + 1 and tt in ("WORD", "STRING", "NAME", "NUMBER"):
            if "=" in stripped:
                return ("E103", "a key is one word, without spaces or quotes", "write `key = value`, e.g. `num_fields = 3`", max(len(str(tok)), 1))
            return ("E103", f"`{stripped}` is not `key = value`", "write `key = value`, or start a section with `[name]`", len(stripped) or 1)
        if tt in ("WORD", "NAME", "NUMBER") and e.column > 1 and line[:col - 1].rstrip().endswith(("[", ":")):
            return ("E105", f"`{tok}` is not a position: write a whole number, as in `arm[2]` or `arm[0:6]`",
                    None, max(len(str(tok)), 1))
        if tt in ("RPAR", "RSQB"):
            return ("E108", f"`{tok}` closes nothing", None, 1)
        if tt == "$END" or tt == "_NL":
            if line.count("(") > line.count(")") or line.count("[") > line.count("]"):
                return ("E108", "bracket or parenthesis not closed on this line", "close it before the end of the line", 1)
            return ("E105", "value ends unexpectedly", "a value cannot end with `(` or `[` or a `:`", 1)
        if tt == "LPAR":
            return ("E105", "`(` must follow a name, as in `scale(0.5)` or `/port (float64 x3)`", None, 1)
        if tt == "EQUAL":
            return ("E105", "unexpected `=` in a value", 'quote a value that holds `=`: `"a=b"`', 1)
        return ("E105", f"unexpected `{tok}`", "items of a list are separated by commas", max(len(str(tok)), 1))
    return ("E105", "unexpected end of file", None, 1)


def parse_text(text: str, sink: Sink) -> ast.Document:
    """Parse ``text``; syntax errors go to ``sink`` and the rest is still parsed."""
    if text.startswith("\ufeff"):
        text = text[1:]
    if not text.endswith("\n"):
        text += "\n"
    lines = text.split("\n")
    blanked: set[int] = set()
    parser = lark_parser()
    while True:
        try:
            tree = parser.parse("\n".join(lines))
        except UnexpectedInput as e:
            code, msg, hint, width = _classify(e, lines)
            sink.error(code, msg, Span(e.line, max(e.column, 1), e.line, max(e.column, 1) + width), hint)
            bad = e.line
            if isinstance(e, UnexpectedToken) and e.token.type == "$END":
                bad = len(lines)
            if bad in blanked or bad < 1 or bad > len(lines) or len(blanked) >= MAX_SYNTAX_ERRORS:
                return ast.Document(())
            blanked.add(bad)
            lines[bad - 1] = ""
            continue
        doc = _ToAst(sink).transform(tree)
        return ast.Document(doc.sections, doc.loose, tuple(scan_comments(lines)))


def scan_comments(lines: list[str]) -> list[ast.Comment]:
    """Comments as the grammar defines them: from `#` or `;` outside a
    double-quoted string to the end of the line."""
    out: list[ast.Comment] = []
    for lno, line in enumerate(lines, 1):
        in_str = False
        i = 0
        while i < len(line):
            c = line[i]
            if in_str:
                if c == "\\":
                    i += 1
                elif c == '"':
                    in_str = False
            elif c == '"':
                in_str = True
            elif c in "#;":
                own = line[:i].strip() == ""
                blank = own and lno < len(lines) and lines[lno].strip() == "" and lno + 1 < len(lines)
                out.append(ast.Comment(line[i:].rstrip("\r"), lno, own, blank))
                break
            i += 1
    return out
