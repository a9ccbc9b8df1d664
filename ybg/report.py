"""Reporters: print diagnostics, separate from checking.

``text`` gives ``FILE:LINE:COL: error CODE message`` lines (with the source
line and a caret on a terminal, through rich), ``json`` one JSON document,
``github`` workflow annotations.
"""

from __future__ import annotations

import json
import sys
from typing import Iterable, TextIO

from ybg.compiler.diagnostics import Diagnostic, Severity, title

FORMATS = ("text", "json", "github")


def _visible(diags: Iterable[Diagnostic], notes: bool) -> list[Diagnostic]:
    return [d for d in diags if notes or d.severity is not Severity.NOTE]


def report_text(diags: list[Diagnostic], sources: dict[str, str], stream: TextIO,
                color: bool | None = None, notes: bool = False) -> None:
    diags = _visible(diags, notes)
    if color is None:
        color = stream.isatty()
    if not color:
        for d in diags:
            stream.write(f"{d.file}:{d.span.line}:{d.span.column}: {d.severity.value} {d.code} {d.message}\n")
            if d.hint:
                stream.write(f"    hint: {d.hint}\n")
        return
    from rich.console import Console
    from rich.markup import escape

    console = Console(file=stream, highlight=False, soft_wrap=True)
    style = {Severity.ERROR: "bold red", Severity.WARNING: "bold yellow", Severity.NOTE: "bold cyan"}
    for d in diags:
        console.print(f"[bold]{escape(d.file)}:{d.span.line}:{d.span.column}:[/bold] "
                      f"[{style[d.severity]}]{d.severity.value} {d.code}[/] {escape(d.message)}")
        text = sources.get(d.file)
        if text is not None and d.span.line >= 1:
            lines = text.split("\n")
            if d.span.line <= len(lines):
                src = lines[d.span.line - 1].rstrip("\r").expandtabs(1)
                width = 1
                if d.span.end_line == d.span.line and d.span.end_column > d.span.column:
                    width = d.span.end_column - d.span.column
                console.print(f"  [dim]{d.span.line:>4} |[/dim] {escape(src)}")
                console.print(f"  [dim]     |[/dim] {' ' * (d.span.column - 1)}[{style[d.severity]}]{'^' * width}[/]")
        if d.hint:
            console.print(f"  [cyan]hint:[/cyan] {escape(d.hint)}")


def _fix_json(fix) -> dict | None:
    """A hint's literal fix for an editor or a bot: the edits (1-based
    line and column, end exclusive, and the new text), or the command."""
    if fix is None:
        return None
    if fix.command is not None:
        return {"command": fix.command}
    return {"edits": [{"line": e.span.line, "column": e.span.column, "end_line": e.span.end_line,
                       "end_column": e.span.end_column, "text": e.text} for e in fix.edits]}


def report_json(diags: list[Diagnostic], stream: TextIO) -> None:
    out = [
        {
            "file": d.file, "line": d.span.line, "column": d.span.column,
            "end_line": d.span.end_line, "end_column": d.span.end_column,
            "severity": d.severity.value, "code": d.code, "title": title(d.code),
            "message": d.message, "hint": d.hint, "fix": _fix_json(d.fix),
        }
        for d in diags
    ]
    json.dump(out, stream, indent=2, ensure_ascii=False)
    stream.write("\n")


def _gh_escape(text: str, prop: bool = False) -> str:
    text = text.replace("%", "%25").replace("\r", "%0D").replace("\n", "%0A")
    if prop:
        text = text.replace(":", "%3A").replace(",", "%2C")
    return text


def report_github(diags: list[Diagnostic], stream: TextIO, notes: bool = False) -> None:
    """Workflow commands: errors, warnings and, with ``notes``, notices."""
    level = {Severity.ERROR: "error", Severity.WARNING: "warning", Severity.NOTE: "notice"}
    for d in _visible(diags, notes):
        msg = d.message + (f" (hint: {d.hint})" if d.hint else "")
        stream.write(f"::{level[d.severity]} file={_gh_escape(d.file, True)},line={d.span.line},"
                     f"col={d.span.column},title={d.code}::{_gh_escape(msg)}\n")


def report(fmt: str, diags: list[Diagnostic], sources: dict[str, str], stream: TextIO | None = None,
           notes: bool = False) -> None:
    stream = stream or sys.stdout
    if fmt == "json":
        report_json(diags, stream)
    elif fmt == "github":
        report_github(diags, stream, notes=notes)
    else:
        report_text(diags, sources, stream, notes=notes)
