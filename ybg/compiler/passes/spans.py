"""Pass ``spans``, after ``program``: where each element of the checked
:class:`~ybg.compiler.ir.Program` came from.

Every element a backend may refuse or report on gets the span of the text
that made it, so that a backend never reads the document: an input, the
item of its `ports`/`topics` entry; a mux, its section's header; a field,
its entry in [message], else the entry of the nearest enclosing field
(`pose = goal` sets `pose.position.x`), else the first entry inside it, else
the [message] line; the output, its `via`/`topic`/`port` line; the output's
type, its `type` item. (Converters get theirs in ``converters``, where each
is made from its item.) A legacy config's named form carries the spans of
the legacy lines, so these point into the file the user wrote.

Reads ``program`` and the document. Sets ``program`` again, with spans.
"""

from __future__ import annotations

import dataclasses

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import Span
from ybg.compiler.passes.context import Context


def run(ctx: Context) -> None:
    if ctx.program is not None:
        ctx.program = with_spans(ctx.program, ctx.doc)


def with_spans(program: ir.Program, doc: ast.Document) -> ir.Program:
    """``program`` with the span of each element in ``doc``."""
    where = Positions(doc)
    muxes = tuple(dataclasses.replace(
        m, span=where.mux(m.name),
        inputs=tuple(dataclasses.replace(i, span=where.input(m.name, i.name)) for i in m.inputs))
        for m in program.muxes)
    output = dataclasses.replace(program.output, span=where.output(), type_span=where.type())
    info = output.camera_info
    if info is not None:
        sec = doc.section("camera_info")
        found = Positions(doc, "camera_info")
        output = dataclasses.replace(output, camera_info=dataclasses.replace(
            info, message=found.struct(info.message, "", sec.span if sec is not None else None)))
    message = where.struct(program.message, "", where.message())
    return dataclasses.replace(program, muxes=muxes, output=output, message=message)


class Positions:
    """The spans of one document's parts, found by name."""

    def __init__(self, doc: ast.Document, message: str = "message"):
        self.doc = doc
        sec = doc.section(message)
        self.message_section = sec
        self.entries = {e.key: e for e in sec.entries} if sec is not None else {}

    def output(self) -> Span | None:
        """The output's `via`, `topic` or `port` line, else the [output] header."""
        return output_span(self.doc)

    def type(self) -> Span | None:
        """Where the output's message type is written, else the output's line."""
        sec = self.doc.section("output")
        e = sec.get("type") if sec is not None else None
        if e is not None:
            return e.items[0].span if e.items else e.span
        return self.output()

    def message(self) -> Span | None:
        return self.message_section.span if self.message_section is not None else self.output()

    def mux(self, name: str) -> Span | None:
        sec = self.doc.section("mux", name)
        return sec.span if sec is not None else None

    def input(self, mux: str, name: str) -> Span | None:
        """Where input ``name`` of ``mux`` is written, else its mux's line."""
        sec = self.doc.section("mux", mux)
        if sec is None:
            return None
        e = sec.get("topics") or sec.get("ports")
        if e is None:
            return sec.span
        for item in e.items:
            head = item.func if isinstance(item, ast.Call) else item
            if isinstance(head, ast.Word) and head.text == name or isinstance(head, ast.Str) and head.value == name:
                return item.span
        return e.span

    def field(self, path: str) -> Span | None:
        """Where the message field ``path`` (dotted, ``points[0].x``) is set: its
        entry, or the entry of the nearest enclosing field, or the first entry
        inside it; else the [message] line."""
        if self.message_section is None:
            return None
        parts = path.split(".")
        for k in range(len(parts), 0, -1):
            e = self.entries.get(".".join(parts[:k]))
            if e is not None:
                return e.span
        for key, e in self.entries.items():
            if key.startswith((path + ".", path + "[")):
                return e.span
        return self.message_section.span

    def struct(self, struct: ir.Struct, prefix: str, span: Span | None) -> ir.Struct:
        fields = []
        for f in struct.fields:
            path = prefix + f.name
            fields.append(dataclasses.replace(f, span=self.field(path), source=self.source(f.source, path)))
        return dataclasses.replace(struct, fields=tuple(fields), span=span)

    def source(self, src: ir.Source, path: str) -> ir.Source:
        if isinstance(src, ir.Struct):
            return self.struct(src, path + ".", self.field(path))
        if isinstance(src, ir.MessageArray):
            return dataclasses.replace(src, elements=tuple(
                self.struct(e, f"{path}[{k}].", self.field(f"{path}[{k}]")) if isinstance(e, ir.Struct) else e
                for k, e in enumerate(src.elements)))
        return src


def output_span(doc: ast.Document) -> Span | None:
    """Where a diagnostic about the output points: its `via`, `topic` or
    `port` line, else the [output] header."""
    sec = doc.section("output")
    if sec is None:
        return None
    e = sec.get("via") or sec.get("topic") or sec.get("port")
    return e.span if e else sec.span
