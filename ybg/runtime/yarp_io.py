"""The YARP side of the Python modules: input Bottles read and checked,
ports opened and watched, the output message tree written as a Bottle on a
YARP port or a ROS 1 topic, and the shutdown within 2 s (docs/runtime.md)."""

import collections
import os
import queue
import signal
import sys
import threading
import time
import xmlrpc.client

import yarp

from .core import _FLOAT_TYPES, _INT_TYPES, BACKLOG, Bridge, InputState  # ybgc:runtime-import
from .core import DEFAULT_CONFIG_FILE, Array, Msg, RateMeter, Rows, Scalar, Splice, parse_options  # ybgc:runtime-import
from .core import call_count, truthy  # ybgc:runtime-import

# --- reading and checking input Bottles --------------------------------------

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


def _leaves(bottle, out):
    """The Bottle's elements, nested lists flattened depth-first (ROS topics)."""
    for k in range(bottle.size()):
        value = bottle.get(k)
        if value.isList():
            _leaves(value.asList(), out)
        else:
            out.append(value)
    return out


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
    """The thread that hands to a bridge what its YARP port inputs read, in
    the order they read it: one for all the inputs of a bridge, so that the
    Bottles of one tick, which come one after the other, wake one thread
    (or none, when it is still busy with the one before), not a thread
    each. The inputs' connection threads put (input, what it read, arrival,
    envelope) in its queue, the interpreter's own (``queue.SimpleQueue``: a
    put, and a get that waits with the interpreter lock let go), or, for an
    input read newest-only (``Timing.queue`` 1), the input alone, its newest
    Bottle kept by the input. None stops it."""

    def __init__(self, name):
        threading.Thread.__init__(self, name=name, daemon=True)
        self.queue = queue.SimpleQueue()
        self.done = False  # it has ended

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
                        inp.handled += 1
                        continue
                    inp._handle(item, now, envelope, 0)
                inp.handled += 1
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
    set), and queues what it read with its arrival and envelope for the
    bridge's reading thread (Inbox), which hands it to the bridge: a
    connection waits for no more than the read, never for a message to be
    built or written, and a reader held up falls behind in the queue
    (BACKLOG Bottles of an input), not in the network. No thread ever blocks
    in a binding call: from YARP 3.12.1 the bindings' BufferedPortBottle
    keeps the interpreter lock in read(), so a thread blocked there stops
    every other; ``yarp.Port`` lets the lock go in its calls."""

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
        self.failed = False
        self.checked = None  # (connections, refused) when the watcher last listed them

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
        and its envelope stamp; queued, or refused if another port sent it."""
        self.reading = True
        self.calls += 1
        try:
            item = self.read_item(connection)
            if item is None:
                return False
            now = time.monotonic()
            source = connection.getRemoteContact().getName()
            if self.bridge.stopping:
                return True
            if source not in self.accepted:
                # the port keeps the envelope of the last message that had one,
                # by whichever connection it came: this one's is not left to
                # the source's next Bottle
                self.port.setEnvelope(_NO_ENVELOPE)
                self.bridge.on_foreign(self, source)
                if self.bridge.watcher is not None:
                    self.bridge.watcher.poke()  # closes the connection now, in its own thread
                return True
            self.queued += 1
            if self.strict:
                self.inbox.queue.put((self, item, now, self.read_envelope()))
            else:  # the newest only, as YARP reads by default
                self.newest.append((item, now, self.read_envelope()))
                self.inbox.queue.put(self)
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
        reply = _admin(self.contact, "list", "in")
        if reply is None:
            return None
        names = [reply.get(k).asString() for k in range(reply.size())]
        return [n for n in names if n.startswith("/") and n != self.local]

    def drop(self, name):
        """Closes the connection of port ``name`` to its port (an admin `del`
        to its own port: no name server needed, and ``name`` may be a port
        the name server does not know)."""
        _admin(self.contact, "del", name)

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


# --- connections ---------------------------------------------------------------

def _admin(contact, *words):
    """The reply of the port at ``contact`` to an admin command (its words),
    or None when it does not answer."""
    style = yarp.ContactStyle()
    style.admin = True
    style.quiet = True
    style.timeout = 1.0
    cmd = yarp.Bottle()
    for word in words:
        cmd.addString(word)
    reply = yarp.Bottle()
    if not yarp.Network.write(contact, cmd, reply, style):
        return None
    return reply


def _answers_as(contact, name):
    """Does the port at ``contact`` answer as the port ``name`` (an admin
    `prop get`, which a port answers with its process only for its own name)?"""
    reply = _admin(contact, "prop", "get", name)
    return reply is not None and reply.check("process")


class Watcher(threading.Thread):
    """Every 0.5 s, connects each (source, destination, input) link whose
    source exists and is not connected, so that a source that starts late or
    is restarted is picked up. ``input``, when given, is the module's input
    whose port is the destination: its connections are listed (asked of the
    port itself) only when their number changed or one of its Bottles was
    refused; one from a port the input does not accept is closed (said
    once); the network is asked only about a missing link, besides one query
    a period about the module's first port (``_register_again``). What YARP
    connected is the port that answered at the address the name server gave:
    it is said by its own name, and when it is another port its Bottles are
    refused and its connection closed; that address is then connected again
    only once the port there answers as the source. A destination restarted
    under the same name is reconnected too: the old connection stays listed
    until a write fails on it, which for a module that writes only on new
    data (a command) would lose the next command; the destination, asked for
    its inputs, tells. The main loop never waits for it."""

    PERIOD = 0.5

    def __init__(self, pairs, log, own=()):
        threading.Thread.__init__(self, name="connection watcher", daemon=True)
        self.pairs = list(pairs)
        self.log = log
        self.own = list(own)  # the module's own ports, kept registered
        self.done = threading.Event()
        self.poked = threading.Event()
        self.connected = {}
        self.made = set()  # the (source, destination) links this watcher connected
        self.blocked = {}  # (source, destination) -> where another port answered to the source's name

    def poke(self):
        """Wakes it at once (an input refused a Bottle: its connection is closed now)."""
        self.poked.set()

    def run(self):
        while not self.done.is_set():
            self.poked.clear()
            self._register_again()
            for src, dst, inp in self.pairs:
                if self.done.is_set():
                    break
                if inp is not None:
                    self._check_input(inp)
                else:
                    self._check(src, dst)
            self.poked.wait(self.PERIOD)

    def _check_input(self, inp):
        key = (inp.source, inp.local)
        state = (inp.connections(), inp.refused)
        if state == inp.checked and state[0] > 0 and self.connected.get(key):
            return  # as when they were listed: a port it accepts
        sources = inp.sources() if state[0] > 0 else []
        if sources is None:
            return
        up = False
        refused = False
        for name in sources:
            if name in inp.accepted:
                up = True
            else:
                inp.bridge.on_foreign(inp, name, bottle=False)
                inp.drop(name)
                refused = True
        inp.checked = None if refused else state
        if up:
            self.connected[key] = True
            return
        src, dst = key
        where = yarp.Network.queryName(src)
        blocked = self.blocked.get(key)
        if where.isValid() and blocked == (where.getHost(), where.getPort()) and not _answers_as(where, src):
            return  # the name still gives the address of the other port (said when it was connected)
        if where.isValid() and yarp.Network.exists(src, True) and yarp.Network.connect(src, dst, "", True):
            # the port YARP connected, by its own name: the one at the address
            # the name server gave, which may be another port's
            after = inp.sources() or []
            real = next((n for n in after if n in inp.accepted), after[0] if after else src)
            inp.checked = None
            if real in inp.accepted:
                self.log("connected %s -> %s" % (real, dst))
                self.connected[key] = True
                self.made.add(key)
                self.blocked.pop(key, None)
            else:
                # its Bottles are refused as they come; its connection is closed next
                self.log("connected %s -> %s (asked for %s)" % (real, dst, src))
                inp.bridge.on_foreign(inp, real, bottle=False)
                self.blocked[key] = (where.getHost(), where.getPort())
                self.connected[key] = False
        elif self.connected.get(key):
            self.log("lost %s -> %s; reconnecting when it is back" % (src, dst))
            self.connected[key] = False

    def _check(self, src, dst):
        """The output's link to a port it connects to."""
        if yarp.Network.exists(dst, True) and yarp.Network.isConnected(src, dst, True):
            if (src, dst) not in self.made or _lists_input(dst, src) is not False:
                self.connected[(src, dst)] = True
                return
            # the destination was restarted: the connection listed is to its predecessor
            yarp.Network.disconnect(src, dst, True)
        if yarp.Network.exists(src, True) and yarp.Network.exists(dst, True) \
                and yarp.Network.connect(src, dst, "", True):
            self.log("connected %s -> %s" % (src, dst))
            self.connected[(src, dst)] = True
            self.made.add((src, dst))
        elif self.connected.get((src, dst)):
            self.log("lost %s -> %s; reconnecting when it is back" % (src, dst))
            self.connected[(src, dst)] = False

    def _register_again(self):
        """A name server restarted has forgotten every port: the module's
        own ports are registered again (asked about the first one only), so
        that a source started since is connected to them and a consumer
        finds the output. Connections made before never needed it."""
        if not self.own or yarp.Network.queryName(self.own[0].getName()).isValid():
            return
        if all(yarp.Network.registerContact(port.where()).isValid() for port in self.own):
            self.log("the name server had forgotten this module's ports: registered them again")

    def stop(self, timeout=1.0):
        self.done.set()
        self.poked.set()
        if self.is_alive():
            self.join(timeout)
        return not self.is_alive()


def _lists_input(port, source):
    """Does ``port`` list a connection from ``source`` among its inputs (its
    admin answer to `list in`)? None when it does not answer."""
    reply = _admin(yarp.Contact(port), "list", "in")
    if reply is None:
        return None
    return any(reply.get(k).asString() == source for k in range(reply.size()))


def ros1_problem():
    """None when this YARP carries ROS 1 topics, else why it cannot. It needs
    a name server started with `--ros` (its ROS master contact, /ros) reached
    through the xmlrpc carrier: built in up to YARP 3.9, YARP's separate
    yarp-ros plugins in 3.10 to 3.12, gone in YARP 4. Without them a ROS 1
    port opens as a plain YARP port, and the module would publish into nothing."""
    version = yarp.YARP_VERSION
    if yarp.YARP_VERSION_MAJOR >= 4:
        return ("YARP %s has no ROS 1 support (removed in YARP 4.0): set `via = ros2` in the "
                "config and generate the ROS 2 node (ybgc CONFIG --backend ros2)" % version)
    master = yarp.Network.queryName("/ros")
    if not master.isValid():
        return ("the YARP name server does not speak ROS: start it as `yarpserver --ros` with "
                "ROS_MASTER_URI set (YARP 3.10 and later: with YARP's yarp-ros plugins)")
    style = yarp.ContactStyle()
    style.quiet = True
    style.timeout = 2.0
    style.carrier = "xmlrpc"
    cmd = yarp.Bottle()
    cmd.addString("getPid")
    cmd.addString("/ybgc")
    if not yarp.Network.write(master, cmd, yarp.Bottle(), style):
        return ("YARP %s cannot reach the ROS master through its xmlrpc carrier (YARP 3.10 and "
                "later need YARP's yarp-ros plugins)" % version)
    return None


class YarpBridge(Bridge):
    """The bridge on YARP: its inputs are YARP ports (or ROS 1 topics
    through YARP); it opens them, watches the connections and closes them;
    its RPC port answers `help`, `stats` and `quit`."""

    rpc = None
    inbox = None  # the thread its YARP port inputs hand what they read to (Inbox)

    def make_input(self, mux, spec, local, timeout):
        return TopicInput(self, spec, local, timeout) if spec.kind == "ros1" else Input(self, spec, local, timeout)

    def run(self):
        """Open everything, loop until SIGINT/SIGTERM, close; the exit status."""
        yarp.Network.init()
        signal.signal(signal.SIGINT, self.request_stop)
        signal.signal(signal.SIGTERM, self.request_stop)
        if not yarp.Network.checkNetwork(3.0):
            self.log("cannot reach the YARP name server (is yarpserver running?)")
            return 1
        if getattr(self.output, "kind", None) == "ros1" or any(i.spec.kind == "ros1" for i in self.inputs):
            problem = ros1_problem()
            if problem is not None:
                self.log("cannot use ROS 1 topics: " + problem)
                return 1
        opened = []
        self.status = 1
        try:
            problem = self.open_all(opened)
            if problem is not None:
                self.log(problem)
                return 1
            self.loop()
            self.status = 0
            return 0
        finally:
            # under the lock: a message being published by an input thread is
            # finished, and none starts after this, before the ports close
            with self.cond:
                self.stopping = True
            self._shut_down(opened)

    def open_all(self, opened, rpc=True):
        """Open the inputs (each added to ``opened``), the output and (``rpc``)
        the RPC port, start the watcher of connections: None, or what could
        not open. (A process of several bridges opens one RPC port of its
        own, not each bridge's: ybgc_runtime.compose.)"""
        for inp in self.inputs:
            if not inp.open():
                return "cannot open the port %s" % inp.local
            opened.append(inp)
        if not self.output.open():
            return "cannot open the output %s" % self.output.port_name
        if rpc:
            self.rpc = RpcPort(self, self.prefix + "/rpc:i")
            if not self.rpc.open():
                return "cannot open the RPC port %s" % self.rpc.name
        pairs = [(i.source, i.local, i) for i in self.inputs if i.spec.kind == "yarp"]
        pairs.extend((src, dst, None) for src, dst in self.output.connections())
        own = [i.port for i in self.inputs if i.spec.kind == "yarp"]
        if getattr(self.output, "kind", None) == "yarp":
            own.append(self.output.port)
        self.watcher = Watcher(pairs, self.log, own)
        self.watcher.start()
        self.log("publishing %s on %s" % (self.output.describe(),
                                          "event-driven" if self.rate is None
                                          else "%g Hz" % self.rate))
        return None

    def loop(self):
        """Publish until stopped: event-driven or at the fixed rate."""
        if self.rate is None:
            self._loop_event_driven()
        else:
            self._loop_fixed_rate()

    def _shut_down(self, opened):
        """Close every port (which unregisters it) within the 2 s budget: a
        port whose reader stalls can hang in close(); it is then unregistered
        by name and the process exits at once."""
        watcher_done, stuck, unclosed = self.close_ports(opened)
        self._print_totals()
        if stuck:
            self.unregister(unclosed)
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(self.status)
        if watcher_done:
            yarp.Network.fini()

    def unregister(self, names):
        """The ports that did not close in time, unregistered by name (said)."""
        for name in names:
            self.log("%s did not close in time (a stalled reader?); unregistering it" % name)
            yarp.Network.unregisterName(name)

    def close_ports(self, opened):
        """Stop the watcher and close the ports within 1 s: (the watcher
        stopped, a port did not close in time, the names of those not
        closed)."""
        watcher_done = self.watcher.stop() if self.watcher is not None else True
        names = [inp.local for inp in opened] + [self.output.port_name]
        closed = []
        if self.rpc is not None:
            names.append(self.rpc.name)

        def close_all():
            if self.rpc is not None:
                self.rpc.close()
                closed.append(self.rpc.name)
            # interrupted first, so that no new Bottle comes in; closed once
            # YARP's reader threads have handed every Bottle they hold to the
            # callbacks (which return at once now): YARP 3.12's bindings keep
            # the interpreter lock in close(), which waits for those threads
            for inp in opened:
                inp.interrupt()
            end = time.monotonic() + 0.5
            while time.monotonic() < end and not all(inp.settled() for inp in opened):
                time.sleep(0.005)
            calls = [inp.calls for inp in opened]
            time.sleep(0.02)  # and none started since: a callback waiting for the lock shows here
            while time.monotonic() < end and [inp.calls for inp in opened] != calls:
                calls = [inp.calls for inp in opened]
                time.sleep(0.02)
            for inp in opened:
                inp.close()
                closed.append(inp.local)
            if not self.output.stalled():  # else unregistered by name below
                self.output.close()
                closed.append(self.output.port_name)

        closer = threading.Thread(target=close_all, name="close ports", daemon=True)
        closer.start()
        closer.join(1.0)
        stuck = closer.is_alive() or len(closed) < len(names)
        return watcher_done, stuck, [name for name in names if name not in closed] if stuck else []


# ===========================================================================
# Output side: the message tree as a Bottle on a YARP port (or on a ROS 1
# topic through YARP's topic@node ports).
# ===========================================================================

def _signed(x, bits):
    """``x`` as the two's complement integer of ``bits`` bits (a uint32
    above 2**31 on an int32 wire keeps its bits, as in C++)."""
    half = 1 << (bits - 1)
    return ((int(x) + half) % (half << 1)) - half


def _add_number(bottle, x):
    """An undeclared port's element, as it came: an integer as int32 (int64
    beyond its range), anything else as float64."""
    if isinstance(x, int) and not isinstance(x, bool):
        if -2**31 <= x < 2**31:
            bottle.addInt32(x)
        else:
            bottle.addInt64(_signed(x, 64))
    else:
        bottle.addFloat64(float(x))


_ADD = {
    "float64": lambda b, x: b.addFloat64(float(x)),
    "float32": lambda b, x: b.addFloat32(float(x)),
    "int64": lambda b, x: b.addInt64(_signed(x, 64)),
    "int32": lambda b, x: b.addInt32(_signed(x, 32)),
    "int16": lambda b, x: b.addInt16(_signed(x, 16)),
    "int8": lambda b, x: b.addInt8(_signed(x, 8)),
    "string": lambda b, x: b.addString(str(x)),
    "number": _add_number,
}


def _add_values(bottle, types, values, wire):
    if isinstance(types, tuple):
        for t, x in zip(types, values):
            _ADD[wire[t]](bottle, x)
    elif wire[types] == "float64":
        # the binding's method itself, one call a value (it takes an int or
        # a float as float() does)
        add = bottle.addFloat64
        for x in values:
            add(x)
    else:
        add = _ADD[wire[types]]
        for x in values:
            add(bottle, x)


def is_message_type(type_):
    """Is an Array's ``type`` a message type ("pkg/Name"), its values messages?"""
    return isinstance(type_, str) and "/" in type_


def add_node(bottle, node, wire):
    """Append ``node`` to ``bottle`` with YARP's ROS 1 wire mapping: a
    message is a nested list of its fields, a time is (sec nsec), an array
    of messages a list of such lists."""
    if isinstance(node, Scalar):
        _ADD[wire[node.type]](bottle, node.value)
    elif isinstance(node, Rows):
        target = bottle.addList() if node.nested else bottle
        for row in node.values:
            _add_values(target.addList(), node.type, row, wire)
    elif isinstance(node, Splice):
        _add_values(bottle, node.type, node.values, wire)
    elif isinstance(node, Array) and is_message_type(node.type):
        inner = bottle.addList()
        for child in node.values:
            add_node(inner, child, wire)
    elif isinstance(node, Array):
        _add_values(bottle.addList(), node.type, node.values, wire)
    elif isinstance(node, Msg):
        inner = bottle.addList()
        for _name, child in node.fields:
            add_node(inner, child, wire)
    else:
        raise TypeError("not a message node: %r" % (node,))


def fill_bottle(bottle, message, wire):
    """The top-level message's fields are the items of the Bottle."""
    bottle.clear()
    for _name, child in message.fields:
        add_node(bottle, child, wire)
    return bottle


class YarpOutput:
    """Writes each message on a BufferedPortBottle, never waiting for a
    slow reader: a reader that lags misses messages, counted (``missed``)."""

    def __init__(self, kind, port_name, connect_to, msg_type, wire):
        self.kind = kind
        self.port_name = port_name
        self.connect_to = connect_to
        self.msg_type = msg_type
        self.wire = wire
        self.port = yarp.BufferedPortBottle()
        self.patient = True
        self.missed = 0

    def open(self):
        self.port.setWriteOnly()
        return self.port.open(self.port_name)

    def connections(self):
        return [(self.port_name, self.connect_to)] if self.connect_to else []

    def describe(self):
        what = self.msg_type or "untyped Bottles"
        return "%s on %s" % (what, self.port_name)

    #: how long a message waits for the previous one to be sent
    PATIENCE = 0.05

    def publish(self, message):
        # A message written while the previous one is still being sent is
        # dropped for the connections that are still busy; so wait for it a
        # little, unless a reader has already shown it stalls. Written while
        # still busy, it is counted as missed (a port found idle stays so
        # until this write).
        busy = self.port.isWriting()
        if busy:
            if self.patient:
                deadline = time.monotonic() + self.PATIENCE
                while self.port.isWriting() and time.monotonic() < deadline:
                    time.sleep(0.0002)
                self.patient = not self.port.isWriting()
        else:
            self.patient = True
        fill_bottle(self.port.prepare(), message, self.wire)
        if busy and self.port.isWriting():
            self.missed += 1
        self.port.write()

    def stalled(self, grace=0.2):
        """A reader still takes a message after ``grace`` seconds. close()
        would then wait for it up to YARP's own limit (5 s), and from YARP
        3.12.1 the bindings keep the interpreter lock all that time."""
        deadline = time.monotonic() + grace
        while self.port.isWriting():
            if time.monotonic() >= deadline:
                return True
            time.sleep(0.002)
        return False

    def close(self):
        self.port.interrupt()
        self.port.close()
        if self.kind == "ros1":
            # YARP 3.5 leaves a closed topic@node publisher registered with the
            # ROS master: withdrawn, so that nothing points at this process
            withdraw_from_ros_master(self.port_name, publisher=True)


def withdraw_from_ros_master(port_name, publisher):
    """The topic@node port ``port_name`` withdrawn from the ROS master, as a
    publisher or a subscriber of its topic (short timeouts; nothing if the
    master does not answer)."""
    topic, _, node = port_name.partition("@")
    contact = yarp.Network.queryName("/ros")
    if not contact.isValid():
        return
    master = xmlrpc.client.ServerProxy("http://%s:%d/" % (contact.getHost(), contact.getPort()),
                                       transport=_QuickTransport())
    try:
        code, _msg, api = master.lookupNode(node, node)
        if code == 1:
            if publisher:
                master.unregisterPublisher(node, topic, api)
            else:
                master.unregisterSubscriber(node, topic, api)
    except (OSError, xmlrpc.client.Error, ValueError):
        pass


class _QuickTransport(xmlrpc.client.Transport):
    """XML-RPC to the ROS master with a short timeout (shutdown has 2 s)."""

    def make_connection(self, host):
        connection = xmlrpc.client.Transport.make_connection(self, host)
        connection.timeout = 0.4
        return connection


# --- the RPC port and the ResourceFinder (YARP modules' conventions) -------------------

#: what `help` answers on the RPC port, one line a command
RPC_HELP = (
    "help: this list",
    "stats: the totals so far: per input (input SOURCE received N dropped N stale N unused N refused N), "
    "(published N skipped N failures N missed N), (rate ACHIEVED configured HZ|event-driven), and per ROS 2 publisher "
    "and subscription (ros2 publisher|subscription TOPIC incompatible_qos N incompatible_type N)",
    "quit: stop the module (it closes its ports and exits 0, as on SIGINT)",
)


def rpc_respond(command, reply, bridge, meter):
    """``reply`` to an RPC ``command`` (Bottles): `help`, `stats`, `quit`
    (also `exit`, `bye`: the RFModule convention). False for an unknown one."""
    word = command.get(0).toString() if command.size() > 0 else ""
    if word == "help":
        reply.addVocab32("many")
        for line in RPC_HELP:
            reply.addString(line)
    elif word == "stats":
        reply.addVocab32("many")
        stats_items(reply, bridge, meter)
    elif word in ("quit", "exit", "bye"):
        bridge.log("asked to quit on the RPC port")
        bridge.quit_asked = True
        bridge.request_stop()
        reply.addVocab32("bye")
    else:
        reply.addString("unknown command %r; the commands: help, stats, quit" % word)
        return False
    return True


def stats_items(reply, bridge, meter):
    """What `stats` answers of ``bridge``, appended to ``reply`` (after its
    vocab ``many``): one list per input, the messages, the rate."""
    inputs, published, skipped, failures, missed = bridge.totals()
    for source, received, dropped, stale, unused, refused in inputs:
        item = reply.addList()
        item.addString("input")
        item.addString(source)
        for key, n in (("received", received), ("dropped", dropped), ("stale", stale), ("unused", unused),
                       ("refused", refused)):
            item.addString(key)
            item.addInt64(n)
    item = reply.addList()
    for key, n in (("published", published), ("skipped", skipped), ("failures", failures), ("missed", missed)):
        item.addString(key)
        item.addInt64(n)
    # the rates as text, with the digits that mean something (a float64
    # prints with 21 digits)
    item = reply.addList()
    item.addString("rate")
    item.addString("%.2f" % meter.read(time.monotonic(), published))
    item.addString("configured")
    item.addString("event-driven" if bridge.rate is None else repr(float(bridge.rate)))
    # the incompatible peers of its ROS 2 publishers and subscriptions (the ros2 node)
    for kind, topic, qos, type_ in bridge.ros2_events():
        item = reply.addList()
        for word in ("ros2", kind, topic):
            item.addString(word)
        for key, n in (("incompatible_qos", qos), ("incompatible_type", type_)):
            item.addString(key)
            item.addInt64(n)


class RpcPort(yarp.PortReader):
    """The module's RPC port ``<prefix>/rpc:i``, as YARP modules have one
    (`yarp rpc /<module>/rpc:i`): each command is answered in YARP's own
    thread for the port, reading the totals under the bridge's lock; the
    loop and the inputs never wait for it."""

    def __init__(self, bridge, name):
        yarp.PortReader.__init__(self)
        self.bridge = bridge
        self.name = name
        self.meter = RateMeter(time.monotonic())
        self.port = yarp.RpcServer()
        self.busy = False

    def open(self):
        self.port.setReader(self)
        return self.port.open(self.name)

    def respond(self, command, reply):
        """``reply`` to ``command``: the module's own commands."""
        rpc_respond(command, reply, self.bridge, self.meter)

    def read(self, connection):
        self.busy = True
        try:
            command = yarp.Bottle()
            if self.bridge.stopping or not command.read(connection):
                return False
            reply = yarp.Bottle()
            self.respond(command, reply)
            writer = connection.getWriter()
            if writer is not None:
                reply.write(writer)
            return True
        except Exception as e:  # never a traceback out of YARP's thread
            self.bridge.log("RPC port: %s: %s" % (type(e).__name__, e))
            return False
        finally:
            self.busy = False

    def close(self):
        """Interrupted, then closed once no command is being answered (a
        binding call keeps the interpreter lock: closing while YARP's thread
        waits for it to answer would deadlock)."""
        end = time.monotonic() + 0.3
        if self.bridge.quit_asked:
            # its `bye` is sent once read() has returned: not dropped by a
            # port closed at once (the caller would not know it was heard)
            end = time.monotonic() + 0.5
            while self.busy and time.monotonic() < end:
                time.sleep(0.005)
            time.sleep(0.05)
        self.port.interrupt()
        while self.busy and time.monotonic() < end:
            time.sleep(0.005)
        self.port.close()


def read_config_file(spec, path, context):
    """The options in the YARP config file ``--from path`` / ``--context
    context`` (alone: its DEFAULT_CONFIG_FILE), found by YARP's
    ResourceFinder as every YARP module finds its own, as command-line
    arguments; ValueError when there is no such file."""
    finder = yarp.ResourceFinder()
    finder.setQuiet(True)
    finder.setDefaultConfigFile(DEFAULT_CONFIG_FILE)
    args = [spec.module]
    if context:
        args += ["--context", context]
    if path:
        args += ["--from", path]
    found = finder.findFile("from") if finder.configure(args) else ""
    if not found:
        raise ValueError("YARP's ResourceFinder finds no config file %s%s" % (
            path or DEFAULT_CONFIG_FILE, " in the context " + context if context else ""))
    out = []
    for key in ("name", "prefix", "rate", "timeout"):
        if finder.check(key):
            out += ["--" + key, finder.find(key).toString()]
    if finder.check("verbose"):
        flag = truthy(finder.find("verbose").toString())
        if flag is None:
            raise ValueError("%s: verbose must be true or false" % found)
        if flag:
            out.append("--verbose")
    return out


def run(spec, argv, default_prefix, make_output, build, compute):
    """Parse the command line, run the bridge until SIGINT/SIGTERM."""
    options = parse_options(spec, argv, default_prefix,
                            lambda path, context: read_config_file(spec, path, context))
    bridge = YarpBridge(spec, options, make_output(), build, compute)
    return bridge.run()
