"""A command's parts, for the node of commands (services.py,
docs/services.md): the spec tables a node fills in, the elements of a reply
or of a command's arguments read, checked and converted, the Bottle a
request or a response fills, the counts of each service and the texts of
its totals and `stats`. No rclpy: plain code with its own tests
(tests/test_runtime_services.py)."""

import collections

import yarp

from .base import _FLOAT_TYPES, _INT_TYPES, ConverterSpec, add_value, add_values, integer, scale_range  # ybgc:runtime-import

# --------------------------------------------------------------------------
# the texts (held to ybg.lower.services by the tests)

#: the exit totals line of one service
TOTALS_LINE = ("service {name}: calls {calls}, answered {answered}, failed {failed} "
               "(timed out {timed_out}, no server {no_server}, did not fit {unfit})")
#: the keys of one service's `stats` list, after ``service NAME``
STATS_KEYS = ("calls", "answered", "failed", "timed_out", "no_server", "unfit")
#: what `help` answers on the RPC port of a node of commands alone
COMMANDS_HELP = (
    "help: this list",
    "stats: the totals so far, one list per service: "
    "(service NAME calls N answered N failed N timed_out N no_server N unfit N)",
    "quit: stop the module (it closes its ports and exits 0, as on SIGINT)",
)
#: the failure reasons counted as "timed out" (``stopped``: the node stopped
#: before the call was answered)
_TIMED_OUT = ("timed_out", "waited", "stopped")
#: the reason of a call given up because the node stops (the runtime's own)
STOPPED = "{module} stopped before {target} answered"


# --------------------------------------------------------------------------
# the spec tables a node fills in

#: a converter of a service's elements: y = x * scale + offset on [start, stop)
#: (a stream's linear converter)
Conv = ConverterSpec

#: A ROS 2 service served by the node, answered by the YARP RPC port ``port``.
#: ``command(request)`` -> the Bottle sent; ``fill(reply, e, response)``
#: fills the response from the reply and its elements ``e`` (Elements) and
#: returns it; ``failure(response, reason)`` the failure answer; ``types``:
#: the reply's declared element types (None: as they come); ``reasons``: the
#: texts of ybg.lower.services.reasons.
ServeRos2 = collections.namedtuple(
    "ServeRos2", "name service srv_class type_name port timeout types converters true_words "
                 "command fill failure reasons description")

#: A YARP RPC command served by the node on the port ``port`` (its first
#: word ``name``), answered by the ROS 2 service ``service``:
#: ``request(args, request)`` fills the request from the arguments ``args``
#: (Elements) and returns it; ``reply(response)`` -> the reply Bottle;
#: ``failure(response, reason)`` -> the failure reply (``response`` a fresh one).
ServeYarp = collections.namedtuple(
    "ServeYarp", "name port service srv_class type_name timeout types converters true_words "
                 "request reply failure reasons description")

#: A YARP RPC port the node serves: its name and what `help` answers there
PortSpec = collections.namedtuple("PortSpec", "name help")

#: The node: its services (ServeRos2, ServeYarp), the ports it serves
#: (PortSpec), ``unknown_command``: the text of a command no service names
#: (``{word}``: the word)
CommandsSpec = collections.namedtuple(
    "CommandsSpec", "module config node_name default_prefix description services ports unknown_command")


# --------------------------------------------------------------------------
# the elements of a Bottle, checked and converted

class Unfit(ValueError):
    """A reply, or a command's arguments, that does not fit: why."""


class Word(str):
    """A word of a Bottle: a string or a vocab."""


class Nested:
    """A nested list of a Bottle (never a field's value)."""

    def __init__(self, text):
        self.text = text


def value_of(v):
    """The Python value of a Bottle's Value: an int, a float, a bool, a Word
    (a string, or a vocab as its word) or a Nested list."""
    if v.isList():
        return Nested("(%s)" % v.asList().toString())
    if v.isString():
        return Word(v.asString())
    if v.isVocab32():
        return Word(yarp.decode(v.asVocab32()))
    if v.isFloat64() or v.isFloat32():
        return v.asFloat64()
    if v.isInt32() or v.isInt64() or v.isInt8() or v.isInt16():
        return v.asInt64()
    if v.isBool():
        return v.asBool()
    return Nested(v.toString())


def describe_value(x):
    """What a value is, as a reason says it."""
    if isinstance(x, Nested):
        return "a list %s" % x.text
    if isinstance(x, Word):
        return "the word %s" % x
    if isinstance(x, bool):
        return "a bool"
    if isinstance(x, int):
        return "the integer %d" % x
    if isinstance(x, float):
        return "the number %r" % x
    return repr(x)


def _is_number(x):
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def check_types(values, types):
    """``values`` as the declaration ``types`` takes them (a number as a
    float, an integer, a word, a bool), or Unfit."""
    if len(values) != len(types):
        raise Unfit("%d element%s, expected %d" % (len(values), "" if len(values) == 1 else "s", len(types)))
    out = []
    for k, (x, t) in enumerate(zip(values, types)):
        if t in _FLOAT_TYPES:
            if not _is_number(x):
                raise Unfit("element %d is %s, expected %s" % (k, describe_value(x), t))
            out.append(float(x))
        elif t in _INT_TYPES:
            if not isinstance(x, int) or isinstance(x, bool):
                raise Unfit("element %d is %s, expected %s" % (k, describe_value(x), t))
            out.append(x)
        elif t == "string":
            if not isinstance(x, Word):
                raise Unfit("element %d is %s, expected a string" % (k, describe_value(x)))
            out.append(x)
        elif t == "bool":
            if isinstance(x, bool):
                out.append(x)
            elif isinstance(x, int) and x in (0, 1):
                out.append(x == 1)
            else:
                raise Unfit("element %d is %s, expected a bool (0 or 1)" % (k, describe_value(x)))
        else:
            raise Unfit("element %d has the unknown type %s" % (k, t))
    return out


def convert_elements(values, converters):
    """The converters, in order, as a stream's (y = x * scale + offset on
    [start, stop)): each element they convert must be a number, else Unfit."""
    values = list(values)
    for c in converters:
        stop = len(values) if c.stop is None else min(c.stop, len(values))
        for k in range(c.start, stop):
            if not _is_number(values[k]):
                raise Unfit("element %d is %s, not a number (%s)" % (k, describe_value(values[k]), c.name))
        scale_range(values, c)
    return values


class Elements:
    """The elements of a Bottle from ``start`` (a reply: 0; a command's
    arguments: 1, after its word), checked against ``types`` (None:
    undeclared, each as it came) and converted; what a node's functions
    fill fields from. Each method raises Unfit for an element that cannot
    fill the field."""

    def __init__(self, bottle, start=0, types=None, converters=(), true_words=()):
        self.bottle = bottle
        self.start = start
        self.true_words = tuple(true_words)
        values = [value_of(bottle.get(k)) for k in range(start, bottle.size())]
        if types is not None:
            values = check_types(values, types)
        self.values = convert_elements(values, converters)

    def __len__(self):
        return len(self.values)

    def text(self):
        """The Bottle as text (``Bottle::toString``): a reply whole, a
        command's arguments after its word."""
        if self.start == 0:
            return self.bottle.toString()
        return self.bottle.tail().toString() if self.start == 1 else \
            " ".join(self.bottle.get(k).toString() for k in range(self.start, self.bottle.size()))

    def _at(self, k):
        if k >= len(self.values):
            raise Unfit("no element %d (%d element%s)" % (k, len(self.values), "" if len(self.values) == 1 else "s"))
        return self.values[k]

    def _range(self, start, stop):
        n = len(self.values)
        end = n if stop is None else stop
        if start > n or end > n:
            raise Unfit("no elements [%d:%s] (%d element%s)" % (start, "" if stop is None else stop, n,
                                                               "" if n == 1 else "s"))
        return range(start, end)

    # -- one element into a field
    def float(self, k):
        x = self._at(k)
        if isinstance(x, bool):
            return 1.0 if x else 0.0
        if not _is_number(x):
            raise Unfit("element %d is %s, not a number" % (k, describe_value(x)))
        return float(x)

    def int(self, k):
        x = self._at(k)
        if isinstance(x, bool):
            return 1 if x else 0
        if isinstance(x, float) and x.is_integer():
            return int(x)
        if not isinstance(x, int):
            raise Unfit("element %d is %s, not an integer" % (k, describe_value(x)))
        return x

    def byte(self, k):
        x = self.int(k)
        if not 0 <= x <= 255:
            raise Unfit("element %d is %d, not a byte" % (k, x))
        return bytes((x,))

    def str(self, k):
        x = self._at(k)
        if not isinstance(x, Word):
            raise Unfit("element %d is %s, not a word" % (k, describe_value(x)))
        return str(x)

    def bool(self, k):
        """A word is true when it is one of the true words, a number when it is not 0."""
        x = self._at(k)
        if isinstance(x, Word):
            return x in self.true_words
        if isinstance(x, bool):
            return x
        if _is_number(x):
            return x != 0
        raise Unfit("element %d is %s, not a word or a number" % (k, describe_value(x)))

    # -- the elements [start, stop) into an array field (``fixed``: exactly
    # that many; ``bound``: at most)
    def _many(self, get, start, stop, fixed, bound, field):
        items = [get(k) for k in self._range(start, stop)]
        if fixed is not None and len(items) != fixed:
            raise Unfit("field %s holds exactly %d values, got %d" % (field, fixed, len(items)))
        if bound is not None and len(items) > bound:
            raise Unfit("field %s holds at most %d values, got %d" % (field, bound, len(items)))
        return items

    def floats(self, start, stop=None, fixed=None, bound=None, field="?"):
        return self._many(self.float, start, stop, fixed, bound, field)

    def ints(self, start, stop=None, fixed=None, bound=None, field="?"):
        return self._many(self.int, start, stop, fixed, bound, field)

    def bytes(self, start, stop=None, fixed=None, bound=None, field="?"):
        return self._many(self.byte, start, stop, fixed, bound, field)

    def strs(self, start, stop=None, fixed=None, bound=None, field="?"):
        return self._many(self.str, start, stop, fixed, bound, field)

    def bools(self, start, stop=None, fixed=None, bound=None, field="?"):
        return self._many(self.bool, start, stop, fixed, bound, field)


# --------------------------------------------------------------------------
# building Bottles from a message's fields

def add_converted(bottle, values, scale, offset):
    """A number field (an array: each element) through a converter, as float64."""
    if isinstance(values, (bytes, bytearray)):
        values = list(values)
    if not hasattr(values, "__len__"):
        values = (values,)
    for x in values:
        bottle.addFloat64(float(integer(x) if isinstance(x, (bytes, bytearray)) else x) * scale + offset)


def reason_text(template, reply=None, why=None):
    """A reason of ybg.lower.services with what is known at run time."""
    text = template
    if reply is not None:
        text = text.replace("{reply}", reply)
    if why is not None:
        text = text.replace("{why}", why)
    return text


# --------------------------------------------------------------------------
# counts

class Counts:
    """What one service did: calls, answered, failed (timed out, no server,
    did not fit)."""

    __slots__ = ("calls", "answered", "timed_out", "no_server", "unfit", "last")

    def __init__(self):
        self.calls = self.answered = self.timed_out = self.no_server = self.unfit = 0
        self.last = None  # the reason of the last call that failed, None after a success

    @property
    def failed(self):
        return self.timed_out + self.no_server + self.unfit

    def as_dict(self):
        return {"calls": self.calls, "answered": self.answered, "failed": self.failed,
                "timed_out": self.timed_out, "no_server": self.no_server, "unfit": self.unfit}

    def count(self, reason_key, text=None):
        """One call ended: answered (``reason_key`` None) or failed."""
        if reason_key is None:
            self.answered += 1
            self.last = None
            return
        if reason_key in _TIMED_OUT:
            self.timed_out += 1
        elif reason_key == "no_server":
            self.no_server += 1
        else:
            self.unfit += 1
        self.last = text or reason_key


def totals_lines(services, counts):
    return [TOTALS_LINE.format(name=s.name, **counts[s.name].as_dict()) for s in services]


def stats_reply(reply, services, counts):
    """`stats`: one list per service (no vocab many before them: `yarp rpc`
    would print the items of a lone list one by one)."""
    for s in services:
        item = reply.addList()
        item.addString("service")
        item.addString(s.name)
        d = counts[s.name].as_dict()
        for key in STATS_KEYS:
            item.addString(key)
            item.addInt64(d[key])
    return reply

