"""The logic of every Python module ybgc generates, with no middleware:
the bridge's description (the spec tables a module fills in), the message
tree its builder returns, what is kept of each input (queue, freshness), the
matching of Bottles into messages, the converters, the timing of the loops,
the totals (docs/runtime.md). ``yarp_io`` and ``ros2_io`` add the ports."""

import argparse
import collections
import math
import os
import sys
import threading
import time

from .base import _INT_BITS, ConverterSpec, call_count, say, scale_range  # ybgc:runtime-import
from .geometry import GEOMETRY, GEOMETRY_WIDTHS  # ybgc:runtime-import

#: ``accepts``: the other ports whose Bottles a YARP port input takes too;
#: ``image``: a camera image input (images.py): the ROS encoding of a YARP
#: port's frames, or "any" for a ROS 2 topic of sensor_msgs/Image
InputSpec = collections.namedtuple("InputSpec", "mux index source kind types timeout positions reads accepts image",
                                   defaults=(None, None, (), None))
#: a geometry converter (geometry.py) on the elements [start, start + its width)
GeometrySpec = collections.namedtuple("GeometrySpec", "name function args start")
#: an element-wise expression: each number x of [start, stop) becomes function(x)
EachSpec = collections.namedtuple("EachSpec", "name function start stop")
#: rows: the mux holds one row (a list of values) per element of an array of
#: messages read from ROS 2, each row converted alike
MuxSpec = collections.namedtuple("MuxSpec", "name inputs converters verbose types rows", defaults=(False,))
BridgeSpec = collections.namedtuple(
    "BridgeSpec", "module config description muxes needed rate trigger queue on_stale on_nan publish",
    defaults=("always",))


# --- the message tree --------------------------------------------------------
# build_message() returns a tree of these; the output side turns it into a
# Bottle (YARP, ROS 1) or fills a typed message (ROS 2).

class Msg:
    """A (nested) message: its fields in order, as (name, node) pairs.
    ``type`` is "pkg/Name", "time", or None for an untyped Bottle."""

    __slots__ = ("type", "fields")

    def __init__(self, type_, fields):
        self.type = type_
        self.fields = fields

    def __repr__(self):
        return "Msg(%r, %r)" % (self.type, self.fields)


class Scalar:
    """One value of element type ``type`` ("float64", "uint32", "string" ...)."""

    __slots__ = ("type", "value")

    def __init__(self, type_, value):
        self.type = type_
        self.value = value

    def __repr__(self):
        return "Scalar(%r, %r)" % (self.type, self.value)


class Array:
    """A list of values: ``type`` is one element type, or a tuple of one
    element type per value; or an array of messages: ``type`` is the
    message type ("pkg/Name") and each value a Msg."""

    __slots__ = ("type", "values")

    def __init__(self, type_, values):
        self.type = type_
        self.values = values

    def __repr__(self):
        return "%s(%r, %r)" % (type(self).__name__, self.type, self.values)


class Splice(Array):
    """Values appended one by one into the enclosing list (untyped Bottles)."""

    __slots__ = ()


class Rows(Array):
    """The rows of a mux read from an array of messages (``values`` a list
    of rows), each a nested list: appended one by one into the enclosing
    list, or with ``nested`` inside one list of their own (untyped Bottles)."""

    __slots__ = ("nested",)

    def __init__(self, type_, values, nested=False):
        Array.__init__(self, type_, values)
        self.nested = nested


def seconds_to_ns(t):
    """A time of ``t`` seconds as integer nanoseconds, to the nanosecond: the
    whole seconds apart from the fraction (``t * 1e9`` alone is a double of
    today's epoch, whose step is 256 ns); None for NaN or an infinity."""
    if not math.isfinite(t):
        return None
    sec = math.floor(t)
    return sec * 1000000000 + round((t - sec) * 1e9)


def time_msg(ns, style):
    """A time of ``ns`` nanoseconds since the epoch: ROS 1 (secs nsecs) or
    ROS 2 builtin_interfaces/Time (sec nanosec)."""
    sec, nsec = divmod(int(ns), 1000000000)
    if style == "ros2":
        return Msg("builtin_interfaces/Time",
                   (("sec", Scalar("int32", sec)), ("nanosec", Scalar("uint32", nsec))))
    return Msg("time", (("secs", Scalar("uint32", sec)), ("nsecs", Scalar("uint32", nsec))))



#: the YARP config file read from a ResourceFinder context given alone (--context CTX)
DEFAULT_CONFIG_FILE = "config.ini"


#: unread Bottles a port may hold before the oldest are skipped unread (a
#: reader that fell this far behind catches up instead of lagging)
BACKLOG = 64


class InputState:
    """What the bridge keeps of one input, guarded by the bridge's lock: the
    accepted Bottles no message used yet (``queue``, oldest first, each
    ``(values, arrival, envelope)``), the values messages use (``values``,
    ``envelope``; ``values`` None before the first), the arrival of the
    newest accepted Bottle, and the totals. ``accepted``: the ports whose
    Bottles it takes (its source, and those the config or the command line
    accept); ``refused`` counts the Bottles of any other port, ``foreign``
    names those ports, in the order they came; it counts too the camera
    frames refused for what they are (``unfit`` of them, the first for
    ``unfit_reason``: a pixel type or an encoding the input does not take)."""

    def init_state(self, bridge, spec, timeout):
        self.bridge = bridge
        self.spec = spec
        self.source = spec.source
        self.accepted = frozenset((spec.source,) + tuple(spec.accepts or ()))
        self.refused = 0
        self.foreign = []
        self.unfit = 0
        self.unfit_reason = None
        self.timeout = timeout
        self.queue = collections.deque()
        self.values = None
        self.envelope = None
        self.arrival = None
        self.received = 0
        self.dropped = 0
        self.unused = 0
        self.stale_periods = 0
        self.state = "waiting"
        self.reported_waiting = False
        self.reported_drop = False
        self.reported_cut = False
        self.calls = 0  # deliveries begun (closing waits until they settle)

    def settled(self):
        """Nothing waits to be delivered and nothing is being delivered."""
        return True



# --- the bridge ------------------------------------------------------------------

class Context:
    """What build_message() sees: converted mux values, counter, clocks."""

    def __init__(self, values, counter, envelopes, now_ns=None):
        self.values = values
        self.counter = counter
        self._envelopes = envelopes
        # the time of this message: the wall clock, or a ROS 2 node's clock
        # (simulated with use_sim_time) when the node gives it
        self._ns = time.time_ns() if now_ns is None else now_ns
        self.seconds = self._ns / 1e9

    def count(self, type_):
        """The message counter, wrapped like an integer of ROS type ``type_``."""
        bits = _INT_BITS.get(type_)
        if bits is None:
            return self.counter
        if type_.startswith("uint") or type_ == "char":
            return self.counter % (1 << bits)
        half = 1 << (bits - 1)
        return ((self.counter + half) % (half << 1)) - half

    def wall_time(self, style):
        return time_msg(self._ns, style)

    def envelope_time(self, mux, style):
        """The newest envelope stamp of ``mux``'s inputs (wall clock if none has one)."""
        t = self._envelopes.get(mux)
        ns = None if t is None else seconds_to_ns(t)
        return time_msg(self._ns if ns is None else ns, style)


class Bridge:
    """The module's loop: gathers inputs into muxes, converts, builds and
    publishes messages, event-driven or at a fixed rate."""

    def __init__(self, spec, options, output, build, compute):
        self.spec = spec
        self.endpoints = []  # EndpointEvents of the ROS 2 publishers and subscriptions (ros2_io.py)
        self.output = output
        self.build = build
        self.compute = compute
        self.prefix = options.prefix
        self.rate = spec.rate if options.rate is None else (options.rate or None)
        self.timeout = options.timeout
        self.verbose = options.verbose
        # no value is printed on the message path (--verbose, a mux's verbose:
        # a terminal that stops reading would hold the thread that prints)
        self.quiet = not self.verbose and not any(m.verbose for m in spec.muxes)
        # the bridge's lock; ``lock`` and ``cond`` are the same lock (``with
        # self.lock`` takes it in C, ``with self.cond`` through Python calls)
        self.lock = threading.RLock()
        self.cond = threading.Condition(self.lock)
        self.stopping = False
        self.quit_asked = False  # `quit` on the RPC port: the port closes once its reply is sent
        self.publishing = False  # event-driven, once the output is open
        self.published = 0
        self.skipped_cycles = 0
        self.build_errors = 0
        self.inputs = []
        self.mux_inputs = {}
        for mux in spec.muxes:
            group = []
            for i in mux.inputs:
                if i.kind == "ros1":
                    local = "%s@%s/%s_in%d" % (i.source, self.prefix, mux.name, i.index)
                else:
                    local = "%s/%s/in%d:i" % (self.prefix, mux.name, i.index)
                timeout = i.timeout if self.timeout is None else self.timeout
                inp = self.make_input(mux, i, local, timeout)
                if i.kind == "yarp":
                    inp.accepted |= frozenset(getattr(options, "accept", {}).get(i.source, ()))
                group.append(inp)
            self.mux_inputs[mux.name] = group
            self.inputs.extend(group)
        needed = [i for name in spec.needed for i in self.mux_inputs[name]]
        self.needed = needed if needed else list(self.inputs)
        # the inputs each message takes the newest Bottle of: all at a fixed
        # rate, those not needed when event-driven
        self.sampled = [i for i in self.inputs if self.rate is not None or i not in self.needed]
        self.watcher = None
        count = call_count()
        if count is not None:  # the cost guard's count (tests/test_cost.py): a cycle at a fixed rate
            self._publish = count.counted(self._publish)

    def make_input(self, mux, spec, local, timeout):
        """The object that reads one input: a subclass opens ports."""
        raise NotImplementedError

    # -- messages to the user
    def log(self, text):
        say(self.spec.module, text)

    # -- called by the input threads
    def on_bottle(self, inp, values, reason, now, envelope):
        with self.lock:
            inp.received += 1
            if reason is not None:
                inp.dropped += 1
                if not inp.reported_drop:
                    inp.reported_drop = True
                    self.log("input %s: dropped a Bottle (%s); further drops are only counted"
                             % (inp.source, reason))
                return
            reads = inp.spec.reads
            if reads is not None and len(values) > reads and not inp.reported_cut:
                inp.reported_cut = True
                self.log(cut_text(inp.source, len(values), reads))
            queue = inp.queue
            queue.append((values, now, envelope))
            if len(queue) > self.spec.queue:
                queue.popleft()
                inp.unused += 1
            inp.arrival = now
            if inp.state != "fresh":
                if inp.state == "stale":
                    self.log("input %s is fresh again" % inp.source)
                inp.state = "fresh"
                self.cond.notify_all()  # the loop sleeps until the next stale deadline
            if self.publishing:
                # event-driven: built and published here, in the thread of
                # the Bottle that completes it (no hand-off to another thread)
                self._publish_ready()

    def on_foreign(self, inp, source, bottle=True):
        """A Bottle (``bottle``), or a connection, of another port than the
        input's own and those it accepts: never used; the Bottle counted;
        said once per port, with both names."""
        with self.cond:
            if bottle:
                inp.refused += 1
            if source in inp.foreign:
                return
            inp.foreign.append(source)
            self.log(foreign_text(inp.source, source))

    def on_refused(self, inp, reason):
        """A message of the input's own port refused for what it is (a camera
        frame of another pixel type than the input's, an encoding YARP has no
        pixel type for): received and refused, never used; said once."""
        with self.cond:
            inp.received += 1
            inp.refused += 1
            inp.unfit += 1
            if inp.unfit_reason is None:
                inp.unfit_reason = reason
                self.log("input %s: refused a frame (%s); further frames refused are only counted"
                         % (inp.source, reason))

    def on_incompatible(self, endpoint, what, total, text):
        """An incompatible-QoS (``what`` "qos") or incompatible-type ("type")
        event of a ROS 2 ``endpoint``: ``total`` the middleware's count of
        such peers so far; the first is said (``text()``), the others counted."""
        with self.cond:
            before = getattr(endpoint, what)
            setattr(endpoint, what, max(total, before + 1))
            if before == 0:
                self.log(text())

    def ros2_events(self):
        """[(kind, topic, incompatible QoS, incompatible type)] of its ROS 2
        publishers, then its subscriptions, read under the lock: what `stats`
        answers of them."""
        with self.cond:
            return [(e.kind, e.topic, e.qos, e.type)
                    for e in sorted(self.endpoints, key=lambda e: e.kind != "publisher")]

    def on_skipped(self, inp):
        """A Bottle skipped unread: the input's reader fell BACKLOG behind."""
        with self.cond:
            inp.received += 1
            inp.unused += 1

    def request_stop(self, *_):
        with self.cond:
            self.stopping = True
            self.cond.notify_all()

    # -- freshness: report each transition once; returns the next deadline
    def _check_freshness(self, now):
        deadline = None
        for inp in self.inputs:
            if inp.state == "waiting":
                if not inp.reported_waiting:
                    inp.reported_waiting = True
                    self.log("waiting for %s" % inp.source)
                continue
            age = now - inp.arrival
            if inp.state == "fresh":
                if age >= inp.timeout:
                    inp.state = "stale"
                    inp.stale_periods += 1
                    self.log("input %s is stale (no data for %.1f s)" % (inp.source, age))
                else:
                    end = inp.arrival + inp.timeout
                    if deadline is None or end < deadline:
                        deadline = end
        return deadline

    def _ready(self, event_driven):
        # (loops, not any() or all() of a generator: this runs for every Bottle)
        needed = self.needed
        hold = self.spec.on_stale == "hold"
        for i in needed:
            if (i.state == "waiting") if hold else (i.state != "fresh"):
                return False  # hold: one has not delivered yet; else one is not fresh
        if event_driven or self.spec.publish == "new":
            # new data, by the trigger (at a fixed rate with publish = new too)
            if not needed:
                return False  # nothing arrives to publish for
            if self.spec.trigger == "all":
                for i in needed:
                    if not i.queue:
                        return False
                return True
            for i in needed:
                if i.queue:
                    return True
            return False
        return True

    @staticmethod
    def _nearest(inp, reference, key):
        """The index of the input's queued Bottle nearest in time to
        ``reference`` (the older one on a tie); ``key`` 2: envelope, 1: arrival."""
        queue = inp.queue
        best, gap = 0, abs(queue[0][key] - reference)
        for k in range(1, len(queue)):
            g = abs(queue[k][key] - reference)
            if g < gap:
                best, gap = k, g
        return best

    @staticmethod
    def _use(inp, k):
        """Queued Bottle ``k`` becomes what messages use; the older ones are unused."""
        queue = inp.queue
        for _ in range(k):
            queue.popleft()
        inp.unused += k
        inp.values, _, inp.envelope = queue.popleft()

    def _take(self, event_driven):
        """Under the lock: moves the Bottles the next message uses from the
        queues (docs/runtime.md, "Which Bottles a message uses")."""
        needed = self.needed
        if event_driven and self.spec.trigger == "all":
            # one Bottle of every needed input, matched in time to the newest
            # of the oldest ones: by envelope stamps when all of them have one
            key = 2
            for i in needed:
                for e in i.queue:
                    if e[2] is None:
                        key = 1
                        break
            reference = None
            for i in needed:
                t = i.queue[0][key]
                if reference is None or t > reference:
                    reference = t
            for inp in needed:
                self._use(inp, self._nearest(inp, reference, key))
        elif event_driven:
            # the oldest unused Bottle of any needed input; an input no message
            # used yet joins with its Bottle nearest in time to it
            first = min((i for i in needed if i.queue), key=lambda i: i.queue[0][1])
            reference = first.queue[0][1]
            self._use(first, 0)
            for inp in needed:
                if inp.values is None and inp.queue:
                    self._use(inp, self._nearest(inp, reference, 1))
        for inp in self.sampled:
            if inp.queue:
                self._use(inp, len(inp.queue) - 1)

    def _snapshot(self, event_driven):
        """Under the lock: takes the next message's Bottles; the raw values
        of every mux and their envelopes."""
        self._take(event_driven)
        raw = {}
        envelopes = {}
        for mux in self.spec.muxes:
            values = []
            newest = None
            for inp in self.mux_inputs[mux.name]:
                if inp.values is not None:
                    values.extend(inp.values)
                if inp.envelope is not None and (newest is None or inp.envelope > newest):
                    newest = inp.envelope
            raw[mux.name] = values
            envelopes[mux.name] = newest
        return raw, envelopes

    def _publish(self, raw, envelopes, now_ns=None):
        """Converts, builds and publishes one message; ``now_ns``: its time
        (None: the wall clock)."""
        values = {}
        for mux in self.spec.muxes:
            if mux.rows:
                v = [convert(row, mux.converters) for row in raw[mux.name]]
            else:
                v = convert(raw[mux.name], mux.converters)
            values[mux.name] = v
        self.compute(values)
        for mux in self.spec.muxes:
            if mux.verbose or self.verbose:
                for k, x in enumerate(values[mux.name]):
                    print("[%s] %d: %r" % (mux.name, k, x))
                sys.stdout.flush()
        ctx = Context(values, self.published, envelopes, now_ns)
        try:
            tree = self.build(ctx)
        except IndexError:
            self.build_errors += 1
            if self.build_errors == 1:
                self.log("cannot build the message: a mux has fewer elements than the "
                         "message needs (%s); further failures are only counted"
                         % ", ".join("%s has %d" % (n, len(v)) for n, v in sorted(values.items())))
            return
        self.output.publish(tree)
        self.published += 1

    # -- the loops
    def _publish_ready(self):
        """Under the lock, event-driven: every message that is ready."""
        while not self.stopping and self._ready(True):
            raw, envelopes = self._snapshot(True)
            self._publish(raw, envelopes)

    def _loop_event_driven(self):
        """Messages are published by the input threads (on_bottle); the loop
        reports freshness, sleeping until an input would go stale."""
        with self.cond:
            self.publishing = True
            self._publish_ready()  # Bottles that came before the output was open
        while True:
            with self.cond:
                if self.stopping:
                    return
                now = time.monotonic()
                deadline = self._check_freshness(now)
                wait = 1.0 if deadline is None else min(1.0, max(0.0, deadline - now))
                self.cond.wait(wait)

    def _loop_fixed_rate(self):
        period = 1.0 / self.rate
        next_time = time.monotonic()
        while True:
            with self.cond:
                while not self.stopping:
                    left = next_time - time.monotonic()
                    if left <= 0:
                        break
                    self.cond.wait(left)
                if self.stopping:
                    return
                now = time.monotonic()
                late = now - next_time
                if late > period:
                    # overran by more than a whole period: skip, never catch up in a burst
                    missed = int(late // period)
                    self.skipped_cycles += missed
                    next_time += missed * period
                next_time += period
                self._check_freshness(now)
                if not self._ready(False):
                    continue
                raw, envelopes = self._snapshot(False)
            self._publish(raw, envelopes)

    def totals(self):
        """The totals as they stand, read under the lock: ([(source,
        received, dropped, stale periods, unused, refused) per input],
        published, skipped cycles, build failures, messages YARP readers
        missed). What `stats` answers on the RPC port."""
        with self.cond:
            inputs = [(i.source, i.received, i.dropped, i.stale_periods, i.unused, i.refused)
                      for i in self.inputs]
            return inputs, self.published, self.skipped_cycles, self.build_errors, self.missed

    @property
    def missed(self):
        """The messages a reader of the output's YARP port missed (0 for an
        output of no YARP port)."""
        return getattr(self.output, "missed", 0)

    def totals_lines(self):
        """The totals at exit, a line each."""
        lines = ["totals:"]
        for inp in self.inputs:
            line = ("  input %s: received %d, dropped %d, stale periods %d, unused %d"
                    % (inp.source, inp.received, inp.dropped, inp.stale_periods, inp.unused))
            lines.append(line + refused_text(inp))
        lines.append("  published %d messages, skipped %d cycles, build failures %d"
                     % (self.published, self.skipped_cycles, self.build_errors))
        if self.missed:
            lines.append("  " + MISSED_LINE % self.missed)
        lines.extend("  " + EVENTS_TOTALS_LINE % e for e in self.ros2_events() if e[2] or e[3])
        return lines


class EndpointEvents:
    """The incompatible peers of one ROS 2 publisher or subscription
    (``kind``) of ``topic`` (as the config names it), counted by kind: a
    peer whose QoS does not match its own (``qos``), a peer whose type has
    its name but another definition (``type``). Guarded by the bridge's lock."""

    def __init__(self, kind, topic):
        self.kind = kind
        self.topic = topic
        self.qos = 0
        self.type = 0


#: what a ROS 2 endpoint says of its first peer of an incompatible QoS (the
#: C++ runtime says the same: ybgc_ros2.cpp; the texts are ybg/lower/ros2_events.py's);
#: {peer} is the other kind
INCOMPATIBLE_QOS_TEXT = ("ROS 2 {kind} {topic}: a {peer} of an incompatible QoS ({policy}; the {peer}'s: "
                         "{theirs}; this {kind}'s: {ours}): no messages between them; further incompatible "
                         "QoS events of it are only counted")
#: ... of its first peer of the same type name and another definition
INCOMPATIBLE_TYPE_TEXT = ("ROS 2 {kind} {topic}: a {peer} of another definition of {type} (its type hash "
                          "{theirs}; this {kind}'s: {ours}): no messages between them; further incompatible "
                          "type events of it are only counted")
#: a publisher's matched subscriptions, each time they change
SUBSCRIBERS_TEXT = "{topic}: {n} subscriber{s}"
#: a subscription's matched publishers, each time they change
PUBLISHERS_TEXT = "{topic}: {n} publisher{s}"
#: the exit totals' line of the messages YARP readers missed, when any (the
#: C++ runtime's missedLine(): ybgc_totals.cpp)
MISSED_LINE = "readers missed %d messages (each written while a reader was still taking the one before)"
#: the exit totals' line of an endpoint that had incompatible peers
EVENTS_TOTALS_LINE = "ros2 %s %s: incompatible QoS %d, incompatible type %d"


def refused_text(inp):
    """What the totals say of an input's refused messages: of which ports,
    and how many frames refused for what they are (the first reason)."""
    if not inp.refused:
        return ""
    if not inp.unfit:
        return ", refused %d from %s" % (inp.refused, ", ".join(inp.foreign))
    frames = "%d frame%s (%s)" % (inp.unfit, "" if inp.unfit == 1 else "s", inp.unfit_reason)
    if inp.refused == inp.unfit:
        return ", refused " + frames
    return ", refused %d: %d from %s, %s" % (inp.refused, inp.refused - inp.unfit, ", ".join(inp.foreign), frames)


def foreign_text(source, other):
    """What the module says, once per port, when another port than an input's
    own (or those it accepts) is connected to it: both names, what is done,
    how to accept it."""
    return ("input %s: %s is connected to its port, not %s (the name server gave %s the address of %s, "
            "or the connection was made by hand): its Bottles are refused (dropped and counted), the "
            "connection closed and %s tried again; to take them, `accept` it in the config or give "
            "--accept %s=%s; said once" % (source, other, source, source, other, source, source, other))


def cut_text(source, width, reads):
    """What the module says, once, when a Bottle of an undeclared port brings
    more values than the message reads (W511)."""
    return ("input %s: a Bottle of %d values, of which the message reads the first %d; the other %d are "
            "dropped (declare the port's elements in the config to check its width); said once"
            % (source, width, reads, width - reads))


def take(values, start, stop):
    """values[start:stop], or IndexError when the mux holds fewer elements
    than the slice names (a slice is never silently shortened)."""
    n = len(values)
    if start > n or (stop is not None and stop > n):
        raise IndexError("slice [%d:%s] of %d elements" % (start, "" if stop is None else stop, n))
    return values[start:stop]


def convert(values, converters):
    """The converters, in order: y = x * scale + offset on [start, stop)
    (ConverterSpec), a geometry converter that replaces its range by its
    results (GeometrySpec), an expression on each element (EachSpec)."""
    if not converters:
        return values
    values = list(values)
    for c in converters:
        n = len(values)
        if isinstance(c, GeometrySpec):
            width = GEOMETRY_WIDTHS[c.function][0]
            if c.start + width <= n:  # else left as it is, as in C++
                part = [float(x) for x in values[c.start:c.start + width]]
                values[c.start:c.start + width] = GEOMETRY[c.function](part, *c.args)
            continue
        if isinstance(c, EachSpec):
            stop = n if c.stop is None else min(c.stop, n)
            f = c.function
            values[c.start:stop] = [x if isinstance(x, str) else float(f(float(x))) for x in values[c.start:stop]]
            continue
        scale_range(values, c)
    return values


class RateMeter:
    """The rate achieved: messages published per second since the previous
    reading (the first: since the meter was made, at start)."""

    def __init__(self, now, published=0):
        self.last = (now, published)

    def read(self, now, published):
        then, before = self.last
        self.last = (now, published)
        return (published - before) / (now - then) if now > then else 0.0


def parse_accept(spec, items):
    """{input port: (other ports it takes Bottles from)} of ``--accept``
    values, each `PORT=OTHER`, or `OTHER` for a module of one YARP port
    input; ValueError saying what is wrong."""
    ports = list(dict.fromkeys(i.source for m in spec.muxes for i in m.inputs if i.kind == "yarp"))
    out = {}
    for item in items:
        port, sep, other = item.partition("=")
        if not sep:
            other = item
            if len(ports) != 1:
                raise ValueError("--accept %s: say which input takes it, --accept PORT=%s (the module reads %s)"
                                 % (item, item, ", ".join(ports) or "no YARP port"))
            port = ports[0]
        if port not in ports:
            raise ValueError("--accept %s: %s is not a YARP port the module reads (it reads %s)"
                             % (item, port, ", ".join(ports) or "none"))
        if not other.startswith("/") or len(other) < 2 or any(c.isspace() for c in other):
            raise ValueError("--accept %s: %r is not a YARP port name" % (item, other))
        out.setdefault(port, [])
        if other not in out[port]:
            out[port].append(other)
    return {k: tuple(v) for k, v in out.items()}


def truthy(text):
    """A YARP config file's flag: ``true``/``1``/no value -> True, ``false``/``0`` -> False, else None."""
    return {"": True, "true": True, "1": True, "false": False, "0": False}.get(text.strip().lower())


def parse_options(spec, argv, default_prefix, read_file=None):
    """The module's options. ``--from FILE`` / ``--context CTX``: the
    options in that YARP config file, as ``read_file(FILE, CTX)`` returns
    them (command-line arguments, or ValueError), come first, so that the
    command line wins over the file and the file over the config."""
    argv = sys.argv[1:] if argv is None else list(argv)
    parser = argparse.ArgumentParser(
        prog=os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else spec.module,
        description="\n".join(spec.description),
        epilog="Generated by ybgc from %s." % spec.config,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--name", dest="prefix", default=default_prefix, metavar="P",
                        type=lambda name: name if name.startswith("/") else "/" + name,
                        help="prefix of the module's own port names, as YARP modules name it "
                        "(default: %(default)s)")
    parser.add_argument("--prefix", dest="prefix", metavar="P", help="the same as --name")
    parser.add_argument("--rate", type=float, default=None, metavar="HZ",
                        help="fixed output rate in Hz, 0 for event-driven (default: %s)"
                        % ("event-driven" if spec.rate is None else "%g" % spec.rate))
    parser.add_argument("--timeout", type=float, default=None, metavar="S",
                        help="freshness timeout of every input in seconds (default: the config's)")
    parser.add_argument("--verbose", action="store_true",
                        help="print every value after conversion, for every mux")
    parser.add_argument("--from", dest="from_file", metavar="FILE",
                        help="read these options (name, prefix, rate, timeout, verbose) from a YARP "
                        "config file, found by YARP's ResourceFinder; the command line wins")
    parser.add_argument("--accept", action="append", default=[], metavar="[PORT=]OTHER",
                        help="the input of YARP port PORT also takes the Bottles of port OTHER (a "
                        "replay under another name); OTHER alone: the module's one YARP port input; "
                        "any other port's Bottles are refused. May be given several times")
    parser.add_argument("--context", metavar="CTX",
                        help="the ResourceFinder's context to look for the file in (alone: %s)"
                        % DEFAULT_CONFIG_FILE)
    options = parser.parse_args(argv)
    if (options.from_file or options.context) and read_file is not None:
        try:
            options = parser.parse_args(read_file(options.from_file, options.context) + argv)
        except ValueError as e:
            parser.error(str(e))
    if options.rate is not None and options.rate < 0:
        parser.error("--rate must be 0 (event-driven) or positive")
    if options.timeout is not None and options.timeout <= 0:
        parser.error("--timeout must be positive")
    if not options.prefix.startswith("/"):
        parser.error("--prefix must start with /")
    try:
        options.accept = parse_accept(spec, options.accept)
    except ValueError as e:
        parser.error(str(e))
    if len(options.prefix) > 1:
        options.prefix = options.prefix.rstrip("/")
    return options

