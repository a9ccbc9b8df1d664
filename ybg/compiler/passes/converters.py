"""Pass ``converters``: `convert = ...` of each mux.

Checks: converter names and parameters (E313, E208), element ranges against
the mux's width (E315), converters that need numbers applied to other
elements (E314).
Reads ``muxes`` and ``mux_keys``. Completes each mux of ``muxes`` with its
converters.
"""

from __future__ import annotations

import dataclasses
import math

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import did_you_mean
from ybg.compiler.passes.context import Context

#: converter name -> (number of parameters, scale, offset, to_float)
CONVERTERS: dict[str, tuple[int, float, float, bool]] = {
    "none": (0, 1.0, 0.0, False),
    "none_double": (0, 1.0, 0.0, True),
    "deg_to_rad": (0, math.pi / 180.0, 0.0, True),
    "rad_to_deg": (0, 180.0 / math.pi, 0.0, True),
    "scale": (1, 1.0, 0.0, True),
    "offset": (1, 1.0, 0.0, True),
}


def run(ctx: Context) -> None:
    for name, mux in ctx.muxes.items():
        entry = ctx.mux_keys[name].get("convert")
        if entry is not None:
            ctx.muxes[name] = dataclasses.replace(mux, converters=tuple(_converters(ctx, mux, entry)))


def _converters(ctx: Context, mux: ir.Mux, entry: ast.Entry) -> list[ir.Converter]:
    s = ctx.sink
    out = []
    width = mux.width
    types = mux.element_types
    for item in entry.items:
        start, stop, rng_span = 0, None, None
        base = item
        if isinstance(item, ast.Subscript):
            base = item.base
            rng_span = item.span
            if item.is_slice:
                start, stop = item.start or 0, item.stop
            else:
                start, stop = item.start, (item.start or 0) + 1
        args: tuple = ()
        if isinstance(base, ast.Call):
            args = base.args
            base = base.func
        if not isinstance(base, ast.Word):
            s.error("E313", "a converter is a name, e.g. `deg_to_rad` or `scale(0.5)`", item.span)
            continue
        name = base.text
        if name not in CONVERTERS:
            s.error("E313", f"unknown converter `{name}`", base.span,
                    did_you_mean(name, CONVERTERS) or f"converters: {', '.join(CONVERTERS)}")
            continue
        nparams, scale, offset, to_float = CONVERTERS[name]
        if len(args) != nparams:
            s.error("E208", f"`{name}` takes {nparams or 'no'} parameter{'s' if nparams != 1 else ''}",
                    item.span, f"e.g. `{name}(0.5)`" if nparams else f"write `{name}`")
            continue
        if nparams:
            arg = args[0]
            k = arg[0].number() if len(arg) == 1 and isinstance(arg[0], ast.Word) else None
            if k is None or isinstance(k, bool) or not math.isfinite(k):
                s.error("E208", f"`{name}` takes a number", arg[0].span if arg else item.span)
                continue
            if name == "scale":
                scale = float(k)
            else:
                offset = float(k)
        if start is not None and start < 0 or (stop is not None and stop < 0):
            s.error("E315", "element ranges count from 0 and are not negative", rng_span)
            continue
        if stop is not None and stop <= start:
            s.error("E315", f"empty element range [{start}:{stop}]", rng_span)
            continue
        if width is not None and (start >= width or (stop is not None and stop > width)):
            s.error("E315", f"range [{start}:{'' if stop is None else stop}] is outside mux `{mux.name}`"
                    f" of {width} elements", rng_span, f"elements are 0..{width - 1}")
            continue
        if types is not None and name != "none":
            hi = width if stop is None else stop
            bad = sorted({t for t in types[start:hi] if t not in ir.NUMERIC_TYPES})
            if bad:
                s.error("E314", f"`{name}` applied to {', '.join(bad)} elements of mux `{mux.name}`",
                        item.span, "give it a range of numeric elements, e.g. `deg_to_rad[0:6]`")
                continue
        if name == "none":
            continue
        out.append(ir.Converter(name, scale, offset, to_float, start, stop))
    return out
