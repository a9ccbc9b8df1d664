"""What lowering reports, and the unit of generated code."""

from __future__ import annotations

from dataclasses import dataclass

from ybg.compiler.diagnostics import Span


class LoweringError(ValueError):
    """A program that a backend cannot build; the message says why, and
    ``span`` where the config writes the part refused (the ``span`` of an IR
    element: a field, an input, the output's type), or None for the output
    or the program as a whole. ``ybgc check --backend`` and ``ybgc generate``
    report it as E318 at that span (``ybg.backends.support``), never as a
    traceback."""

    def __init__(self, message: str, span: Span | None = None):
        super().__init__(message)
        self.span = span

    def at(self, span: Span | None) -> "LoweringError":
        """Say where the error is, unless a deeper part of the program said it already."""
        if self.span is None:
            self.span = span
        return self


@dataclass(frozen=True)
class Line:
    """One line of generated code, already made of escaped parts."""

    indent: int
    text: str


__all__ = ["LoweringError", "Line"]
