"""The diagnostics of ``ybgc probe`` in the formats of ``ybgc check``: text
and GitHub annotations by ybg/report.py; JSON the same document, with the
title of a probe code (``PROBE_CODES``), which ybg/report.py's JSON does
not know."""

from __future__ import annotations

import json
from typing import TextIO

from ybg.compiler.diagnostics import Diagnostic, title
from ybg.report import _fix_json, report


def report_probe(fmt: str, diags: list[Diagnostic], sources: dict[str, str], stream: TextIO,
                 notes: bool = False) -> None:
    if fmt != "json":
        report(fmt, diags, sources, stream, notes=notes)
        return
    json.dump([{"file": d.file, "line": d.span.line, "column": d.span.column, "end_line": d.span.end_line,
                "end_column": d.span.end_column, "severity": d.severity.value, "code": d.code,
                "title": title(d.code), "message": d.message, "hint": d.hint, "fix": _fix_json(d.fix)}
               for d in diags], stream, indent=2, ensure_ascii=False)
    stream.write("\n")
