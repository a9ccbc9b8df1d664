"""A Bottle's values as numbers, the same for every kind of bridge that
reads YARP ports (a stream's inputs, yarp_inputs.py; an action's encoders,
actions.py), and what to say of one that is not the number wanted. YARP 4
gave float32 the Bottle tag that YARP 3 gives float64: a float32 is taken
only where it is declared."""

import yarp


#: YARP 4 gave float32 the Bottle tag that YARP 3 gives float64, so on YARP 4
#: a float32 element is most likely a YARP 3 producer's float64, read as
#: other values: taken only where the input declares float32
_FLOAT32_AMBIGUOUS = yarp.YARP_VERSION_MAJOR >= 4
_MIXED_VERSIONS = ("a float32 (on YARP %s, what a YARP 3 producer's float64 reads as: "
                   "YARP 4 changed the Bottle tags; declare the port (float32 xN) if it "
                   "really sends float32)" % yarp.YARP_VERSION)


def _number(value, float32=False):
    """The value as a Python number, or None. ``float32``: a float32 element
    is wanted (never ambiguous then)."""
    if value.isFloat64():
        return value.asFloat64()
    if value.isFloat32():
        return value.asFloat64() if float32 or not _FLOAT32_AMBIGUOUS else None
    if value.isInt32() or value.isInt64() or value.isInt8() or value.isInt16():
        return value.asInt64()
    return None


def _describe(value):
    if value.isList():
        return "a list"
    if value.isString():
        return "a string"
    if value.isFloat64() or value.isFloat32():
        return "a float"
    if value.isInt8() or value.isInt16() or value.isInt32() or value.isInt64():
        return "an integer"
    if value.isVocab32():
        return "a vocab"
    return "a " + value.toString()


def _not_a(k, value, wanted):
    """Why element ``k`` is not the number wanted."""
    if _FLOAT32_AMBIGUOUS and value.isFloat32():
        return "element %d is %s" % (k, _MIXED_VERSIONS)
    return "element %d is %s, %s" % (k, _describe(value), wanted)
