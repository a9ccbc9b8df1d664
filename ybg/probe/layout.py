"""Does a Bottle seen on an input port fit the layout the config declares?
The rule the modules apply to every Bottle they read (docs/runtime.md,
"Reading"): a declared layout takes exactly its number of elements, a
float element any number, an integer element an integer, a string a
string, a bool a bool or an integer 0 or 1; an undeclared port any number
of numbers. A Bottle is given here as its elements' wire types and values
(:func:`ybg.probe.yarp_graph.elements`), so this is pure."""

from __future__ import annotations

from ybg.compiler import ir

INTEGERS = ("int8", "int16", "int32", "int64")
NUMBERS = INTEGERS + ("float32", "float64")


def declared(layout: tuple[ir.ElementGroup, ...] | None) -> str:
    """A layout as the config writes it: ``(float64 x8)``; ``undeclared``."""
    if layout is None:
        return "undeclared (numbers)"
    return "(" + ", ".join(f"{g.type} x{g.count}" for g in layout) + ")"


def seen(elements: list[tuple[str, object]]) -> str:
    """What a Bottle holds, in the config's notation: ``6 values: int32 x6``."""
    runs: list[list] = []
    for kind, _ in elements:
        if runs and runs[-1][0] == kind:
            runs[-1][1] += 1
        else:
            runs.append([kind, 1])
    n = len(elements)
    body = ", ".join(f"{kind} x{count}" for kind, count in runs)
    return f"{n} value{'s' if n != 1 else ''}" + (f": {body}" if body else "")


def _fits(want: str, kind: str, value) -> bool:
    if want in ir.FLOAT_TYPES:
        return kind in NUMBERS
    if want in ir.INTEGER_TYPES:
        return kind in INTEGERS
    if want == "string":
        return kind == "string"
    if want == "bool":
        return kind == "bool" or (kind in INTEGERS and value in (0, 1))
    return False


def mismatch(layout: tuple[ir.ElementGroup, ...] | None, elements: list[tuple[str, object]]) -> str | None:
    """Why the Bottle of ``elements`` does not fit ``layout``, or None."""
    if layout is None:
        for k, (kind, _) in enumerate(elements):
            if kind not in NUMBERS:
                return f"element {k} is {kind}, not a number"
        return None
    want = [g.type for g in layout for _ in range(g.count)]
    if len(elements) != len(want):
        return f"{len(elements)} elements, not {len(want)}"
    for k, ((kind, value), t) in enumerate(zip(elements, want)):
        if not _fits(t, kind, value):
            return f"element {k} is {kind}, not {t}"
    return None
