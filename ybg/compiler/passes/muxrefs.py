"""References to muxes in [message] values, read by the ``typed`` and
``bottles`` passes: `arm`, `arm[2]`, `arm[0:3]`, `timestamp(arm)`.

Checks: unknown muxes (E212), negative or out-of-range indices and ranges
(E315, E316). Reads ``mux_sections``, ``muxes`` and ``ros``; adds each
mux referred to to ``used_muxes``.
"""

from __future__ import annotations

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import Span, did_you_mean
from ybg.compiler.passes.context import Context


def is_mux_ref(ctx: Context, item: ast.Item) -> bool:
    if isinstance(item, ast.Subscript):
        item = item.base
    return isinstance(item, ast.Word) and item.text in ctx.mux_sections


def is_timestamp(item: ast.Item) -> bool:
    if isinstance(item, ast.Call):
        item = item.func
    return isinstance(item, ast.Word) and item.text == "timestamp"


def timestamp(ctx: Context, item: ast.Item) -> ir.Timestamp:
    """`timestamp` (the wall clock) or `timestamp(<mux>)` (the envelope of the mux's Bottles)."""
    style = "ros2" if ctx.ros == "ros2" else "ros1"
    if isinstance(item, ast.Call):
        args = item.args
        if len(args) != 1 or len(args[0]) != 1 or not isinstance(args[0][0], ast.Word):
            ctx.sink.error("E208", "`timestamp(<mux>)` takes the name of one mux", item.span)
            return ir.Timestamp("wall", None, style)
        name = args[0][0].text
        if name not in ctx.muxes:
            unknown_mux(ctx, name, args[0][0].span)
            return ir.Timestamp("wall", None, style)
        ctx.used_muxes.add(name)
        return ir.Timestamp("envelope", name, style)
    return ir.Timestamp("wall", None, style)


def image_misplaced(ctx: Context, name: str, span: Span) -> None:
    ctx.sink.error("E340", f"mux `{name}` reads camera images: a frame fills the `data` of a "
                   "`sensor_msgs/Image`, not this", span,
                   f"publish `type = sensor_msgs/Image` with `data = {name}` (a ROS 2 image), or write a YARP "
                   f"image port with `image = {name}` in [output]")


def unknown_mux(ctx: Context, name: str, span: Span) -> None:
    if name in ctx.mux_sections:  # defined, but broken: already reported
        return
    sections = ctx.mux_sections
    ctx.sink.error("E212", f"no mux named `{name}`", span,
                   did_you_mean(name, list(sections)) or
                   (f"muxes: {', '.join(sections)}" if sections else
                    f"define it: `[mux {name}]` with `ports = ...`; quote text: `\"{name}\"`"))


def mux_slice(ctx: Context, item: ast.Item):
    """(mux, start, stop, index) or None; reports problems."""
    s = ctx.sink
    start, stop, index = 0, None, None
    base = item
    if isinstance(item, ast.Subscript):
        base = item.base
        if item.is_slice:
            start, stop = item.start or 0, item.stop
        else:
            index = item.start
    assert isinstance(base, ast.Word)
    name = base.text
    if name not in ctx.muxes:
        unknown_mux(ctx, name, base.span)
        return None
    ctx.used_muxes.add(name)
    mux = ctx.muxes[name]
    if mux.image is not None:
        image_misplaced(ctx, name, item.span)
        return None
    width = mux.width
    if (index is not None and index < 0) or start < 0 or (stop is not None and stop < 0):
        s.error("E316", "mux positions count from 0 and are not negative", item.span)
        return None
    if stop is not None and stop <= start:
        s.error("E315", f"empty range [{start}:{stop}]", item.span)
        return None
    if width is not None:
        if index is not None and index >= width:
            s.error("E316", f"index {index} is outside mux `{name}` of {width} elements", item.span,
                    f"elements are 0..{width - 1}")
            return None
        if start >= width and not (start == 0 and width == 0) or (stop is not None and stop > width):
            s.error("E315", f"range [{start}:{'' if stop is None else stop}] is outside mux `{name}` "
                    f"of {width} elements", item.span)
            return None
    return mux, start, stop, index


def slice_types(mux: ir.Mux, start: int, stop: int | None, index: int | None) -> tuple[str, ...] | None:
    """The element types of a part of ``mux`` (None when its width is dynamic)."""
    types = mux.element_types
    if types is None:
        return None
    if index is not None:
        return types[index: index + 1]
    return types[start: stop]
