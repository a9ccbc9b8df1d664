"""Pass ``cuts``: how many values the message reads of an undeclared port
that a nested message takes a part of without a range (W511, said by
``typed``), so that the module can say when a Bottle brings more.

For each such mux, when every use of it has a known end (a nested message,
a range, one element) and the ports before the undeclared one declare their
widths, the undeclared input's ``reads`` is the number of its values that
the furthest use reaches. A use that takes the mux to its end reads
everything: nothing is cut, and ``reads`` stays unset.
Reads ``silent_cuts``, ``message``, ``muxes``. Sets ``muxes`` (their inputs'
``reads``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator

from ybg.compiler import ir
from ybg.compiler.passes.context import Context


def run(ctx: Context) -> None:
    if ctx.message is None:
        return
    for name in sorted(ctx.silent_cuts):
        mux = ctx.muxes.get(name)
        end = _furthest(ctx.message, name)
        if mux is None or end is None:
            continue
        ctx.muxes[name] = dataclasses.replace(mux, inputs=_with_reads(mux.inputs, end))


def _refs(sources) -> Iterator[ir.MuxRef]:
    """Every part of a mux that the message tree below ``sources`` reads."""
    for src in sources:
        if isinstance(src, ir.Struct):
            yield from _refs(f.source for f in src.fields)
        elif isinstance(src, ir.MessageArray):  # each element: a message, or a mux filling one
            yield from _refs(src.elements)
        elif isinstance(src, ir.MuxRef):
            yield src


def _furthest(message: ir.Struct, mux: str) -> int | None:
    """The end of the furthest part of ``mux`` the message reads; None when
    a use reads the mux to its end."""
    end = 0
    for ref in _refs([message]):
        if ref.mux != mux:
            continue
        if ref.index is not None:
            stop = ref.index + 1
        elif ref.into_fields is not None and ref.stop is None:
            stop = ref.start + len(ref.into_fields)
        else:
            stop = ref.stop
        if stop is None:
            return None
        end = max(end, stop)
    return end


def _with_reads(inputs: tuple[ir.Input, ...], end: int) -> tuple[ir.Input, ...]:
    """The inputs, the first undeclared YARP port told how many of its
    values the message reads (the ones after it start at unknown places)."""
    out = list(inputs)
    offset = 0
    for k, i in enumerate(inputs):
        if i.width is None:
            if i.kind == "yarp":
                out[k] = dataclasses.replace(i, reads=max(0, end - offset))
            break
        offset += i.width
    return tuple(out)
