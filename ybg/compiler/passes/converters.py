"""Pass ``converters``: `convert = ...` of each mux.

Checks: converter names and parameters (E313, E208), element ranges against
the mux's width as the converters before leave it (E315), converters that need
numbers applied to other elements (E314), the width of a geometry
converter's range (E322, E323), the names, functions and arguments of an
expression (E324, E325).
A mux whose converters do not all check is taken out of ``muxes``, as
``inputs`` leaves out a mux whose inputs do not: what its elements become
is not known, so the lines that use it are not checked against a guess
(one mistake, one diagnostic), and the converters after the one that
failed are checked for their names and parameters only.
Reads ``muxes``, ``mux_keys`` and ``legacy``. Completes each mux of
``muxes`` with its converters.
"""

from __future__ import annotations

import dataclasses
import math

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import Edit, closest, did_you_mean
from ybg.compiler.fmt import format_item, format_node
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

_EULER = ("euler_to_quat", "quat_to_euler")
#: the parameters of an Euler converter: the axis orders (`rpy` is `xyz`), the units
AXES = (*ir.EULER_AXES, "rpy")
UNITS = ("deg", "rad")
#: the names an expression knows
EXPR_NAMES = ("x", "pi")


def run(ctx: Context) -> None:
    checked: dict[str, ir.Mux] = {}
    for name, mux in ctx.muxes.items():
        entry = ctx.mux_keys[name].get("convert")
        if entry is None:
            checked[name] = mux
            continue
        if mux.image is not None:
            ctx.sink.error("E343", f"mux `{name}` reads a camera image: its frames are not converted",
                           entry.span, "remove `convert`")
            continue
        converters = _converters(ctx, mux, entry)
        if converters is not None:
            checked[name] = dataclasses.replace(mux, converters=tuple(converters))
    ctx.muxes = checked


def _converters(ctx: Context, mux: ir.Mux, entry: ast.Entry) -> list[ir.AnyConverter] | None:
    """The converters of ``entry``; None when one of them does not check (reported)."""
    out: list[ir.AnyConverter] = []
    failed = False
    for item in entry.items:
        # each converter's range counts the elements as the ones before it leave them; after
        # one that failed, what they leave is not known, and no range is checked against it
        current = dataclasses.replace(mux, converters=tuple(out))
        width = None if failed else current.width
        types = None if failed else current.element_types
        ok, conv = _converter(ctx, mux, item, width, types, not failed)
        failed = failed or not ok
        if conv is not None:
            out.append(dataclasses.replace(conv, span=item.span))
    return None if failed else out


def _converter(ctx: Context, mux: ir.Mux, item: ast.Item, width: int | None, types: tuple[str, ...] | None,
               width_known: bool) -> tuple[bool, ir.AnyConverter | None]:
    """(checks, the converter ``item`` is or None for `none`); ``width_known``: False when a
    converter before it failed, and ``width`` and ``types`` are not known."""
    s = ctx.sink
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
    called = isinstance(base, ast.Call)
    if isinstance(base, ast.Call):
        args = base.args
        base = base.func
    if isinstance(base, ast.Expr):
        name = "expr"
    elif isinstance(base, ast.Word):
        name = base.text
    else:
        s.error("E313", "a converter is a name, e.g. `deg_to_rad` or `scale(0.5)`", item.span)
        return False, None
    known = (*CONVERTERS, *ir.GEOMETRY_WIDTHS, "expr")
    if name not in known:
        guess = closest(name, known)
        s.error("E313", f"unknown converter `{name}`", base.span,
                f"did you mean `{guess}`?" if guess else f"converters: {', '.join(known)}",
                ctx.fix(Edit(base.span, guess)) if guess else None)
        return False, None
    if name == "expr" and not isinstance(base, ast.Expr):
        # the word `expr` without its expression: `expr`, `expr[0:3]`, or `expr (x)` with a space
        example = "e.g. `expr(x * 0.5)` or `expr(clamp(x, -1, 1))[0:3]`"
        if called:
            s.error("E208", "`expr` takes its expression in parentheses right after it", base.span,
                    f"remove the space before `(`: {example}")
        else:
            s.error("E208", "`expr` is an element-wise expression: it needs the expression in parentheses",
                    base.span, example)
        return False, None
    if name == "expr" and args:
        s.error("E208", "an expression takes no parameters after it", item.span,
                "write `expr(...)` or `expr(...)[start:stop]`")
        return False, None
    if not _range_ok(ctx, mux, width, start, stop, rng_span):
        return False, None
    if name in ir.GEOMETRY_WIDTHS:
        conv = _geometry(ctx, mux, item, name, args, start, stop, width, types, width_known)
        return conv is not None, conv
    if types is not None and name != "none":
        hi = width if stop is None else stop
        bad = sorted({t for t in types[start:hi] if t not in ir.NUMERIC_TYPES})
        if bad:
            s.error("E314", f"`{name}` applied to {', '.join(bad)} elements of mux `{mux.name}`",
                    item.span, "give it a range of numeric elements, e.g. `deg_to_rad[0:6]`")
            return False, None
    if name == "expr":
        body = _node(ctx, base.body)
        if body is None:
            return False, None
        return True, ir.ExprConverter(body, start, stop, format_node(base.body))
    nparams, scale, offset, to_float = CONVERTERS[name]
    if len(args) != nparams:
        s.error("E208", f"`{name}` takes {nparams or 'no'} parameter{'s' if nparams != 1 else ''}",
                item.span, f"e.g. `{name}(0.5)`" if nparams else f"write `{name}`")
        return False, None
    if nparams:
        arg = args[0]
        k = arg[0].number() if len(arg) == 1 and isinstance(arg[0], ast.Word) else None
        if k is None or isinstance(k, bool) or not math.isfinite(k):
            s.error("E208", f"`{name}` takes a number", arg[0].span if arg else item.span)
            return False, None
        if name == "scale":
            scale = float(k)
        else:
            offset = float(k)
    if name == "none":
        return True, None
    return True, ir.Converter(name, scale, offset, to_float, start, stop)



def _range_ok(ctx: Context, mux: ir.Mux, width: int | None, start: int | None, stop: int | None, rng_span) -> bool:
    s = ctx.sink
    if start is not None and start < 0 or (stop is not None and stop < 0):
        s.error("E315", "element ranges count from 0 and are not negative", rng_span)
        return False
    if stop is not None and stop <= start:
        s.error("E315", f"empty element range [{start}:{stop}]", rng_span)
        return False
    if width is not None and (start >= width or (stop is not None and stop > width)):
        after = " after the converters before it" if width != mux.input_width else ""
        s.error("E315", f"range [{start}:{'' if stop is None else stop}] is outside mux `{mux.name}`"
                f" of {width} elements{after}", rng_span, f"elements are 0..{width - 1}")
        return False
    return True


def _geometry(ctx: Context, mux: ir.Mux, item: ast.Item, name: str, args, start: int, stop: int | None,
              width: int | None, types: tuple[str, ...] | None, width_known: bool) -> ir.GeometryConverter | None:
    """A geometry converter on [start, stop), whose width must be its own."""
    s = ctx.sink
    need = ir.GEOMETRY_WIDTHS[name][0]
    example = ir.GEOMETRY[name].example
    axes, degrees = None, False
    if name in _EULER:
        words = [a[0].text if len(a) == 1 and isinstance(a[0], ast.Word) else None for a in args]
        if len(words) != 2 or words[0] not in AXES or words[1] not in UNITS:
            _euler_parameters(ctx, name, args, words, item)
            return None
        axes = "xyz" if words[0] == "rpy" else words[0]
        degrees = words[1] == "deg"
    elif args:
        s.error("E208", f"`{name}` takes no parameters", item.span, f"e.g. `{example}`")
        return None
    if not width_known:
        return None  # a converter before it failed: its range is not known to be right or wrong
    if width is None or types is None:
        s.error("E323", f"`{name}` needs the width of mux `{mux.name}`, which is known only at run time",
                item.span, "declare the ports of the mux, e.g. `/port:o (float64 x7)`")
        return None
    hi = width if stop is None else stop
    if hi - start != need:
        where = f"elements [{start}:{hi}]" if (start, stop) != (0, None) else f"the {width} elements of mux `{mux.name}`"
        s.error("E322", f"`{name}` takes {need} elements, not {hi - start}: it is given {where}",
                item.span, f"give it a range of {need} elements, e.g. `{example}`")
        return None
    bad = sorted({t for t in types[start:hi] if t not in ir.NUMERIC_TYPES})
    if bad:
        s.error("E314", f"`{name}` applied to {', '.join(bad)} elements of mux `{mux.name}`", item.span,
                f"give it a range of {need} numbers, e.g. `{example}`")
        return None
    return ir.GeometryConverter(name, start, axes, degrees, format_item(item))


def _euler_parameters(ctx: Context, name: str, args, words: list[str | None], item: ast.Item) -> None:
    """E208 for the parameters of an Euler converter, with the words meant
    when they are plain (`degrees` for `deg`, `RPY` for `rpy`)."""
    orders = (f"axis orders (fixed axes, the first rotation first): rpy (= xyz, ROS's roll pitch yaw), "
              f"{', '.join(ir.EULER_AXES[1:])}")
    message = (f"`{name}` takes the axis order and the unit of its angles: "
               f"`{name}(xyz, deg)` or `{name}(xyz, rad)`")
    if len(words) != 2 or None in words:
        ctx.sink.error("E208", message, item.span, orders)
        return
    meant = [_meant(words[0], AXES), _meant(words[1], UNITS)]
    if None in meant:
        ctx.sink.error("E208", message, item.span,
                       orders if meant[0] is None else f"the unit is `deg` or `rad`, not `{words[1]}`")
        return
    edits = [Edit(a[0].span, m) for a, w, m in zip(args, words, meant) if w != m]
    wrong = [(what, w, m) for what, w, m in zip(("axis order", "unit"), words, meant) if w != m]
    ctx.sink.error("E208", f"`{name}` takes " + ", and ".join(
                       f"the {what} `{m}`{' (or `rad`)' if what == 'unit' and m == 'deg' else ''}, not `{w}`"
                       for what, w, m in wrong),
                   edits[0].span, f"write `{name}({meant[0]}, {meant[1]})`", ctx.fix(*edits))


def _meant(word: str, choices: tuple[str, ...]) -> str | None:
    """The choice ``word`` means: itself, in other case, or a unit spelt out (`degrees`, `radian`)."""
    low = word.lower()
    if low in choices:
        return low
    for unit in UNITS if choices == UNITS else ():
        if low.startswith(unit) and {"deg": "degrees", "rad": "radians"}[unit].startswith(low):
            return unit
    return None


def _node(ctx: Context, node: ast.Node) -> ir.ExprNode | None:
    """The checked expression ``node``, or None (reported)."""
    s = ctx.sink
    if isinstance(node, ast.Number):
        v = node.value
        if not math.isfinite(v):
            s.error("E208", f"`{node.text}` is too large for a float64", node.span)
            return None
        return ir.ExprNode("number", (), v)
    if isinstance(node, ast.Name):
        if node.name in EXPR_NAMES:
            return ir.ExprNode(node.name)
        hint = (f"`{node.name}` is a function: write `{node.name}(...)`" if node.name in ir.EXPR_FUNCTIONS
                else did_you_mean(node.name, EXPR_NAMES) or "an expression knows `x` (the element) and `pi`")
        s.error("E324", f"unknown name `{node.name}` in an expression", node.span, hint)
        return None
    if isinstance(node, ast.Negate):
        inner = _node(ctx, node.operand)
        return None if inner is None else ir.ExprNode("neg", (inner,))
    if isinstance(node, ast.Binary):
        left, right = _node(ctx, node.left), _node(ctx, node.right)
        return None if left is None or right is None else ir.ExprNode(node.op, (left, right))
    assert isinstance(node, ast.Function)
    arity = ir.EXPR_FUNCTIONS.get(node.name)
    if arity is None:
        s.error("E324", f"unknown function `{node.name}` in an expression", node.name_span,
                did_you_mean(node.name, ir.EXPR_FUNCTIONS) or f"functions: {', '.join(ir.EXPR_FUNCTIONS)}")
        return None
    args = [_node(ctx, a) for a in node.args]
    if len(args) != arity:
        s.error("E325", f"`{node.name}` takes {arity} argument{'s' if arity != 1 else ''}, not {len(args)}",
                node.span, f"e.g. `{node.name}({', '.join(['x', '-1', '1'][:arity])})`")
        return None
    if any(a is None for a in args):
        return None
    return ir.ExprNode(node.name, tuple(args))  # type: ignore[arg-type]
