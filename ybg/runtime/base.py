"""What every bridge of every kind stands on, with no middleware: the
element types of the values it carries, the linear converters, its log
lines, and the count of its calls that the cost guard asks for at start
(docs/runtime.md). A stream (core, yarp_io, ros2_io) and a node of commands
(services) both use these, and so do one process's several bridges."""

import collections
import functools
import os
import sys
import threading

#: an element type -> what a Bottle (or a message's field) must hold there
_FLOAT_TYPES = frozenset(("float32", "float64"))
_INT_TYPES = frozenset(("int8", "uint8", "int16", "uint16", "int32", "uint32",
                        "int64", "uint64", "byte", "char"))

_INT_BITS = {"int8": 8, "uint8": 8, "byte": 8, "char": 8, "int16": 16, "uint16": 16,
             "int32": 32, "uint32": 32, "int64": 64, "uint64": 64}

#: a linear converter, y = x * scale + offset on the elements [start, stop)
#: (``stop`` None: to the end); ``to_float``: every result a float, else an
#: integer stays an integer
ConverterSpec = collections.namedtuple("ConverterSpec", "name scale offset to_float start stop")


def scale_range(values, c):
    """The linear converter ``c`` applied to the list ``values`` in place
    (a range past the end is cut; ``none``, which changes nothing, is skipped)."""
    stop = len(values) if c.stop is None else min(c.stop, len(values))
    if c.start >= stop or (c.scale == 1.0 and c.offset == 0.0 and not c.to_float):
        return
    scale, offset = c.scale, c.offset
    part = values[c.start:stop]
    if c.to_float:
        part = [float(x * scale + offset) for x in part]
    else:  # an integer stays an integer
        part = [int(x * scale + offset) if isinstance(x, int) else x * scale + offset for x in part]
    values[c.start:stop] = part


def integer(x):
    """A value as an integer: a ``byte`` field holds bytes."""
    if isinstance(x, (bytes, bytearray)):
        return x[0] if len(x) == 1 else int.from_bytes(x, "little")
    return int(x)


def signed(x, bits):
    """``x`` as the two's complement integer of ``bits`` bits (a uint32
    above 2**31 on an int32 wire keeps its bits, as in C++)."""
    half = 1 << (bits - 1)
    return ((integer(x) + half) % (half << 1)) - half


# --- values on YARP's wire ------------------------------------------------------

def _add_number(bottle, x):
    """An undeclared port's element, as it came: an integer as int32 (int64
    beyond its range), anything else as float64."""
    if isinstance(x, int) and not isinstance(x, bool):
        if -2**31 <= x < 2**31:
            bottle.addInt32(x)
        else:
            bottle.addInt64(signed(x, 64))
    else:
        bottle.addFloat64(float(x))


#: a wire type -> how a value is added to a Bottle as it (a bool is the
#: int32 0 or 1; "number": an undeclared port's element, as it came)
ADD = {
    "float64": lambda b, x: b.addFloat64(float(x)),
    "float32": lambda b, x: b.addFloat32(float(x)),
    "int64": lambda b, x: b.addInt64(signed(x, 64)),
    "int32": lambda b, x: b.addInt32(signed(x, 32)),
    "int16": lambda b, x: b.addInt16(signed(x, 16)),
    "int8": lambda b, x: b.addInt8(signed(x, 8)),
    "string": lambda b, x: b.addString(str(x)),
    "number": _add_number,
}


def add_value(bottle, wire, x):
    """One value added to ``bottle`` as the wire type ``wire``."""
    try:
        add = ADD[wire]
    except KeyError:
        raise ValueError("no wire type %r" % (wire,)) from None
    add(bottle, x)


def add_values(bottle, wire, values):
    """The values of an array (bytes: each byte a value), one item each, all
    of the wire type ``wire``."""
    if isinstance(values, (bytes, bytearray)):
        values = list(values)
    if wire == "float64":
        # the binding's method itself, one call a value (it takes an int or
        # a float as float() does)
        add = bottle.addFloat64
        for x in values:
            add(x)
        return
    try:
        add = ADD[wire]
    except KeyError:
        raise ValueError("no wire type %r" % (wire,)) from None
    for x in values:
        add(bottle, x)


# --- log lines -----------------------------------------------------------------

_LOG_LOCK = threading.Lock()


def say(name, text):
    """One line ``name: text`` on the standard output, written whole: several
    threads log (inputs, loops, ROS 2 callbacks, callers), and print()
    writes the end of line apart."""
    with _LOG_LOCK:
        sys.stdout.write("%s: %s\n" % (name, text))
        sys.stdout.flush()


# --- the cost guard's count ------------------------------------------------------

#: the environment variable that makes a module count, from its start, the
#: Python calls on the path of its Bottles and messages (CallCount)
COUNT_CALLS = "YBGC_COUNT_CALLS"


class CallCount:
    """The Python calls made on the message path, counted for the cost guard
    (tests/test_cost.py): each entry of that path (an input's Bottle or
    message read in a middleware's thread, its handling, a cycle of the
    fixed-rate loop) is run with a profile hook in its thread, which counts
    every Python function called and every C function called from Python,
    and of these the calls into YARP's bindings (each lets the interpreter
    lock go, and another thread may take it). The totals (calls, YARP calls,
    entries run) are kept as three int64 in a file, which a test reads while
    the module runs. Only when COUNT_CALLS names that file at start
    (``call_count``); otherwise nothing is wrapped and nothing is counted."""

    def __init__(self, path):
        self.fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_TRUNC, 0o644)
        self.lock = threading.Lock()
        self.totals = [0, 0, 0]
        self._save()

    def _save(self):
        os.pwrite(self.fd, b"".join(n.to_bytes(8, "little") for n in self.totals), 0)

    def counted(self, function):
        """``function``, its calls counted; within another counted function
        (the same thread), it is counted as part of that one."""
        def run(*args):
            if sys.getprofile() is not None:
                return function(*args)
            tally = [0, 0]

            def hook(frame, event, arg):
                if event == "call":
                    tally[0] += 1
                elif event == "c_call":
                    tally[0] += 1
                    if "yarp" in (getattr(arg, "__module__", None) or ""):
                        tally[1] += 1

            sys.setprofile(hook)
            try:
                return function(*args)
            finally:
                sys.setprofile(None)
                with self.lock:
                    self.totals[0] += tally[0]
                    self.totals[1] += tally[1]
                    self.totals[2] += 1
                    self._save()
        return run


@functools.lru_cache(maxsize=1)
def call_count():
    """The process's CallCount when the environment asked for one at start
    (COUNT_CALLS, read once), else None."""
    path = os.environ.get(COUNT_CALLS)
    return CallCount(path) if path else None
