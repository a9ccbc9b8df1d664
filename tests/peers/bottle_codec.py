"""Bottle <-> JSON-able Python values, shared by the YARP peers.

Python -> Bottle (what the producer writes):
  int -> int32 (int64 if it does not fit), float -> float64, str -> string,
  bool -> int32 0/1, list/tuple -> nested list,
  {"int64": n}, {"int32": n}, {"float32": x}, {"float64": x}, {"vocab": "abcd"},
  {"string": s} force a wire type.

Bottle -> Python (what the reader records): ``data`` with ints, floats, strings
and nested lists (a vocab becomes its string), plus ``types``: the same shape
with the wire type of every leaf ("int8", "int16", "int32", "int64", "float32",
"float64", "string", "vocab", "blob", "bool"). Blobs are recorded as a list of
byte values.
"""


def _add(bottle, v):
    if isinstance(v, bool):
        bottle.addInt32(int(v))
    elif isinstance(v, int):
        if -2**31 <= v < 2**31:
            bottle.addInt32(v)
        else:
            bottle.addInt64(v)
    elif isinstance(v, float):
        bottle.addFloat64(v)
    elif isinstance(v, str):
        bottle.addString(v)
    elif isinstance(v, (list, tuple)):
        fill(bottle.addList(), v)
    elif isinstance(v, dict) and len(v) == 1:
        (tag, x), = v.items()
        if tag == "int64":
            bottle.addInt64(int(x))
        elif tag == "int32":
            bottle.addInt32(int(x))
        elif tag == "float32":
            bottle.addFloat32(float(x))
        elif tag == "float64":
            bottle.addFloat64(float(x))
        elif tag == "vocab":
            import yarp
            bottle.addVocab32(yarp.encode(x) if hasattr(yarp, "encode") else x)
        elif tag == "string":
            bottle.addString(str(x))
        else:
            raise ValueError("unknown wire type tag %r" % tag)
    else:
        raise TypeError("cannot put %r in a Bottle" % (v,))


def fill(bottle, values):
    """Append Python ``values`` (a list) to ``bottle``."""
    bottle.clear()
    for v in values:
        _add(bottle, v)
    return bottle


def _vocab_str(v):
    import yarp
    n = v.asVocab32()
    if hasattr(yarp, "decode"):
        try:
            return yarp.decode(n)
        except Exception:
            pass
    return v.toString()


def value_to_py(v):
    """(data, type) of one yarp.Value."""
    if v.isList():
        return to_py(v.asList())
    if v.isVocab32():
        return _vocab_str(v), "vocab"
    if v.isBool():
        return int(v.asBool()), "bool"
    if v.isInt8():
        return v.asInt8(), "int8"
    if v.isInt16():
        return v.asInt16(), "int16"
    if v.isInt32():
        return v.asInt32(), "int32"
    if v.isInt64():
        return v.asInt64(), "int64"
    if v.isFloat32():
        return v.asFloat32(), "float32"
    if v.isFloat64():
        return v.asFloat64(), "float64"
    if v.isString():
        return v.asString(), "string"
    if v.isBlob():
        s = v.toString()
        return list(s.encode("latin-1", "replace")), "blob"
    return v.toString(), "unknown"


def to_py(bottle, head=None):
    """(data, types) of a yarp.Bottle (of its first ``head`` values only, if given)."""
    data, types = [], []
    for i in range(bottle.size() if head is None else min(head, bottle.size())):
        d, t = value_to_py(bottle.get(i))
        data.append(d)
        types.append(t)
    return data, types
