"""A YARP module's connections and names: the watcher that connects its
links and keeps its ports registered with a restarted name server, the
admin commands it asks ports, whether this YARP carries ROS 1 topics, and
a closed ROS 1 port withdrawn from the ROS master (docs/runtime.md,
"Faults"; docs/network.md)."""

import functools
import threading
import xmlrpc.client

import yarp


def admin(contact, *words):
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
    reply = admin(contact, "prop", "get", name)
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
    reply = admin(yarp.Contact(port), "list", "in")
    if reply is None:
        return None
    return any(reply.get(k).asString() == source for k in range(reply.size()))


@functools.lru_cache(maxsize=1)
def ros1_problem():
    """None when this YARP carries ROS 1 topics, else why it cannot. It needs
    a name server started with `--ros` (its ROS master contact, /ros) reached
    through the xmlrpc carrier: built in up to YARP 3.9, YARP's separate
    yarp-ros plugins in 3.10 to 3.12, gone in YARP 4. Without them a ROS 1
    port opens as a plain YARP port, and the module would publish into nothing.
    Asked once a process (its bridges share the answer)."""
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

