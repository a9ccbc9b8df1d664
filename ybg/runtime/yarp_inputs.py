"""A stream bridge's YARP inputs: each Bottle of a YARP port read with the
name of the port that sent it and checked against the input's layout, in
the thread of its connection, and handed to the bridge there when it is
idle, or to the bridge's reading thread when it is busy; a ROS 1 topic read
through YARP (docs/runtime.md, "Reading")."""

import collections
import ctypes
import queue
import threading
import time

import yarp

from .base import _FLOAT_TYPES, _INT_TYPES, call_count  # ybgc:runtime-import
from .connections import admin, withdraw_from_ros_master  # ybgc:runtime-import
from .core import BACKLOG, InputState  # ybgc:runtime-import
from .yarp_values import _describe, _not_a, _number  # ybgc:runtime-import

# --- reading and checking input Bottles --------------------------------------

def _leaves(bottle, out):
    """The Bottle's elements, nested lists flattened depth-first (ROS topics)."""
    for k in range(bottle.size()):
        value = bottle.get(k)
        if value.isList():
            _leaves(value.asList(), out)
        else:
            out.append(value)
    return out


def _at(bottle, path):
    """The value at an index path of nested lists, or None."""
    value = None
    for k in path:
        if bottle is None or not 0 <= k < bottle.size():
            return None
        value = bottle.get(k)
        bottle = value.asList() if value.isList() else None
    return value


def _picked(bottle, positions):
    """The values at ``positions`` (a one-field array input: its elements)."""
    items = []
    for path in positions:
        value = _at(bottle, path)
        if value is None:
            return None
        if value.isList():
            items.extend(value.asList().get(k) for k in range(value.asList().size()))
        else:
            items.append(value)
    return items


#: Bottle.getSpecialization() of a Bottle whose items are all float64: from
#: the bindings, never a literal (YARP 4 changed the tags: 10 became float32)
_TAG_FLOAT64 = yarp.BOTTLE_TAG_FLOAT64


def parse_bottle(bottle, types, flatten, drop_nan, positions=None, floats=False):
    """(values, None) for a Bottle that matches the input's layout, else
    (None, reason). ``types`` None: any number of numbers, each as it came
    (an integer stays an integer, a float32 becomes a float).
    ``positions``: take the values at these index paths (typed ROS 1 topics);
    ``flatten``: nested lists flattened depth-first (untyped ROS 1 topics);
    ``floats``: every element is read as a float (undeclared, or declared
    float32/float64 only), so a Bottle of float64 only is taken whole."""
    if floats and bottle.getSpecialization() == _TAG_FLOAT64:
        # one binding call for the whole Bottle, not two per element: each
        # call lets the GIL go, and input threads reading at once would take
        # turns at it for every element. YARP prints a float64 with 21
        # significant digits (exact), "nan" and "inf" as float() reads them,
        # each one word: as many words as elements.
        try:
            out = list(map(float, bottle.toString().split()))
        except ValueError:
            out = None
        if out is not None and (types is None or len(out) == len(types)):
            if drop_nan:
                for k, x in enumerate(out):
                    if x != x:
                        return None, "element %d is NaN" % k
            return out, None
    if positions is not None:
        items = _picked(bottle, positions)
        if items is None:
            return None, "not laid out as its message type (a field is missing)"
    elif flatten:
        items = _leaves(bottle, [])
    else:
        items = [bottle.get(k) for k in range(bottle.size())]
    out = []
    if types is None:
        # undeclared: any number, as it came (an integer stays an integer)
        for k, value in enumerate(items):
            x = _number(value)
            if x is None:
                return None, _not_a(k, value, "not a number")
            out.append(x)
    else:
        if len(items) != len(types):
            return None, "%d elements, expected %d" % (len(items), len(types))
        for k, (value, t) in enumerate(zip(items, types)):
            if t in _FLOAT_TYPES:
                x = _number(value, t == "float32")
                if x is None:
                    return None, _not_a(k, value, "expected " + t)
                out.append(float(x))
            elif t in _INT_TYPES:
                if not (value.isInt32() or value.isInt64() or value.isInt8() or value.isInt16()):
                    return None, "element %d is %s, expected %s" % (k, _describe(value), t)
                out.append(value.asInt64())
            elif t == "string":
                if not value.isString():
                    return None, "element %d is %s, expected a string" % (k, _describe(value))
                out.append(value.asString())
            elif t == "bool":
                if value.isBool():
                    out.append(value.asBool())
                elif (value.isInt32() or value.isInt64() or value.isInt8() or value.isInt16()) \
                        and value.asInt64() in (0, 1):
                    out.append(value.asInt64() == 1)
                else:
                    return None, "element %d is %s, expected a bool (0 or 1)" % (k, _describe(value))
            else:
                return None, "element %d has the unknown type %s" % (k, t)
    if drop_nan:
        for k, x in enumerate(out):
            if isinstance(x, float) and x != x:
                return None, "element %d is NaN" % k
    return out, None

#: what clears a port's envelope stamp (an empty one)
_NO_ENVELOPE = yarp.Bottle()


#: how many of an input's connection threads keep their interpreter thread
#: state (keep_thread_state)
KEPT_THREADS = 4

_KEPT = threading.local()
_gil_ensure = ctypes.pythonapi.PyGILState_Ensure
_gil_ensure.restype = ctypes.c_int


def keep_thread_state(inp):
    """Called by each YARP thread that reads an input (a connection's, a
    port's callback thread), the first time it enters Python: its thread
    state is kept for the next Bottles. YARP's bindings enter Python from a
    thread of YARP's own with PyGILState_Ensure, which makes a new thread
    state for each call and deletes it after (with its frame stack: a
    mmap, a munmap and a gettid a Bottle, and the page faults of a new
    stack); one more Ensure, never released, keeps it. An input keeps it for
    KEPT_THREADS threads at most (a connection closed keeps its thread's
    state until the process exits; a producer reconnecting again and again
    makes no more than that), the others make one a call, as before."""
    if inp.kept < KEPT_THREADS:
        inp.kept += 1
        _KEPT.state = _gil_ensure()
    else:
        _KEPT.state = None


class _SourceReader(yarp.PortReader):
    """What YARP calls for each Bottle that reaches an input's port, in the
    thread of its connection (one connection at a time: the port's callback
    lock): the input reads it there with the name of the port that sent it."""

    def __init__(self, inp):
        yarp.PortReader.__init__(self)
        self.inp = inp

    def read(self, connection):
        return self.inp.arrive(connection)


class Inbox(threading.Thread):
    """The thread that hands to a bridge what its YARP port inputs read
    while the bridge was busy (a message being built or written, a cycle,
    `stats`), in the order they read it: one for all the inputs of a bridge.
    The inputs' connection threads put (input, what it read, arrival,
    envelope) in its queue, the interpreter's own (``queue.SimpleQueue``: a
    put, and a get that waits with the interpreter lock let go), or, for an
    input read newest-only (``Timing.queue`` 1), the input alone, its newest
    Bottle kept by the input. ``pending``: the entries not handled yet (an
    input hands no Bottle to the bridge itself while there are any, so that
    none overtakes one queued before it). None stops it."""

    def __init__(self, name):
        threading.Thread.__init__(self, name=name, daemon=True)
        self.queue = queue.SimpleQueue()
        self.lock = threading.Lock()  # guards pending
        self.pending = 0
        self.done = False  # it has ended

    def put(self, entry):
        with self.lock:
            self.pending += 1
        self.queue.put(entry)

    def run(self):
        get = self.queue.get
        try:
            while True:
                entry = get()
                if entry is None:
                    return
                if entry.__class__ is tuple:
                    inp = entry[0]
                    inp._handle(entry[1], entry[2], entry[3], inp.queued - inp.handled - 1)
                else:  # the newest Bottle of an input read newest-only, if no entry before took it
                    inp = entry
                    try:
                        item, now, envelope = inp.newest.popleft()
                    except IndexError:
                        item = None
                    if item is not None:
                        inp._handle(item, now, envelope, 0)
                inp.handled += 1
                with self.lock:
                    self.pending -= 1
        finally:
            self.done = True

    def stop(self):
        self.queue.put(None)


class Input(InputState):
    """One input of a mux read from a YARP port: its own port, read strictly
    (every Bottle, in order; ``Timing.queue`` 1: the newest only), each
    Bottle with the name of the port that sent it, which is YARP's name for
    the connection's remote end (what YARP prints as "Receiving input
    from"), the sender's own, whatever name the connection was asked for: a
    Bottle of any port the input does not accept is refused, never used.

    YARP's thread for each connection reads the Bottle (the port's reader,
    ``_SourceReader``), one connection at a time (the port's callback
    lock), into the input's one Bottle, checks it against the input's
    layout and the name of its sender against the ports the input takes (a
    set), and hands it with its arrival and envelope to the bridge: there,
    when the bridge is idle (its lock free), nothing read before waits for
    it and the message path prints no values (a terminal that stops reading
    would hold the connection), so that a tick's Bottles and its message
    take no other thread; else through the bridge's reading thread (Inbox),
    so that a connection never waits for another thread's message to be
    built or written, and a reader held up falls behind in that queue
    (BACKLOG Bottles of an input), not in the network. No thread ever blocks in a binding call: from YARP
    3.12.1 the bindings' BufferedPortBottle keeps the interpreter lock in
    read(), so a thread blocked there stops every other; ``yarp.Port`` lets
    the lock go in its calls."""

    def __init__(self, bridge, spec, local, timeout):
        self.init_state(bridge, spec, timeout)
        self.local = local
        self.port = yarp.Port()
        self.reader = None
        self.contact = None  # its port's own address, for admin commands
        self.floats = spec.types is None or all(t in _FLOAT_TYPES for t in spec.types)
        self.drop_nan = bridge.spec.on_nan == "drop"
        self.strict = bridge.spec.queue > 1
        # what the connection threads use, one at a time (the callback lock)
        self.bottle = yarp.Bottle()
        self.stamp = yarp.Stamp()
        self.reading = False  # a connection thread is in arrive()
        self.inbox = None     # the bridge's reading thread (Inbox), once open
        self.newest = collections.deque(maxlen=1)  # read newest-only: (item, arrival, envelope)
        self.queued = 0       # put in the inbox
        self.handled = 0      # of those, taken by the inbox's thread
        self.kept = 0         # its YARP threads that keep their thread state
        self.failed = False
        self.checked = None  # (connections, refused) when the watcher last listed them
        # what arrive() hands a Bottle to itself, in the connection's thread (a
        # part of arrive, the cost guard's count of it included)
        self.take = self._handle

    def open(self):
        count = call_count()
        if count is not None:  # the cost guard's count (tests/test_cost.py)
            self.arrive = count.counted(self.arrive)
            self._handle = count.counted(self._handle)
        self.reader = _SourceReader(self)
        self.port.setReader(self.reader)
        # one connection's Bottle at a time in arrive(): the input's Bottle
        # and stamp are read by one thread, and its counters are exact
        self.port.setCallbackLock()
        self.port.setInputMode(True)
        self.port.setOutputMode(False)
        if not self.port.open(self.local):
            return False
        where = self.port.where()
        self.contact = yarp.Contact(self.local, "tcp", where.getHost(), where.getPort())
        if self.bridge.inbox is None:
            self.bridge.inbox = Inbox("inputs of " + self.bridge.prefix)
            self.bridge.inbox.start()
        self.inbox = self.bridge.inbox
        return True

    def arrive(self, connection):
        """In the connection's thread: the Bottle, when it came, where from
        and its envelope stamp; handed to the bridge, or refused if another
        port sent it."""
        try:
            _KEPT.state
        except AttributeError:
            keep_thread_state(self)
        self.reading = True
        self.calls += 1
        try:
            item = self.read_item(connection)
            if item is None:
                return False
            now = time.monotonic()
            source = connection.getRemoteContact().getName()
            bridge = self.bridge
            if bridge.stopping:
                return True
            if source not in self.accepted:
                # the port keeps the envelope of the last message that had one,
                # by whichever connection it came: this one's is not left to
                # the source's next Bottle
                self.port.setEnvelope(_NO_ENVELOPE)
                bridge.on_foreign(self, source)
                if bridge.watcher is not None:
                    bridge.watcher.poke()  # closes the connection now, in its own thread
                return True
            envelope = self.read_envelope()
            inbox = self.inbox
            if bridge.quiet and not inbox.pending and bridge.lock.acquire(False):
                # the bridge idle: handled here, unless the inbox still holds
                # a Bottle read before this one (checked again under the lock:
                # the inbox counts an entry pending until the bridge has it)
                try:
                    if not inbox.pending:
                        self.take(item, now, envelope, 0)
                        return True
                finally:
                    bridge.lock.release()
            self.queued += 1
            if self.strict:
                inbox.put((self, item, now, envelope))
            else:  # the newest only, as YARP reads by default
                self.newest.append((item, now, envelope))
                inbox.put(self)
            return True
        except Exception as e:  # an exception into YARP's thread would abort the process
            self.fail(e)
            return False
        finally:
            self.reading = False

    def read_item(self, connection):
        """What the connection brings, as the input's thread takes it: the
        Bottle's (values, None), or (None, why it is dropped); None if it
        cannot be read."""
        bottle = self.bottle
        if not bottle.read(connection):
            return None
        return parse_bottle(bottle, self.spec.types, False, self.drop_nan, None, self.floats)

    def read_envelope(self):
        """The envelope stamp of what was just read (seconds), or None."""
        stamp = self.stamp
        if self.port.getEnvelope(stamp) and stamp.isValid():
            return stamp.getTime()
        return None

    def fail(self, e):
        if not self.failed:
            self.failed = True
            self.bridge.log("input %s: %s: %s" % (self.source, type(e).__name__, e))

    def _handle(self, item, now, envelope, behind):
        """In the bridge's reading thread: what a connection read, to the
        bridge; ``behind``: the input's Bottles queued after it."""
        if self.bridge.stopping:
            return
        try:
            if behind > BACKLOG:
                # far behind: skipped unread, so that the reader catches up
                self.bridge.on_skipped(self)
                return
            self.bridge.on_bottle(self, item[0], item[1], now, envelope)
        except Exception as e:  # never a traceback out of the input's thread
            self.fail(e)

    def sources(self):
        """The ports connected to its port, by YARP's names for them (its own
        answer to `list in`); None when it does not answer."""
        reply = admin(self.contact, "list", "in")
        if reply is None:
            return None
        names = [reply.get(k).asString() for k in range(reply.size())]
        return [n for n in names if n.startswith("/") and n != self.local]

    def drop(self, name):
        """Closes the connection of port ``name`` to its port (an admin `del`
        to its own port: no name server needed, and ``name`` may be a port
        the name server does not know)."""
        admin(self.contact, "del", name)

    def connections(self):
        return self.port.getInputCount()

    def interrupt(self):
        self.port.interrupt()
        if self.inbox is not None:
            self.inbox.stop()

    def settled(self):
        """No Bottle waits to be handled and none is being read or handled."""
        return not self.reading and (self.inbox is None or self.inbox.done or self.handled == self.queued)

    def close(self):
        self.port.close()
        if self.inbox is not None:
            self.inbox.join(0.2)


class _Reader(yarp.BottleCallback):
    """What YARP calls for each Bottle of a ROS 1 topic input, in YARP's own thread."""

    def __init__(self, inp):
        yarp.BottleCallback.__init__(self)
        self.inp = inp

    def onRead(self, bottle, *reader):
        self.inp.on_read(bottle)


class TopicInput(InputState):
    """One input of a mux read from a ROS 1 topic through YARP (its
    topic@node port), strictly (every Bottle, in order) through a callback
    in YARP's reader thread. Never a blocking read(): from YARP 3.12.1 the
    bindings' BufferedPortBottle keeps the interpreter lock in read(), so a
    thread blocked there stops every other. (Its publishers are ROS nodes:
    the names of YARP's ports do not apply.)"""

    def __init__(self, bridge, spec, local, timeout):
        self.init_state(bridge, spec, timeout)
        self.local = local
        self.port = yarp.BufferedPortBottle()
        self.reader = None
        self.stamp = yarp.Stamp()
        self.busy = False   # inside a callback
        self.kept = 0       # its YARP threads that keep their thread state
        self.failed = False

    def open(self):
        # queue > 1: every Bottle, in order (BACKLOG bounds it); 1: the
        # newest only, as YARP reads by default
        self.port.setStrict(self.bridge.spec.queue > 1)
        self.port.setReadOnly()
        count = call_count()
        if count is not None:  # the cost guard's count (tests/test_cost.py)
            self.on_read = count.counted(self.on_read)
        self.reader = _Reader(self)
        self.port.useCallback(self.reader)
        return self.port.open(self.local)

    def on_read(self, bottle):
        try:
            _KEPT.state
        except AttributeError:
            keep_thread_state(self)
        self.calls += 1
        if self.bridge.stopping:
            return
        self.busy = True
        try:
            now = time.monotonic()
            if self.port.getPendingReads() > BACKLOG:
                self.bridge.on_skipped(self)
                return
            envelope = None
            if self.port.getEnvelope(self.stamp) and self.stamp.isValid():
                envelope = self.stamp.getTime()
            values, reason = parse_bottle(bottle, self.spec.types, True,
                                          self.bridge.spec.on_nan == "drop",
                                          self.spec.positions, False)
            self.bridge.on_bottle(self, values, reason, now, envelope)
        except Exception as e:  # never a traceback out of YARP's thread
            if not self.failed:
                self.failed = True
                self.bridge.log("input %s: %s: %s" % (self.source, type(e).__name__, e))
        finally:
            self.busy = False

    def interrupt(self):
        self.port.interrupt()

    def settled(self):
        """No Bottle waits for the callback and none is being handled."""
        return not self.busy and self.port.getPendingReads() == 0

    def close(self):
        self.port.close()
        # YARP 3.5 leaves a closed topic@node subscriber registered with
        # the ROS master: withdrawn, so that no publisher points at this process
        withdraw_from_ros_master(self.local, publisher=False)


