"""The plan of a command's message fields and Bottles, checked once for
every backend (docs/services.md).

A command fills a request or a response from a Bottle (the reply, or the
command's arguments) and writes a Bottle from a request or a response (the
command sent, or the reply given). The checker decides which field fills
which; this module turns each :class:`ir.Fill` and :class:`ir.BottleItem`
into a plan with its values already coerced to their field's type, and
refuses what no backend can build with one wording (a ``LoweringError``):
a backend only spells the plan out in its language.

Fills (:func:`plan_fill`)::

    constant   value (a scalar, or a tuple for an array field), coerced
    reason     why the call failed (a failure answer only), into a string
    text       the whole Bottle's text, into a string
    element    element ``start`` into a scalar field
    elements   elements [start, stop) into an array field (stop None: to
               the end; ``size``: the field's fixed size or bound)

Bottle items (:func:`plan_item`)::

    literal    a constant, written as ``wire`` (int32, int64, float64, string;
               a bool as the int32 0 or 1)
    field      a field of the message (``conversion``: scale and offset, or None)
    list       a nested list of ``items``
    reason     why the call failed (the failure reply only)
"""

from __future__ import annotations

from dataclasses import dataclass

from ybg.compiler import ir
from ybg.lower.errors import Line, LoweringError
from ybg.lower.wire import WIRE_YARP

FLOATS = ("float32", "float64")
INTEGERS = ("int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64", "char", "byte")
#: the element types an element of a Bottle fills (a field of another type is refused)
FILLED = FLOATS + INTEGERS + ("bool", "string")


def coerce(value, base: str):
    """A constant of the config as a field of element type ``base`` holds it."""
    if base in FLOATS:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise LoweringError(f"{value!r} is not a number, for a {base} field")
        return float(value)
    if base == "bool":
        return bool(value)
    if base == "string":
        return str(value)
    if base in INTEGERS:
        if isinstance(value, bool) or not isinstance(value, (int, float)) \
                or (isinstance(value, float) and not value.is_integer()):
            raise LoweringError(f"{value!r} is not an integer, for a {base} field")
        v = int(value)
        if base == "byte" and not 0 <= v <= 255:
            raise LoweringError(f"{v} is not a byte")
        return v
    raise LoweringError(f"no constant of type {base!r}")


def constant(value, typ: ir.TypeRef):
    """A field's constant, coerced: a scalar, or a tuple for an array field
    (of its fixed size, or within its bound)."""
    if typ.array is None:
        if isinstance(value, tuple):
            raise LoweringError(f"a list for the scalar field of type {typ}")
        return coerce(value, typ.base)
    values = value if isinstance(value, tuple) else (value,)
    if typ.array == "fixed" and typ.size is not None and len(values) != typ.size:
        raise LoweringError(f"{len(values)} values for a field of type {typ}")
    if typ.array == "sequence" and typ.size is not None and len(values) > typ.size:
        raise LoweringError(f"{len(values)} values for a field of type {typ}")
    return tuple(coerce(v, typ.base) for v in values)


@dataclass(frozen=True)
class FillPlan:
    """How one field is filled (the module docstring's table)."""

    ref: ir.FieldRef
    type: ir.TypeRef
    op: str
    value: object = None
    start: int = 0
    stop: int | None = None


def plan_fill(fill: ir.Fill, failure: bool) -> FillPlan:
    """The plan of ``fill``, in a failure answer when ``failure``."""
    ref = fill.ref
    typ = ref.type
    if typ is None:
        raise LoweringError(f"the field {ref.dotted} needs its type")
    if typ.is_message or typ.base in ("time", "duration"):
        raise LoweringError(f"the field {ref.dotted} is a {typ}: fill its fields")
    if fill.source == "literal":
        return FillPlan(ref, typ, "constant", constant(fill.value, typ))
    if fill.source == "error":
        if not failure:
            raise LoweringError("`error` is the reason of a failed call: only in a failure answer")
        if typ.base != "string" or typ.array is not None:
            raise LoweringError(f"the reason of a failed call is a string, not a {typ} ({ref.dotted})")
        return FillPlan(ref, typ, "reason")
    if failure:
        raise LoweringError(f"a failure answer is constants and `error`, not {fill.source} ({ref.dotted})")
    if fill.source == "text":
        if typ.base != "string" or typ.array is not None:
            raise LoweringError(f"a Bottle's text is a string, not a {typ} ({ref.dotted})")
        return FillPlan(ref, typ, "text")
    if fill.source != "element":
        raise LoweringError(f"unknown source {fill.source!r} of the field {ref.dotted}")
    if typ.base not in FILLED:
        raise LoweringError(f"no element fills the {typ.base} field {ref.dotted}")
    if fill.start < 0 or (fill.stop is not None and fill.stop < fill.start):
        raise LoweringError(f"the elements [{fill.start}:{fill.stop}] of the field {ref.dotted}")
    if not fill.slice:
        if typ.array is not None:
            raise LoweringError(f"one element for the array field {ref.dotted} ({typ})")
        return FillPlan(ref, typ, "element", start=fill.start)
    if typ.array is None:
        raise LoweringError(f"elements [{fill.start}:{'' if fill.stop is None else fill.stop}] for the "
                            f"scalar field {ref.dotted}")
    if typ.size is not None and fill.stop is not None:
        n = fill.stop - fill.start
        if (typ.array == "fixed" and n != typ.size) or n > typ.size:
            raise LoweringError(f"{n} elements for the field {ref.dotted} ({typ})")
    return FillPlan(ref, typ, "elements", start=fill.start, stop=fill.stop)


@dataclass(frozen=True)
class ItemPlan:
    """One item of a Bottle the module writes (the module docstring's table)."""

    op: str
    wire: str | None = None
    value: object = None
    ref: ir.FieldRef | None = None
    conversion: tuple[float, float] | None = None
    converter: str | None = None
    items: tuple[ir.BottleItem, ...] = ()


def plan_item(item: ir.BottleItem, failure: bool) -> ItemPlan:
    """The plan of ``item``, in the failure reply when ``failure``."""
    if item.kind == "literal":
        wire, value = _literal(item.value, item.type)
        return ItemPlan("literal", wire, value)
    if item.kind == "field":
        return _field(item)
    if item.kind == "list":
        return ItemPlan("list", items=item.items)
    if item.kind == "error":
        if not failure:
            raise LoweringError("`error` is the reason of a failed call: only in the failure reply")
        return ItemPlan("reason")
    raise LoweringError(f"unknown Bottle item {item.kind!r}")


def _literal(v, t) -> tuple[str, object]:
    if isinstance(v, bool) or t == "bool":
        return "int32", 1 if v else 0
    if t == "string" or (t is None and isinstance(v, str)):
        return "string", str(v)
    if t == "float64" or (t is None and isinstance(v, float)):
        return "float64", float(v)
    if t in ("int32", "int64", None) and isinstance(v, int):
        if t == "int32" and not -2**31 <= v < 2**31:
            raise LoweringError(f"{v} is beyond an int32")
        if t is None:
            t = "int32" if -2**31 <= v < 2**31 else "int64"
        if not -2**63 <= v < 2**63:
            raise LoweringError(f"{v} is beyond an int64")
        return t, v
    raise LoweringError(f"a constant {v!r} of type {t!r} in a Bottle")


def _field(item: ir.BottleItem) -> ItemPlan:
    ref = item.ref
    if ref is None:
        raise LoweringError("a field item names its field")
    typ = ref.type
    if typ is None:
        raise LoweringError(f"the field {ref.dotted} needs its type")
    if typ.is_message or typ.base in ("time", "duration"):
        raise LoweringError(f"the field {ref.dotted} is a {typ}: a Bottle item is a number, a string "
                            f"or a bool (name its fields)")
    conv = item.converter
    if conv is not None and not conv.is_identity:
        if typ.base not in FLOATS + INTEGERS:
            raise LoweringError(f"the converter {conv.name} of the {typ.base} field {ref.dotted}")
        return ItemPlan("field", "float64", ref=ref, conversion=(float(conv.scale), float(conv.offset)),
                        converter=conv.name)
    wire = WIRE_YARP.get(typ.base)
    if wire not in ("int32", "int64", "float64", "string"):
        raise LoweringError(f"no Bottle item for the {typ.base} field {ref.dotted}")
    return ItemPlan("field", wire, ref=ref)


class BottleWriter:
    """The lines that add a Bottle's items, walked by their plans
    (:func:`plan_item`), each error at its item's position: a backend's
    subclass spells each kind of item (:meth:`literal`, :meth:`field`,
    :meth:`reason`: the lines of one item; :meth:`nested`: a nested list,
    whose items it adds with :meth:`items`). ``msg``: the variable of the
    request or response; ``failure``: the failure reply."""

    def __init__(self, msg: str, failure: bool):
        self.msg = msg
        self.failure = failure
        self.lines: list[Line] = []
        self.lists = 0

    def items(self, bottle: str, items, indent: int = 1) -> None:
        for item in items:
            try:
                self.item(bottle, plan_item(item, self.failure), indent)
            except LoweringError as e:
                raise e.at(item.span)

    def item(self, bottle: str, plan: ItemPlan, indent: int) -> None:
        if plan.op == "list":
            self.lists += 1
            self.nested(bottle, f"items{self.lists}" if self.lists > 1 else "items", plan.items, indent)
            return
        spell = {"literal": self.literal, "field": self.field, "reason": self.reason}[plan.op]
        self.lines += [Line(indent, text) for text in spell(bottle, plan)]

    def literal(self, bottle: str, plan: ItemPlan) -> list[str]:
        raise NotImplementedError

    def field(self, bottle: str, plan: ItemPlan) -> list[str]:
        raise NotImplementedError

    def reason(self, bottle: str, plan: ItemPlan) -> list[str]:
        raise NotImplementedError

    def nested(self, bottle: str, name: str, items, indent: int) -> None:
        raise NotImplementedError


__all__ = ["BottleWriter", "FLOATS", "INTEGERS", "FILLED", "coerce", "constant", "FillPlan", "plan_fill", "ItemPlan", "plan_item"]
