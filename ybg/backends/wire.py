"""The Bottle layout on the wire, which every backend writes and reads.

The compiler knows ROS types and element types only; how they travel in a
Bottle is the backends' business. A value goes with the tag of its element
type: the tables below, one for YARP ports and untyped Bottles, one for ROS 1
topics through YARP. A ROS 1 message travels as a Bottle laid out like its
definition (a nested message a nested list, in field order): the IR gives
where each field of a ROS 1 input sits (:attr:`ybg.compiler.ir.Input.positions`).
"""

from __future__ import annotations

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
