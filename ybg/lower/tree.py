"""The message tree as every backend walks it: nesting of dotted fields,
the values of literals and defaults, sizes and slice ranges, and the
message types a program uses."""

from __future__ import annotations

from ybg.compiler import ir
from ybg.lower.errors import LoweringError

#: the ROS time and duration types (ROS 1 primitives and ROS 2 messages)
TIME_TYPES = ("time", "duration", "builtin_interfaces/Time", "builtin_interfaces/Duration")


def nest_fields(leaves: list) -> list:
    """Leaves ``(dotted path, payload)`` of a nested message, in order, as its
    tree: each item ``(name, payload)`` for a leaf or ``(name, [items])`` for
    a sub-message (``position.x``, ``position.y`` -> ``("position", [("x", ..),
    ("y", ..)])``), as a Bottle of the ROS 1 layout nests them."""
    out: list = []
    for path, payload in leaves:
        head, _, rest = path.partition(".")
        if not rest:
            out.append((head, payload))
        elif out and out[-1][0] == head and isinstance(out[-1][1], list):
            out[-1][1].append((rest, payload))
        else:
            out.append((head, [(rest, payload)]))
    return [(name, nest_fields(sub) if isinstance(sub, list) else sub) for name, sub in out]


def coerce(value, element_type: str):
    """A literal of the config as the value an element of ``element_type`` holds."""
    if element_type in ir.FLOAT_TYPES:
        return float(value)
    if element_type == "bool":
        return bool(value)
    if element_type == "string":
        return str(value)
    if element_type in ir.NUMERIC_TYPES:
        return int(value)
    raise LoweringError(f"unknown element type {element_type!r}")


def default_scalar(base: str):
    """The default of a primitive field of type ``base`` (0, false, "")."""
    if base in ir.FLOAT_TYPES:
        return 0.0
    if base == "bool":
        return False
    if base == "string":
        return ""
    if base in ir.NUMERIC_TYPES:
        return 0
    raise LoweringError(f"no default for type {base!r}")


def time_style(base: str, ros: str | None) -> str:
    """How a time of type ``base`` is laid out: ``"ros2"`` (sec, nanosec) for
    ``builtin_interfaces`` and ROS 2 programs, else ``"ros1"`` (sec, nsec)."""
    if base.startswith("builtin_interfaces/") or ros == "ros2":
        return "ros2"
    return "ros1"


def check_size(typ: ir.TypeRef, n: int, what: str) -> None:
    """``n`` values fit the array field of type ``typ`` (exactly a fixed
    size, at most a bound)."""
    if typ.array == "fixed" and typ.size is not None and n != typ.size:
        raise LoweringError(f"{what}: {n} values for the fixed-size field {typ}")
    if typ.array == "sequence" and typ.size is not None and n > typ.size:
        raise LoweringError(f"{what}: {n} values for the bounded field {typ}")


def slice_stop(program: ir.Program, ref: ir.MuxRef, typ: ir.TypeRef, name: str) -> int | None:
    """The end of the mux slice ``ref`` into the array field ``name`` of type
    ``typ`` when the mux's width is known (else None: it is known at run
    time); the slice is checked against the mux and the field's size."""
    width = program.mux(ref.mux).width
    if width is None:
        if ref.stop is not None:
            check_size(typ, ref.stop - ref.start, f"field {name}")
        return None
    stop = width if ref.stop is None else ref.stop
    if stop > width or ref.start > stop:
        raise LoweringError(f"field {name}: elements [{ref.start}, {stop}) of a mux of {width}")
    check_size(typ, stop - ref.start, f"field {name}")
    return stop


def message_types(struct: ir.Struct, out: set[str]) -> None:
    """Add to ``out`` the message types of ``struct`` and of its nested fields."""
    if struct.msg_type:
        out.add(struct.msg_type)
    for f in struct.fields:
        if f.type is not None and f.type.is_message:
            out.add(f.type.base)
        if isinstance(f.source, ir.Struct):
            message_types(f.source, out)


__all__ = ["TIME_TYPES", "nest_fields", "coerce", "default_scalar", "time_style", "check_size", "slice_stop",
           "message_types"]
