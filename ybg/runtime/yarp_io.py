"""The YARP side of a stream bridge (the ``py`` module, and the YARP ports
of the ``ros2`` node): the bridge on YARP ports, a part of the process shell
(shell.py) that opens its inputs and output, watches its connections and
closes them; the output message tree written as a Bottle on a YARP port or a
ROS 1 topic; the options of a YARP module from its command line and a YARP
config file (docs/runtime.md)."""

import sys
import threading
import time

import yarp

from .base import ADD, add_values  # ybgc:runtime-import
from .core import DEFAULT_CONFIG_FILE, Array, Bridge, Msg, RateMeter, Rows, Scalar, Splice  # ybgc:runtime-import
from .core import parse_options, truthy  # ybgc:runtime-import
from .connections import Watcher, ros1_problem, withdraw_from_ros_master  # ybgc:runtime-import
from .shell import Member, Part, Process  # ybgc:runtime-import
from .yarp_inputs import Input, TopicInput  # ybgc:runtime-import


class YarpBridge(Bridge, Part):
    """The bridge on YARP: its inputs are YARP ports (or ROS 1 topics
    through YARP); as a part of the process (shell.Part) it opens them and
    its output, watches the connections and closes them; the process's RPC
    port answers `stats` with its totals."""

    inbox = None  # the thread its YARP port inputs hand what they read to (Inbox)
    meter = None  # the rate `stats` says, since the previous one

    def __init__(self, spec, options, output, build, compute):
        Bridge.__init__(self, spec, options, output, build, compute)
        self.name = spec.module
        self.opened = []

    def make_input(self, mux, spec, local, timeout):
        return TopicInput(self, spec, local, timeout) if spec.kind == "ros1" else Input(self, spec, local, timeout)

    def check(self):
        """None, or why this YARP cannot carry its ROS 1 topics."""
        if getattr(self.output, "kind", None) == "ros1" or any(i.spec.kind == "ros1" for i in self.inputs):
            problem = ros1_problem()
            if problem is not None:
                return "cannot use ROS 1 topics: " + problem
        return None

    def open(self, rpc=None):
        """Open the inputs, the output, start the watcher of connections:
        None, or what could not open."""
        self.meter = RateMeter(time.monotonic())
        for inp in self.inputs:
            if not inp.open():
                return "cannot open the port %s" % inp.local
            self.opened.append(inp)
        if not self.output.open():
            return "cannot open the output %s" % self.output.port_name
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

    def serve(self):
        """Publish until stopped: event-driven or at the fixed rate."""
        if self.rate is None:
            self._loop_event_driven()
        else:
            self._loop_fixed_rate()

    def halt(self, within):
        # under the lock: a message being published by an input thread is
        # finished, and none starts after this, before the ports close
        with self.cond:
            self.stopping = True
            self.cond.notify_all()

    def port_names(self):
        return [inp.local for inp in self.opened] + [self.output.port_name]

    def close(self):
        """Stop the watcher and close the ports within 1 s: (the watcher
        stopped, the names of the ports not closed). A port whose reader
        stalls can hang in close(): it is then left to be unregistered by
        name, and the process exits at once."""
        opened = self.opened
        watcher_done = self.watcher.stop() if self.watcher is not None else True
        names = self.port_names()
        closed = []

        def close_all():
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
            if not self.output.stalled():  # else unregistered by name
                self.output.close()
                closed.append(self.output.port_name)

        closer = threading.Thread(target=close_all, name="close ports", daemon=True)
        closer.start()
        closer.join(1.0)
        return watcher_done, [name for name in names if name not in closed]

    # -- what the process's RPC port answers of it
    def help_lines(self, port):
        return RPC_HELP

    def stats_items(self, reply):
        stats_items(reply, self, self.meter)


# ===========================================================================
# Output side: the message tree as a Bottle on a YARP port (or on a ROS 1
# topic through YARP's topic@node ports).
# ===========================================================================

def _add_values(bottle, types, values, wire):
    if isinstance(types, tuple):
        for t, x in zip(types, values):
            ADD[wire[t]](bottle, x)
    else:
        add_values(bottle, wire[types], values)


def is_message_type(type_):
    """Is an Array's ``type`` a message type ("pkg/Name"), its values messages?"""
    return isinstance(type_, str) and "/" in type_


def add_node(bottle, node, wire):
    """Append ``node`` to ``bottle`` with YARP's ROS 1 wire mapping: a
    message is a nested list of its fields, a time is (sec nsec), an array
    of messages a list of such lists."""
    if isinstance(node, Scalar):
        ADD[wire[node.type]](bottle, node.value)
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


# --- what the RPC port answers, the ResourceFinder (YARP modules' conventions) ----------

#: what `help` answers on the RPC port, one line a command
RPC_HELP = (
    "help: this list",
    "stats: the totals so far: per input (input SOURCE received N dropped N stale N unused N refused N), "
    "(published N skipped N failures N missed N), (rate ACHIEVED configured HZ|event-driven), and per ROS 2 publisher "
    "and subscription (ros2 publisher|subscription TOPIC incompatible_qos N incompatible_type N)",
    "quit: stop the module (it closes its ports and exits 0, as on SIGINT)",
)


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
    """Parse the command line, run the bridge until SIGINT, SIGTERM or `quit`."""
    options = parse_options(spec, argv, default_prefix,
                            lambda path, context: read_config_file(spec, path, context))
    bridge = YarpBridge(spec, options, make_output(), build, compute)
    process = Process(spec.module, (Member(spec.module),), alone=True)
    process.handle_signals()
    if not process.connect() or not process.open_rpc(bridge.prefix + "/rpc:i"):
        return 1
    process.start(process.members[0], bridge)
    return process.serve()
