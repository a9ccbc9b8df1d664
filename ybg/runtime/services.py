"""Commands: the rclpy node of a config of ``[service]`` sections
(docs/services.md), between YARP RPC ports and ROS 2 services, both ways.

- A ROS 2 service served by the node (``ServeRos2``): each request becomes
  a command Bottle (the node's function), sent to a YARP RPC port; the
  reply fills the response (the node's function). The calls to one YARP
  port are made one after another, in the order they came, by one thread
  (``YarpCaller``), each within its own deadline (its arrival + its
  timeout): a call that waited its whole timeout for the ones before it
  fails without being sent.
- A YARP RPC port served by the node (``ServeYarp``, ``ServedPort``): a
  command whose first word names a service fills the request from its
  arguments, calls the ROS 2 service (``Ros2Caller``) and replies the
  Bottle the node's function builds; ``help`` lists the commands.

Never hang, never lie: every call ends within its timeout, with the
answer of success or the failure answer (the node's function, given the
reason): no server, no answer in time, a reply or command that does not
fit. Counted per service, in ``stats`` on the module's RPC port, in the
exit totals and on /diagnostics.

Blocking YARP calls: ``yarp.Port`` lets the interpreter lock go in its
calls (on every YARP the tests run), so a thread waiting in ``write`` or
``read`` stops no other. A write waiting for a stopped server cannot be
interrupted (``interrupt`` and ``close`` wait for it): the client port is
opened with a timeout (``Port.setTimeout``, the longest of its services'),
after which YARP gives the write up and drops the connection; the caller
itself waits on a Python event until its own deadline, never longer.

Plain code with its own tests (tests/test_runtime_services.py): the texts
it prints are made by the compiler (``ybg.lower.services``) and printed
into the node.
"""

import argparse
import collections
import os
import signal
import sys
import threading
import time

import rclpy
import rclpy.utilities
import yarp
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.clock import Clock, ClockType
from rclpy.executors import MultiThreadedExecutor
from rclpy.signals import SignalHandlerOptions

# --------------------------------------------------------------------------
# the texts (held to ybg.lower.services by the tests)

#: the exit totals line of one service
TOTALS_LINE = ("service {name}: calls {calls}, answered {answered}, failed {failed} "
               "(timed out {timed_out}, no server {no_server}, did not fit {unfit})")
#: the keys of one service's `stats` list, after ``service NAME``
STATS_KEYS = ("calls", "answered", "failed", "timed_out", "no_server", "unfit")
#: what `help` answers on the module's own RPC port
RPC_HELP = (
    "help: this list",
    "stats: the totals so far, one list per service: "
    "(service NAME calls N answered N failed N timed_out N no_server N unfit N)",
    "quit: stop the module (it closes its ports and exits 0, as on SIGINT)",
)
#: the seconds between two /diagnostics messages, unless the parameter
#: diagnostic_updater.period says (as the stream bridges' ros2_io.DIAGNOSTICS_PERIOD)
DIAGNOSTICS_PERIOD = 1.0
#: the failure reasons counted as "timed out" (``stopped``: the node stopped
#: before the call was answered)
_TIMED_OUT = ("timed_out", "waited", "stopped")
#: the reason of a call given up because the node stops (the runtime's own)
STOPPED = "{module} stopped before {target} answered"


# --------------------------------------------------------------------------
# the spec tables a node fills in

#: a converter of a service's elements: y = x * scale + offset on [start, stop)
Conv = collections.namedtuple("Conv", "name scale offset to_float start stop")

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


_FLOAT_TYPES = frozenset(("float32", "float64"))
_INT_TYPES = frozenset(("int8", "uint8", "int16", "uint16", "int32", "uint32",
                        "int64", "uint64", "byte", "char"))


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


def describe(x):
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
                raise Unfit("element %d is %s, expected %s" % (k, describe(x), t))
            out.append(float(x))
        elif t in _INT_TYPES:
            if not isinstance(x, int) or isinstance(x, bool):
                raise Unfit("element %d is %s, expected %s" % (k, describe(x), t))
            out.append(x)
        elif t == "string":
            if not isinstance(x, Word):
                raise Unfit("element %d is %s, expected a string" % (k, describe(x)))
            out.append(x)
        elif t == "bool":
            if isinstance(x, bool):
                out.append(x)
            elif isinstance(x, int) and x in (0, 1):
                out.append(x == 1)
            else:
                raise Unfit("element %d is %s, expected a bool (0 or 1)" % (k, describe(x)))
        else:
            raise Unfit("element %d has the unknown type %s" % (k, t))
    return out


def convert(values, converters):
    """The converters, in order: y = x * scale + offset on [start, stop)."""
    values = list(values)
    for c in converters:
        stop = len(values) if c.stop is None else min(c.stop, len(values))
        for k in range(c.start, stop):
            x = values[k]
            if not _is_number(x):
                raise Unfit("element %d is %s, not a number (%s)" % (k, describe(x), c.name))
            y = x * c.scale + c.offset
            values[k] = float(y) if c.to_float or not isinstance(x, int) else int(y)
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
        self.values = convert(values, converters)

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
            raise Unfit("element %d is %s, not a number" % (k, describe(x)))
        return float(x)

    def int(self, k):
        x = self._at(k)
        if isinstance(x, bool):
            return 1 if x else 0
        if isinstance(x, float) and x.is_integer():
            return int(x)
        if not isinstance(x, int):
            raise Unfit("element %d is %s, not an integer" % (k, describe(x)))
        return x

    def byte(self, k):
        x = self.int(k)
        if not 0 <= x <= 255:
            raise Unfit("element %d is %d, not a byte" % (k, x))
        return bytes((x,))

    def str(self, k):
        x = self._at(k)
        if not isinstance(x, Word):
            raise Unfit("element %d is %s, not a word" % (k, describe(x)))
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
        raise Unfit("element %d is %s, not a word or a number" % (k, describe(x)))

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

def _integer(x):
    """A field's integer value (a ``byte`` field holds bytes)."""
    if isinstance(x, (bytes, bytearray)):
        return x[0] if len(x) == 1 else int.from_bytes(x, "little")
    return int(x)


def _signed(x, bits):
    half = 1 << (bits - 1)
    return ((_integer(x) + half) % (half << 1)) - half


def add_value(bottle, wire, x):
    """One value on the wire type ``wire`` (int32, int64, float64, string);
    a bool is the int32 0 or 1."""
    if wire == "float64":
        bottle.addFloat64(float(x))
    elif wire == "int32":
        bottle.addInt32(_signed(x, 32))
    elif wire == "int64":
        bottle.addInt64(_signed(x, 64))
    elif wire == "string":
        bottle.addString(str(x))
    else:
        raise ValueError("no wire type %r" % (wire,))


def add_values(bottle, wire, values):
    """An array field: one item per element."""
    if isinstance(values, (bytes, bytearray)):
        values = list(values)
    for x in values:
        add_value(bottle, wire, x)


def add_converted(bottle, values, scale, offset):
    """A number field (an array: each element) through a converter, as float64."""
    if isinstance(values, (bytes, bytearray)):
        values = list(values)
    if not hasattr(values, "__len__"):
        values = (values,)
    for x in values:
        bottle.addFloat64(float(_integer(x) if isinstance(x, (bytes, bytearray)) else x) * scale + offset)


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


def first_word(bottle):
    """The command's first item as a word ('' for none or a number)."""
    if bottle.size() == 0:
        return ""
    v = bottle.get(0)
    if v.isString():
        return v.asString()
    if v.isVocab32():
        return yarp.decode(v.asVocab32())
    return v.toString()


# --------------------------------------------------------------------------
# calling a YARP RPC port

class _Call:
    __slots__ = ("command", "deadline", "done", "reply", "reason", "sent", "over")

    def __init__(self, command, deadline):
        self.command = command
        self.deadline = deadline
        self.done = threading.Event()
        self.reply = None
        self.reason = None
        self.sent = False   # taken by the caller's thread
        self.over = False   # answered (by the thread) or given up (by its caller)


class YarpCaller:
    """One YARP RPC port called by the node: one connection at a time,
    through its own port ``local`` (opened with ``timeout``, the longest of
    its services': YARP gives a write up after it). Calls are made one
    after another, in the order they came, by one thread; ``call`` returns
    by the call's deadline whatever the server does. After a failed call
    the port is closed and opened afresh, so that nothing of that call's
    connection is ever read as another's; the next call connects again."""

    def __init__(self, local, target, timeout, log):
        self.local = local
        self.target = target
        self.timeout = timeout
        self.log = log
        self.port = None
        self.queue = collections.deque()
        self.cond = threading.Condition()
        self.stopping = False
        self.busy = False
        self.thread = threading.Thread(target=self._run, name="calls to " + target, daemon=True)

    # -- the port
    def open(self):
        port = yarp.Port()
        port.setTimeout(float(self.timeout))
        port.setOutputMode(True)
        port.setInputMode(False)
        if not port.open(self.local):
            return False
        self.port = port
        if not self.thread.is_alive():
            self.thread.start()
        return True

    def _fresh(self):
        """Close the port (after a failed call) and open a new one."""
        port, self.port = self.port, None
        if port is not None:
            port.close()
        if not self.stopping:
            if not self.open():
                self.log("cannot open the port %s again" % self.local)

    def _connected(self):
        port = self.port
        if port is None:
            return False
        if port.getOutputCount() > 0:
            return True
        style = yarp.ContactStyle()
        style.quiet = True
        return yarp.Network.connect(self.local, self.target, style)

    # -- calls
    def call(self, command, deadline, stop_event=None):
        """(reply, None) or (None, reason key): ``no_server``, ``timed_out``,
        ``waited`` (its whole timeout spent waiting for the calls before it),
        ``stopped`` (``stop_event`` set before the deadline)."""
        c = _Call(command, deadline)
        with self.cond:
            if self.stopping:
                return None, "stopped"
            self.queue.append(c)
            self.cond.notify_all()
        while True:
            left = deadline - time.monotonic()
            if left <= 0 or (stop_event is not None and stop_event.is_set()):
                break
            if c.done.wait(min(left, 0.1)):
                break
        with self.cond:
            if c.over:
                return c.reply, c.reason
            c.over = True  # given up: the thread drops its reply
            if stop_event is not None and stop_event.is_set() and time.monotonic() < deadline:
                try:
                    self.queue.remove(c)
                except ValueError:
                    pass
                return None, "stopped"
            if not c.sent:
                try:
                    self.queue.remove(c)
                except ValueError:
                    pass
                return None, "waited"
        # a server that left the name server while the call waited (it quit) is no
        # server, whether or not its leaving broke the connection before the deadline
        # (the C++ runtime says the same); one still registered did not answer in time
        return None, "timed_out" if self._registered() else "no_server"

    def _registered(self):
        try:
            return yarp.Network.queryName(self.target).isValid()
        except Exception:  # a name server that cannot be asked: as before, no answer in time
            return True

    def _run(self):
        while True:
            with self.cond:
                while not self.queue and not self.stopping:
                    self.cond.wait()
                if self.stopping:
                    return
                c = self.queue.popleft()
                if c.over:
                    continue
                if time.monotonic() >= c.deadline:
                    self._answer(c, None, "waited")
                    continue
                c.sent = True
                self.busy = True
            try:
                self._send(c)
            except Exception as e:  # never a traceback out of the thread
                self.log("calling %s: %s: %s" % (self.target, type(e).__name__, e))
                with self.cond:
                    self._answer(c, None, "no_server")
                self._fresh()
            finally:
                with self.cond:
                    self.busy = False
                    self.cond.notify_all()

    def _send(self, c):
        if not self._connected():
            with self.cond:
                self._answer(c, None, "timed_out" if time.monotonic() >= c.deadline else "no_server")
            self._fresh()
            return
        reply = yarp.Bottle()
        ok = self.port.write(c.command, reply)
        with self.cond:
            if ok:
                self._answer(c, reply, None)
                return
            self._answer(c, None, "timed_out" if time.monotonic() >= c.deadline else "no_server")
        self._fresh()

    def _answer(self, c, reply, reason):
        """Under the lock: the call's answer, unless its caller gave it up."""
        if not c.over:
            c.over = True
            c.reply, c.reason = reply, reason
        c.done.set()

    def stop(self):
        with self.cond:
            self.stopping = True
            for c in self.queue:
                c.done.set()
            self.cond.notify_all()

    def close(self):
        """Close the port (a write waiting for a stopped server keeps it open
        until YARP gives up: the node then unregisters its name)."""
        port = self.port
        if port is not None:
            port.close()


# --------------------------------------------------------------------------
# calling a ROS 2 service

class Ros2Caller:
    """A ROS 2 service called by the node: each call waits for a server up
    to its deadline, then for its response up to the deadline; a response
    that comes later is dropped (rclpy matches each response to its request)."""

    POLL = 0.01

    def __init__(self, node, srv_class, name, group):
        self.name = name
        self.client = node.create_client(srv_class, name, callback_group=group)

    def call(self, request, deadline, stop_event):
        """(response, None) or (None, reason key): ``no_server``, ``timed_out``,
        ``stopped`` (``stop_event`` set before the deadline)."""
        while not self.client.service_is_ready():
            if stop_event.is_set():
                return None, "stopped"
            if time.monotonic() >= deadline:
                return None, "no_server"
            time.sleep(self.POLL)
        done = threading.Event()
        future = self.client.call_async(request)
        future.add_done_callback(lambda f: done.set())
        while not done.is_set():
            left = deadline - time.monotonic()
            if left <= 0 or stop_event.is_set():
                break
            done.wait(min(left, 0.1))
        if not future.done():
            self.client.remove_pending_request(future)
            future.cancel()
            return None, "stopped" if stop_event.is_set() and time.monotonic() < deadline else "timed_out"
        try:
            return future.result(), None
        except Exception:
            return None, "timed_out"


# --------------------------------------------------------------------------
# a YARP RPC port served by the node

class _CommandReader(yarp.PortReader):
    """What YARP calls for each command on a served port, in the thread of
    the connection it came by: the connections of several callers are
    answered at once (a `quit` is not kept waiting by a call in flight)."""

    def __init__(self, served):
        yarp.PortReader.__init__(self)
        self.served = served

    def read(self, connection):
        return self.served.read(connection)


class ServedPort:
    """A YARP RPC port the node serves: each command answered by
    ``answer(command)`` in the thread of its connection, the reply written
    back on it. ``after_reply`` (quit) is called once a reply is sent."""

    def __init__(self, name, answer, log):
        self.name = name
        self.answer = answer
        self.log = log
        self.port = yarp.Port()
        self.reader = _CommandReader(self)
        self.stopping = False
        self.busy = 0
        self.lock = threading.Lock()
        self.after_reply = None

    def open(self):
        self.port.setReader(self.reader)
        return self.port.open(self.name)

    def read(self, connection):
        with self.lock:
            self.busy += 1
        try:
            command = yarp.Bottle()
            if self.stopping or not command.read(connection):
                return False
            try:
                reply = self.answer(command)
            except Exception as e:  # never a traceback out of YARP's thread; never no answer
                self.log("port %s: %s: %s" % (self.name, type(e).__name__, e))
                reply = yarp.Bottle()
                reply.addVocab32("fail")
                reply.addString("%s: %s" % (type(e).__name__, e))
            writer = connection.getWriter()
            if writer is not None:
                reply.write(writer)
            return True
        except Exception as e:
            self.log("port %s: %s: %s" % (self.name, type(e).__name__, e))
            return False
        finally:
            with self.lock:
                self.busy -= 1
                then, self.after_reply = self.after_reply, None
            if then is not None:
                then()

    def idle(self):
        with self.lock:
            return self.busy == 0

    def stop(self, grace=0.3):
        """No command taken any more; interrupted once none is being
        answered (closing while YARP's thread waits to answer would deadlock)."""
        self.stopping = True
        end = time.monotonic() + grace
        while not self.idle() and time.monotonic() < end:
            time.sleep(0.005)
        time.sleep(0.05)  # the last reply (`bye` of quit) on its way before the port goes
        self.port.interrupt()

    def close(self):
        self.port.close()


# --------------------------------------------------------------------------
# the node

_LOG_LOCK = threading.Lock()

#: seconds for the stop's steps together (answering the calls in flight,
#: the executor, closing the ports), leaving the rest of the 2 s a module
#: has to exit to the ROS 2 context's shutdown
STOP_WITHIN = 1.3


class CommandsNode:
    """The services of one config of commands, inside an rclpy node."""

    def __init__(self, spec, node, prefix, verbose=False, stop_event=None):
        self.spec = spec
        self.node = node
        self.prefix = prefix
        self.verbose = verbose
        self.stop_event = threading.Event() if stop_event is None else stop_event
        self.quit_asked = False
        self.lock = threading.Lock()
        self.counts = {s.name: Counts() for s in spec.services}
        self.active = 0        # calls being answered
        self.callers = {}      # YARP port -> YarpCaller
        self.ros_callers = {}  # service name -> Ros2Caller
        self.served = []       # ServedPort
        self.services = []     # rclpy services
        self.rpc_name = prefix + "/rpc:i"
        self.by_port = {}      # served port -> {word: ServeYarp}
        for s in spec.services:
            if isinstance(s, ServeYarp):
                self.by_port.setdefault(s.port, {})[s.name] = s
        self.help = {p.name: tuple(p.help) for p in spec.ports}
        #: its own RPC port (help, stats, quit): not in a process of several
        #: bridges, which has one of its own (ybgc_runtime.compose)
        self.own_rpc = True

    def log(self, text):
        with _LOG_LOCK:
            sys.stdout.write("%s: %s\n" % (self.spec.module, text))
            sys.stdout.flush()

    # -- counts
    def _count(self, s, reason_key=None, text=None):
        with self.lock:
            self.counts[s.name].count(reason_key, text)

    def _call_started(self, s):
        with self.lock:
            self.counts[s.name].calls += 1

    def _reason(self, s, key):
        if key == "stopped":
            return STOPPED.format(module=self.spec.module, target=s.port if isinstance(s, ServeRos2) else s.service)
        return s.reasons[key]

    def _active(self, step):
        with self.lock:
            self.active += step

    # -- a ROS 2 service served, a YARP port called
    def serve_ros2(self, s, request, response):
        """The rclpy service's callback (an executor thread each)."""
        arrival = time.monotonic()
        self._active(1)
        try:
            return self._serve_ros2(s, request, arrival + s.timeout)
        finally:
            self._active(-1)

    def _serve_ros2(self, s, request, deadline):
        self._call_started(s)
        try:
            command = s.command(request)
        except Exception as e:
            text = reason_text(s.reasons["unfit_reply"], "nothing",
                               "the request does not fit the command (%s)" % e)
            return self._ros2_failure(s, "unfit", text)
        reply, key = self.callers[s.port].call(command, deadline, self.stop_event)
        if key is not None:
            return self._ros2_failure(s, key, self._reason(s, key), command)
        try:
            e = Elements(reply, 0, s.types, s.converters, s.true_words)
            out = s.fill(reply, e, s.srv_class.Response())
        except (Unfit, AssertionError, TypeError, ValueError, OverflowError, IndexError) as e:
            text = reason_text(s.reasons["unfit_reply"], reply.toString(), str(e))
            return self._ros2_failure(s, "unfit", text, command)
        self._count(s)
        if self.verbose:
            self.log("service %s: %s -> %s" % (s.name, command.toString(), reply.toString()))
        return out

    def _ros2_failure(self, s, key, text, command=None):
        self._count(s, key, text)
        if self.verbose or self.counts[s.name].failed == 1:
            more = "" if self.verbose else "; further failures are only counted"
            self.log("service %s: %s%s" % (s.name, text, more))
        return s.failure(s.srv_class.Response(), text)

    # -- a YARP port served, a ROS 2 service called
    def answer(self, port, command):
        """The reply to a command on a served port (or on the module's RPC port)."""
        word = first_word(command)
        commands = self.by_port.get(port, {})
        s = commands.get(word)
        if s is not None:
            return self.serve_yarp(s, command)
        reply = yarp.Bottle()
        own = port == self.rpc_name and self.own_rpc
        if word == "help":
            # a served port: its commands (stats and quit unlisted where it is the module's own too)
            reply.addVocab32("many")
            for line in self.help.get(port) or RPC_HELP:
                reply.addString(line)
            return reply
        if own and word == "stats":
            with self.lock:
                return stats_reply(reply, self.spec.services, self.counts)
        if own and word in ("quit", "exit", "bye"):
            self.log("asked to quit on the RPC port")
            self.quit_asked = True
            reply.addVocab32("bye")
            return reply
        text = self.spec.unknown_command.replace("{word}", word)
        if commands:
            # a served port: the failure reply (of its first command), and why
            first = next(iter(commands.values()))
            return first.failure(first.srv_class.Response(), text)
        reply.addVocab32("fail")
        reply.addString(text)
        return reply

    def serve_yarp(self, s, command):
        arrival = time.monotonic()
        self._active(1)
        try:
            return self._serve_yarp(s, command, arrival + s.timeout)
        finally:
            self._active(-1)

    def _serve_yarp(self, s, command, deadline):
        self._call_started(s)
        try:
            args = Elements(command, 1, s.types, s.converters, s.true_words)
            request = s.request(args, s.srv_class.Request())
        except (Unfit, AssertionError, TypeError, ValueError, OverflowError, IndexError) as e:
            return self._yarp_failure(s, "unfit", reason_text(s.reasons["bad_arguments"], why=str(e)))
        response, key = self.ros_callers[s.name].call(request, deadline, self.stop_event)
        if key is not None:
            return self._yarp_failure(s, key, self._reason(s, key))
        try:
            reply = s.reply(response)
        except (AssertionError, TypeError, ValueError, OverflowError, IndexError) as e:
            return self._yarp_failure(s, "unfit", reason_text(s.reasons["unfit_reply"], str(response), str(e)))
        self._count(s)
        if self.verbose:
            self.log("service %s: %s -> %s" % (s.name, command.toString(), reply.toString()))
        return reply

    def _yarp_failure(self, s, key, text):
        self._count(s, key, text)
        if self.verbose or self.counts[s.name].failed == 1:
            more = "" if self.verbose else "; further failures are only counted"
            self.log("service %s: %s%s" % (s.name, text, more))
        return s.failure(s.srv_class.Response(), text)

    # -- start and stop
    def open(self, group):
        """Open every port, service and client; False (said why) if one fails."""
        local_names = {}
        timeouts = {}
        for s in self.spec.services:
            if isinstance(s, ServeRos2):
                local_names.setdefault(s.port, "%s/%s/rpc:o" % (self.prefix, s.name))
                timeouts[s.port] = max(timeouts.get(s.port, 0.0), float(s.timeout))
        for port, local in local_names.items():
            caller = YarpCaller(local, port, timeouts[port], self.log)
            if not caller.open():
                self.log("cannot open the port %s" % local)
                return False
            self.callers[port] = caller
        ports = [p.name for p in self.spec.ports]
        if self.rpc_name not in ports and self.own_rpc:
            ports.append(self.rpc_name)
        for name in ports:
            served = ServedPort(name, lambda command, name=name: self._answer_then(name, command), self.log)
            if not served.open():
                self.log("cannot open the port %s" % name)
                return False
            self.served.append(served)
        for s in self.spec.services:
            try:
                if isinstance(s, ServeRos2):
                    self.services.append(self.node.create_service(
                        s.srv_class, s.service, lambda req, res, s=s: self.serve_ros2(s, req, res),
                        callback_group=group))
                else:
                    self.ros_callers[s.name] = Ros2Caller(self.node, s.srv_class, s.service, group)
            except Exception as e:  # an rclpy error: said, never a traceback
                self.log("cannot %s the ROS 2 service %s: %s" % (
                    "serve" if isinstance(s, ServeRos2) else "call", s.service, e))
                return False
        return True

    def _answer_then(self, port, command):
        reply = self.answer(port, command)
        if self.quit_asked and not self.stop_event.is_set():
            served = next(p for p in self.served if p.name == port)
            served.after_reply = self.request_stop
        return reply

    def request_stop(self, *_):
        self.stop_event.set()

    def begin_stop(self, grace=0.5):
        """Stop taking calls; the calls in flight are answered (the
        failure answer, ``stopped``) within ``grace`` seconds."""
        self.stop_event.set()
        for caller in self.callers.values():
            caller.stop()
        for served in self.served:
            served.stopping = True
        end = time.monotonic() + grace
        while time.monotonic() < end:
            with self.lock:
                if self.active == 0:
                    break
            time.sleep(0.01)

    def shut_down(self, within=1.0):
        """Close every port within ``within`` seconds: True when everything
        closed (else the caller exits at once, the names unregistered)."""
        self.begin_stop(0.0)
        closed = []
        names = [p.name for p in self.served] + [c.local for c in self.callers.values()]

        def close_all():
            for served in self.served:
                served.stop()
            for served in self.served:
                served.close()
                closed.append(served.name)
            for caller in self.callers.values():
                if caller.busy:
                    continue  # a write waiting for its server: unregistered below
                caller.close()
                closed.append(caller.local)

        closer = threading.Thread(target=close_all, name="close ports", daemon=True)
        closer.start()
        closer.join(within)
        done = not closer.is_alive() and len(closed) == len(names)
        if not done:
            for name in names:
                if name not in closed:
                    yarp.Network.unregisterName(name)
        return done

    def print_totals(self, prefix=""):
        """The totals at exit; ``prefix`` heads each line (the bridge's name,
        in a process of several bridges)."""
        with self.lock:
            lines = ["totals:"] + totals_lines(self.spec.services, self.counts)
        print("\n".join(prefix + line for line in lines), flush=True)


# --------------------------------------------------------------------------
# /diagnostics

def service_status(s, counts):
    """The (level, message, key-values) of one service: OK until a call
    fails, WARN while its last call failed (the reason)."""
    if counts.last is None:
        level = DiagnosticStatus.OK
        text = "no call yet" if counts.calls == 0 else "answered its last call"
    else:
        level, text = DiagnosticStatus.WARN, "its last call failed: %s" % counts.last
    d = counts.as_dict()
    values = [(key.replace("_", " "), str(d[key])) for key in STATS_KEYS]
    values += [("timeout (s)", "%g" % s.timeout)]
    return level, text, values


class ServiceDiagnostics:
    """The services' counts on /diagnostics every ``period`` seconds of the
    steady clock: one status per service (``<node>: service <name>``),
    hardware_id the module's name."""

    def __init__(self, commands, node, period):
        self.commands = commands
        self.node = node
        self.name = node.get_name()
        self.publisher = node.create_publisher(DiagnosticArray, "/diagnostics", 1)
        self.timer = node.create_timer(period, self.publish, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def array(self):
        statuses = []
        with self.commands.lock:
            for s in self.commands.spec.services:
                level, text, values = service_status(s, self.commands.counts[s.name])
                statuses.append(DiagnosticStatus(
                    level=level, name="%s: service %s" % (self.name, s.name), message=text,
                    hardware_id=self.commands.spec.module,
                    values=[KeyValue(key=k, value=v) for k, v in values]))
        msg = DiagnosticArray(status=statuses)
        msg.header.stamp = self.node.get_clock().now().to_msg()
        return msg

    def publish(self):
        self.publisher.publish(self.array())


# --------------------------------------------------------------------------
# a node of commands among the bridges of one process (ybgc compose)

class ComposedCommands:
    """The node of commands as one bridge of a composed process
    (ybgc_runtime.compose.Composer): its services, served ports and callers
    as alone, but not its own RPC port (the process has one); its executor
    (threads of its own) run by the bridge's loop thread."""

    def __init__(self, spec, node, options):
        self.spec = spec
        self.node = node
        self.cond = threading.Condition(threading.RLock())  # as a bridge's (the composer takes it to stop it)
        self.stopping = False
        self.commands = CommandsNode(spec, node, options.prefix, options.verbose)
        self.commands.own_rpc = False
        self.executor = None
        self.problem = None
        log = self.commands.log

        def said(text):  # what could not open, for the composer
            self.problem = text
            log(text)
        self.commands.log = said
        self.log = log

    def open_all(self, opened, rpc=False):
        """Open every port, service and client: None, or what could not open."""
        if not self.commands.open(ReentrantCallbackGroup()):
            return self.problem or "cannot open its ports and services"
        self.commands.log = self.log
        self.executor = MultiThreadedExecutor(num_threads=_executor_threads(self.spec))
        self.executor.add_node(self.node)
        for s in self.spec.services:
            self.log(s.description)
        return None

    def start_diagnostics(self, period):
        if period:
            ServiceDiagnostics(self.commands, self.node, period)

    def loop(self):
        _spin(self.executor, self.commands.stop_event, self.log)

    def request_stop(self, *_):
        self.stopping = True
        self.commands.request_stop()

    def port_names(self, opened):
        return [p.name for p in self.commands.served] + [c.local for c in self.commands.callers.values()]

    def close_ports(self, opened):
        """The calls in flight answered, the executor stopped, every port
        closed: (True, a port did not close in time, [] (those are
        unregistered by name already))."""
        self.request_stop()
        self.commands.begin_stop(0.5)
        if self.executor is not None:
            closer = threading.Thread(target=self.executor.shutdown, kwargs={"timeout_sec": 0.3}, daemon=True)
            closer.start()
            closer.join(0.4)
        return True, not self.commands.shut_down(), []

    def unregister(self, names):
        for name in names:
            yarp.Network.unregisterName(name)

    def stats_items(self, reply):
        """What `stats` answers of it: one list per service."""
        with self.commands.lock:
            stats_reply(reply, self.spec.services, self.commands.counts)

    def _print_totals(self, prefix=""):
        self.commands.print_totals(prefix)


# --------------------------------------------------------------------------
# parameters, start and shutdown

class ParameterError(ValueError):
    pass


def node_options(node, default_prefix):
    """The node's parameters: prefix, verbose, diagnostics, diagnostic_updater.period."""
    def declare(name, default, text):
        return node.declare_parameter(name, default, ParameterDescriptor(description=text,
                                                                         dynamic_typing=True)).value

    prefix = declare("prefix", default_prefix, "prefix of the node's own YARP port names")
    if not isinstance(prefix, str) or not prefix.startswith("/"):
        raise ParameterError("parameter prefix must be a string starting with /")
    verbose = declare("verbose", False, "print every call and its answer")
    if not isinstance(verbose, bool):
        raise ParameterError("parameter verbose must be true or false")
    diagnostics = declare("diagnostics", True, "publish the services' counts on /diagnostics")
    if not isinstance(diagnostics, bool):
        raise ParameterError("parameter diagnostics must be true or false")
    period = declare("diagnostic_updater.period", DIAGNOSTICS_PERIOD, "seconds between two /diagnostics messages")
    if isinstance(period, bool) or not isinstance(period, (int, float)) or period <= 0:
        raise ParameterError("parameter diagnostic_updater.period must be a positive number")
    return argparse.Namespace(prefix=prefix, verbose=verbose,
                              diagnostics_period=float(period) if diagnostics else None)


def _parse_command_line(spec, args):
    parser = argparse.ArgumentParser(
        prog=os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else spec.module,
        description="\n".join(spec.description),
        epilog="ROS parameters (--ros-args -p NAME:=VALUE):\n"
               "  prefix        prefix of the node's own YARP port names (default: %s)\n"
               "  verbose       print every call and its answer (default: false)\n"
               "  diagnostics   publish the services' counts on /diagnostics (default: true)\n"
               "  diagnostic_updater.period\n"
               "                seconds between two /diagnostics messages (default: 1)\n"
               "Generated by ybgc from %s." % (spec.default_prefix, spec.config),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_args(args)


def _executor_threads(spec):
    """Threads for the executor: each request of a ROS 2 service served
    waits in one for its YARP call, so that a slow server delays no other."""
    served = sum(1 for s in spec.services if isinstance(s, ServeRos2))
    return min(64, 4 + 8 * served)


def run_commands(spec, argv=None):
    """Start rclpy, YARP and the node's services; run until SIGINT, SIGTERM
    or `quit`; the exit status (0 when stopped, 1 when something could not
    open, 2 for a bad parameter)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    stop = threading.Event()
    signal.signal(signal.SIGINT, lambda *_: stop.set())
    signal.signal(signal.SIGTERM, lambda *_: stop.set())
    prog = sys.argv[0] if sys.argv and sys.argv[0] else spec.module
    _parse_command_line(spec, rclpy.utilities.remove_ros_args([prog] + argv)[1:])
    try:
        rclpy.init(args=[prog] + argv, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as e:
        print("%s: cannot start ROS 2: %s" % (spec.module, e), flush=True)
        return 2
    node = None
    executor = None
    spinner = None
    status = 1
    commands = None
    try:
        node = rclpy.create_node(spec.node_name)
        try:
            options = node_options(node, spec.default_prefix)
        except ParameterError as e:
            print("%s: %s" % (spec.module, e), flush=True)
            return 2
        commands = CommandsNode(spec, node, options.prefix, options.verbose, stop)
        yarp.Network.init()
        if not yarp.Network.checkNetwork(3.0):
            commands.log("cannot reach the YARP name server (is yarpserver running?)")
            return 1
        if stop.is_set():
            return 0
        if not commands.open(ReentrantCallbackGroup()):
            return 1
        if options.diagnostics_period:
            ServiceDiagnostics(commands, node, options.diagnostics_period)
        executor = MultiThreadedExecutor(num_threads=_executor_threads(spec))
        executor.add_node(node)
        spinner = threading.Thread(target=_spin, args=(executor, stop, commands.log), name="ros 2 executor",
                                   daemon=True)
        spinner.start()
        for s in spec.services:
            commands.log(s.description)
        commands.log("its RPC port: %s (help, stats, quit)" % commands.rpc_name)
        while not stop.is_set():
            stop.wait(0.1)
        status = 0
        return 0
    finally:
        stop.set()
        clean = True
        # every step of the stop within its own bound, and all of them within
        # STOP_WITHIN: the process exits within its 2 s (docs/runtime.md)
        end = time.monotonic() + STOP_WITHIN

        def left(bound):
            return max(0.05, min(bound, end - time.monotonic()))

        if commands is not None:
            commands.begin_stop(left(0.5))  # the calls in flight answered
        if executor is not None:
            # the answers of those calls sent by the executor's threads
            closer = threading.Thread(target=executor.shutdown, kwargs={"timeout_sec": 0.3}, daemon=True)
            closer.start()
            closer.join(left(0.4))
        if spinner is not None:
            spinner.join(left(0.2))
        if commands is not None:
            clean = commands.shut_down(left(1.0))
            commands.print_totals()
        if not clean or (spinner is not None and spinner.is_alive()):
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(status)
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
        if commands is not None:
            yarp.Network.fini()


def _spin(executor, stop, log):
    reported = False
    while not stop.is_set():
        try:
            executor.spin_once(timeout_sec=0.1)
        except Exception as e:
            if stop.is_set() or not rclpy.ok():
                break
            if not reported:
                reported = True
                log("ROS 2 executor: %s" % e)
