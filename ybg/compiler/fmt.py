"""Canonical text of a :class:`~ybg.compiler.ast.Document` (``ybgc fmt``).

The canonical form: one blank line between sections, ``key = a, b`` with
single spaces, strings re-escaped the one way, a long list wrapped after
commas onto continuation lines, comments kept where they were (a comment on
its own line stays before what followed it; a trailing comment stays on its
line). ``format_document(parse(s)) == s`` for a canonical ``s``.

A file in the legacy form is never wrapped: the original tool's INI reader
takes one line for each value and refuses continuation lines, and a legacy
file formatted in place stays readable by it.
"""

from __future__ import annotations

from ybg.compiler import ast
from ybg.compiler.legacy import is_legacy

WIDTH = 100


def quote(value: str) -> str:
    """The canonical double-quoted spelling of ``value``."""
    out = ['"']
    for ch in value:
        if ch == '"':
            out.append('\\"')
        elif ch == "\\":
            out.append("\\\\")
        elif ch == "\n":
            out.append("\\n")
        elif ch == "\t":
            out.append("\\t")
        elif ch == "\r":
            out.append("\\r")
        elif ch == "\0":
            out.append("\\0")
        elif ord(ch) < 0x20 or ord(ch) == 0x7F or ch in "\u2028\u2029\x85":
            out.append(f"\\u{ord(ch):04x}")
        elif 0xD800 <= ord(ch) <= 0xDFFF:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def format_item(item: ast.Item) -> str:
    if isinstance(item, ast.Str):
        return quote(item.value)
    if isinstance(item, ast.Word):
        return item.text
    if isinstance(item, ast.Call):
        args = ", ".join(" ".join(format_item(a) for a in arg) for arg in item.args)
        func = format_item(item.func)
        # a port declaration reads `/port:o (float64 x6)`; a converter `scale(0.5)`
        sep = " " if isinstance(item.func, (ast.Word, ast.Str)) and func.startswith(("/", '"')) else ""
        return f"{func}{sep}({args})"
    if isinstance(item, ast.Subscript):
        base = format_item(item.base)
        if item.is_slice:
            a = "" if item.start is None else str(item.start)
            b = "" if item.stop is None else str(item.stop)
            return f"{base}[{a}:{b}]"
        return f"{base}[{item.start}]"
    if isinstance(item, ast.Bracket):
        return "[" + ", ".join(format_item(i) for i in item.items) + "]"
    if isinstance(item, ast.Expr):
        return f"expr({format_node(item.body)})"
    raise TypeError(item)  # pragma: no cover


#: binding strength of an expression's nodes (higher binds tighter)
_PRECEDENCE = {"+": 1, "-": 1, "*": 2, "/": 2}


def _strength(node: ast.Node) -> int:
    if isinstance(node, ast.Binary):
        return _PRECEDENCE[node.op]
    return 3 if isinstance(node, ast.Negate) else 4


def format_node(node: ast.Node) -> str:
    """An expression with the parentheses its tree needs, and no others
    (``a - (b - c)`` keeps them: the tree, hence the rounding, is kept)."""
    if isinstance(node, ast.Number):
        return node.text
    if isinstance(node, ast.Name):
        return node.name
    if isinstance(node, ast.Function):
        return f"{node.name}({', '.join(format_node(a) for a in node.args)})"
    if isinstance(node, ast.Negate):
        inner = format_node(node.operand)
        return f"-({inner})" if _strength(node.operand) < 3 else f"-{inner}"
    p = _PRECEDENCE[node.op]
    left, right = format_node(node.left), format_node(node.right)
    if _strength(node.left) < p:
        left = f"({left})"
    if _strength(node.right) <= p:
        right = f"({right})"
    return f"{left} {node.op} {right}"


def format_entry(entry: ast.Entry, trailing: str | None = None, wrap: bool = True) -> str:
    """``key = value`` on one line, or, with ``wrap``, a long list on several."""
    head = f"{entry.key} ="
    if not entry.items:
        line = head
        return line + (f"  {trailing}" if trailing else "")
    parts = [format_item(i) for i in entry.items]
    one = head + " " + ", ".join(parts)
    if len(one) <= WIDTH or len(parts) == 1 or not wrap:
        return one + (f"  {trailing}" if trailing else "")
    indent = " " * (len(head) + 1)
    lines: list[str] = []
    cur = head + " " + parts[0]
    for p in parts[1:]:
        if len(cur) + 2 + len(p) > WIDTH:
            lines.append(cur + ",")
            cur = indent + p
        else:
            cur += ", " + p
    lines.append(cur)
    if trailing:
        lines[0] += f"  {trailing}"
    return "\n".join(lines)


def format_document(doc: ast.Document, wrap: bool | None = None) -> str:
    """The canonical text of ``doc`` (comments from ``doc.comments``).
    ``wrap``: long lists on continuation lines; by default, unless ``doc``
    is in the legacy form."""
    if wrap is None:
        wrap = not is_legacy(doc)
    own = sorted((c for c in doc.comments if c.own_line), key=lambda c: c.line)
    trailing = {c.line: c.text for c in doc.comments if not c.own_line}
    out: list[str] = []
    pending = list(own)

    def flush(before_line: int | None) -> None:
        while pending and (before_line is None or pending[0].line < before_line):
            c = pending.pop(0)
            out.append(c.text)
            if c.blank_after and before_line is not None:
                out.append("")

    def emit_entry(e: ast.Entry) -> None:
        flush(e.span.line)
        # a trailing comment on any line the entry spans stays with it
        t = None
        for ln in range(e.key_span.line, e.span.end_line + 1):
            if ln in trailing:
                t = trailing[ln]
                break
        out.append(format_entry(e, t, wrap))

    for e in doc.loose:
        emit_entry(e)
    for sec in doc.sections:
        if out:
            if out[-1] != "":
                out.append("")
        flush(sec.span.line)
        header = f"[{sec.title}]"
        if sec.span.line in trailing and sec.span.line > 0:
            header += f"  {trailing[sec.span.line]}"
        out.append(header)
        for e in sec.entries:
            emit_entry(e)
    flush(None)
    while out and out[-1] == "":
        out.pop()
    return "\n".join(out) + "\n" if out else ""


def strip_positions(doc: ast.Document) -> ast.Document:
    """``doc`` without comments, for printing a generated document."""
    return ast.Document(doc.sections, doc.loose, ())
