"""The Bottle layout on the wire, which every backend writes and reads.

The compiler knows ROS types and element types only; how they travel in a
Bottle is the backends' business. A value goes with the tag of its element
type: the tables below, one for YARP ports and untyped Bottles, one for ROS 1
topics through YARP. A ROS 1 message travels as a Bottle laid out like its
definition (a nested message a nested list, in field order): the IR gives
where each field of a ROS 1 input sits (:attr:`ybg.compiler.ir.Input.positions`).
"""

from __future__ import annotations

from ybg.compiler import ir

#: Bottle tag of each element type on a YARP port or an untyped Bottle
#: (docs/runtime.md, "Value types on the wire"). Every backend writes these.
WIRE_YARP: dict[str, str] = {
    "float32": "float64", "float64": "float64",
    "int64": "int64", "uint32": "int64", "uint64": "int64",
    "int8": "int32", "uint8": "int32", "int16": "int32", "uint16": "int32",
    "int32": "int32", "byte": "int32", "char": "int32", "bool": "int32",
    "string": "string",
    # an undeclared port's element, written as it came: an integer as int32
    # (int64 beyond int32's range), a real as float64; YARP passes values
    # through, so a command like `set pos 3 45.0` keeps its integer
    "number": "number",
}

#: Bottle tag of each element type on a ROS 1 output. YARP's tcpros carrier
#: turns the Bottle into the ROS message by a fixed layout (WireTwiddler)
#: that compares the tags byte for byte: a uint32 must be an int32 (an int64
#: is refused, "Structure of message is unexpected"), a float32 a float32 (a
#: float64 in a float32 field arrives as garbage), a bool an int8.
WIRE_ROS1: dict[str, str] = {
    "float32": "float32", "float64": "float64",
    "int64": "int64", "uint64": "int64",
    "int32": "int32", "uint32": "int32",
    "int16": "int16", "uint16": "int16",
    "int8": "int8", "uint8": "int8", "byte": "int8", "char": "int8", "bool": "int8",
    "string": "string",
    "number": "float64",  # never in a typed ROS 1 message; an untyped one as YARP had it
}


#: types a ROS 1 Bottle holds as a nested list (sec nsec) of their own
_TIME_TYPES = ("time", "duration")


def has_message_array(struct: ir.Struct) -> bool:
    """Does the message hold an array of messages (at any depth)?"""
    for f in struct.fields:
        src = f.source
        if isinstance(src, ir.MessageArray):
            return True
        if isinstance(src, ir.Struct) and has_message_array(src):
            return True
    return False


def has_fixed_array(struct: ir.Struct) -> bool:
    """Does the message hold a fixed-size array (at any depth, set or not:
    ``sensor_msgs/Imu``'s covariances)? YARP's Bottle translation to ROS 1
    sends one with a length before it, which ROS 1 reads as its first values."""
    for f in struct.fields:
        if f.type is not None and f.type.array == "fixed":
            return True
        if isinstance(f.source, ir.Struct) and has_fixed_array(f.source):
            return True
    return False


def ros1_shape(struct: ir.Struct) -> str:
    """What each nested list of a ROS 1 message's Bottle is, in depth-first
    order: ``s`` a sequence (serialized with its length), ``f`` a nested
    message, a time or a fixed-size array (without). YARP 3's Bottle
    translation to ROS 1 (its type server's map) has no arrays of messages,
    so a module serializes such a message itself, from the Bottle it built
    and this shape (docs/config.md, "Arrays of messages")."""
    return "".join(_shape(f.source, f.type) for f in struct.fields)


def _shape(src, typ: ir.TypeRef | None) -> str:
    if typ is None:
        raise ValueError("a ROS 1 message field needs its type")
    seq = "f" if typ.array == "fixed" else "s"
    if isinstance(src, ir.Struct):
        return "f" + ros1_shape(src)
    if isinstance(src, ir.MessageArray):
        return seq + "".join("f" + (ros1_shape(e) if isinstance(e, ir.Struct) else "") for e in src.elements)
    if isinstance(src, ir.MuxRef):
        if src.index is not None:
            return ""
        return "f" if src.into_fields is not None else seq
    if isinstance(src, ir.Literal):
        return seq if src.is_list else ""
    if isinstance(src, ir.Timestamp):
        return "f"
    if isinstance(src, ir.Default):
        if typ.array is not None:
            return seq
        return "f" if typ.base in _TIME_TYPES else ""
    return ""  # Counter, Seconds: one value
