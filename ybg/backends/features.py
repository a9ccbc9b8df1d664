"""The message features of a program that not every backend builds, and
where the config asks for each (``Builds.features`` declares which a
backend builds, for each output kind)."""

from __future__ import annotations

from typing import Iterator

from ybg.compiler import ir
from ybg.compiler.diagnostics import Span

#: feature -> what it is, as a refusal names it
FEATURES: dict[str, str] = {
    "fixed_array": "a fixed-size array field",
    "message_array": "an array of messages",
    "rows": "a ROS 2 input read a row for each element of an array of messages",
    "image": "camera images",
}


def used(program: ir.Program) -> dict[str, Span | None]:
    """The features ``program`` uses, each with the span of its first use."""
    out: dict[str, Span | None] = {}
    for feature, span in _uses(program):
        out.setdefault(feature, span)
    return out


def _uses(program: ir.Program) -> Iterator[tuple[str, Span | None]]:
    for m in program.muxes:
        for i in m.inputs:
            if i.each is not None:
                yield "rows", i.span
            if i.image is not None:
                yield "image", i.span
    yield from _struct(program.message)


def _struct(struct: ir.Struct) -> Iterator[tuple[str, Span | None]]:
    for f in struct.fields:
        if f.type is not None and f.type.array == "fixed":
            yield "fixed_array", f.span
        src = f.source
        if isinstance(src, ir.Struct):
            yield from _struct(src)
        elif isinstance(src, ir.MessageArray):
            yield "message_array", f.span
            for element in src.elements:
                if isinstance(element, ir.Struct):
                    yield from _struct(element)


__all__ = ["FEATURES", "used"]
