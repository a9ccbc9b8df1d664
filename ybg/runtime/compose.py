"""Several bridges in one process (``ybgc compose``, docs/compose.md): one
YARP network, one RPC port of the process (``/<name>/rpc:i``), and every
bridge as it runs alone, with its own ports, threads (inputs, loop, watcher
of connections), rate, freshness and totals, so that one that stalls or is
fed malformed Bottles delays no other. A bridge that cannot start is said
with its config and the others run; the process then exits 1 when stopped.

The composed module (``<name>.py``, or the ``ros2`` backend's
``<name>_node.py``) lists its bridges (:class:`Member`) and how to load each
one's generated module; :func:`run_bridges` runs YARP modules (the ``py``
backend's), ``ros2_io.run_composed`` rclpy nodes, both on :class:`Composer`.
"""

import argparse
import collections
import importlib.util
import os
import signal
import sys
import threading
import time

import yarp

from .core import _LOG_LOCK, RateMeter, parse_options  # ybgc:runtime-import
from .yarp_io import RpcPort, YarpBridge, ros1_problem, stats_items  # ybgc:runtime-import

#: one bridge of a composed module: its module's name, its config file, where
#: in the config its output is (``file:line:column``), and where its generated
#: module is (a file of the composed module's folder, or a module of its package)
Member = collections.namedtuple("Member", "module config at where")

#: what `help` answers on the RPC port of a composed module
COMPOSED_HELP = (
    "help: this list",
    "stats: one list per bridge, its name then its own stats: per input (input SOURCE received N dropped N "
    "stale N unused N refused N), (published N skipped N failures N missed N), (rate ACHIEVED configured "
    "HZ|event-driven); a node of commands: per service (service NAME calls N answered N failed N timed_out N "
    "no_server N unfit N); a bridge that is not running: (NAME \"not running\" WHY)",
    "quit: stop every bridge (each closes its ports and prints its totals; exit 0, or 1 if a bridge could "
    "not start)",
)

#: the seconds every bridge has to close its ports, all at once
CLOSE_BUDGET = 1.5
#: the seconds from a stop (SIGINT, SIGTERM, `quit`) to the exit, at most
EXIT_BUDGET = 1.8
#: the interpreter's switch interval in a process of several bridges: a
#: bridge's loop waiting for the interpreter lock gets it within about this
#: (Python's default, 5 ms, let a loop of 100 Hz that several threads kept
#: waiting miss its cycle)
SWITCH_INTERVAL = 0.001


def load_file(path, name):
    """The generated module of a bridge, from its file ``path``, as module ``name``."""
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None:
        raise ImportError("no module at %s" % path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def load_failure(member, e):
    """Why a bridge's module did not load (a message type that is not
    installed, a runtime of another version): the reason, one line."""
    if isinstance(e, SystemExit):
        text = str(e.code)
    else:
        text = "%s: %s" % (type(e).__name__, e)
    return "cannot load its module %s (%s)" % (member.where, text.strip().splitlines()[0] if text.strip() else text)


class ComposedRpc(RpcPort):
    """The RPC port of a composed module: the composer answers."""

    def respond(self, command, reply):
        self.bridge.respond(command, reply)


class Composer:
    """The bridges of one process: started one after the other (a bridge
    that cannot start is refused, the others run), each loop in a thread of
    its own, the RPC port ``/<name>/rpc:i``, the stop (SIGINT, SIGTERM,
    `quit`) and the close of every bridge at once within the 2 s budget,
    each printing its totals under its name."""

    def __init__(self, name, members):
        self.name = name
        self.members = tuple(members)
        self.bridges = {}   # module -> its bridge, once it runs
        self.opened = {}    # module -> its inputs opened
        self.meters = {}    # module -> its rate meter for `stats`
        self.failed = {}    # module -> why it is not running
        self.threads = []
        self.stop_event = threading.Event()
        self.stopped_at = None  # when the stop was asked (time.monotonic())
        self.stopping = False
        self.quit_asked = False
        self.rpc = None

    def log(self, text):
        with _LOG_LOCK:
            sys.stdout.write("%s: %s\n" % (self.name, text))
            sys.stdout.flush()

    def handle_signals(self):
        signal.signal(signal.SIGINT, self.request_stop)
        signal.signal(signal.SIGTERM, self.request_stop)

    def request_stop(self, *_):
        if self.stopped_at is None:
            self.stopped_at = time.monotonic()
        self.stopping = True
        self.stop_event.set()
        for bridge in list(self.bridges.values()):
            bridge.request_stop()

    # -- start
    def open_rpc(self):
        """The process's RPC port; False (said) when it cannot open."""
        rpc = ComposedRpc(self, "/%s/rpc:i" % self.name)
        if not rpc.open():
            self.log("cannot open the RPC port %s" % rpc.name)
            return False
        self.rpc = rpc
        return True

    def refuse(self, member, reason):
        """A bridge that cannot start: said with its config; the others run."""
        self.failed[member.module] = reason
        self.log("bridge %s (%s) cannot start: %s; the other bridges run" % (member.module, member.at, reason))

    def start(self, member, bridge):
        """Open the bridge's ports and start its watcher (not its own RPC
        port: the process has one): True once it runs. When a port cannot
        open, those it opened are closed and the bridge is refused."""
        opened = []
        problem = bridge.open_all(opened, rpc=False)
        if problem is not None:
            with bridge.cond:
                bridge.stopping = True
            _, stuck, unclosed = bridge.close_ports(opened)
            if stuck:
                bridge.unregister(unclosed)
            self.refuse(member, problem)
            return False
        self.opened[member.module] = opened
        self.meters[member.module] = RateMeter(time.monotonic())
        self.bridges[member.module] = bridge
        if self.stopping:
            bridge.request_stop()
        return True

    # -- run
    def _loop(self, module, bridge):
        try:
            bridge.loop()
        except Exception as e:  # this bridge stops; the others run on
            reason = "stopped: %s: %s" % (type(e).__name__, e)
            bridge.log(reason)
            self.failed[module] = reason

    def serve(self, finish=None):
        """Run every bridge that started until stopped; close them all, each
        printing its totals; ``finish(stuck)`` then (the ROS 2 side). The
        exit status: 0, or 1 if a bridge could not start or stopped."""
        running = len(self.bridges)
        self.log("%d bridge%s running%s" % (running, "" if running == 1 else "s",
                                             "; not running: %s" % ", ".join(self.failed) if self.failed else ""))
        for module, bridge in self.bridges.items():
            thread = threading.Thread(target=self._loop, args=(module, bridge), name="loop " + module, daemon=True)
            thread.start()
            self.threads.append(thread)
        while not self.stop_event.is_set():
            self.stop_event.wait(0.5)
        stuck, watchers_done = self.shut_down()
        if finish is not None:
            finish(stuck)
        status = 1 if self.failed else 0
        if stuck:
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(status)
        if watchers_done:
            yarp.Network.fini()
        return status

    # -- stop
    def time_left(self):
        """The seconds left before the exit is due (EXIT_BUDGET after the stop)."""
        if self.stopped_at is None:
            self.stopped_at = time.monotonic()
        return self.stopped_at + EXIT_BUDGET - time.monotonic()

    def shut_down(self):
        """Stop every bridge and close its ports, all at once (a bridge whose
        reader stalls delays no other's), then print each one's totals under
        its name: (a port did not close in time, every watcher stopped)."""
        if self.stopped_at is None:
            self.stopped_at = time.monotonic()
        self.stopping = True
        self.stop_event.set()
        bridges = list(self.bridges.items())
        for _, bridge in bridges:
            # under the lock: a message being published is finished, and none starts after this
            with bridge.cond:
                bridge.stopping = True
                bridge.cond.notify_all()
        if self.rpc is not None:
            self.rpc.close()
        results = {}

        def close(module, bridge):
            results[module] = bridge.close_ports(self.opened[module])

        closers = []
        for module, bridge in bridges:
            closer = threading.Thread(target=close, args=(module, bridge), name="close " + module, daemon=True)
            closer.start()
            closers.append(closer)
        end = time.monotonic() + CLOSE_BUDGET
        for closer in closers:
            closer.join(max(0.0, end - time.monotonic()))
        for thread in self.threads:
            thread.join(max(0.0, min(0.2, end - time.monotonic())))
        stuck = False
        watchers_done = True
        for member in self.members:
            bridge = self.bridges.get(member.module)
            if bridge is None:
                print("%s: not started (%s)" % (member.module, self.failed.get(member.module, "stopped before")),
                      flush=True)
                continue
            bridge._print_totals(prefix=member.module + ": ")
        for module, bridge in bridges:
            result = results.get(module)
            if result is None:  # still closing: every port of it unregistered by name
                stuck = True
                watchers_done = False
                bridge.unregister(self._port_names(bridge, self.opened[module]))
                continue
            done, late, unclosed = result
            watchers_done = watchers_done and done
            if late:
                stuck = True
                bridge.unregister(unclosed)
        return stuck, watchers_done

    @staticmethod
    def _port_names(bridge, opened):
        names = getattr(bridge, "port_names", None)  # a node of commands
        if names is not None:
            return names(opened)
        return [inp.local for inp in opened] + [bridge.output.port_name]

    # -- the RPC port
    def respond(self, command, reply):
        """``reply`` to ``command`` on the process's RPC port."""
        word = command.get(0).toString() if command.size() > 0 else ""
        if word == "help":
            reply.addVocab32("many")
            for line in COMPOSED_HELP:
                reply.addString(line)
        elif word == "stats":
            reply.addVocab32("many")
            for member in self.members:
                item = reply.addList()
                item.addString(member.module)
                bridge = self.bridges.get(member.module)
                if member.module in self.failed or bridge is None:
                    item.addString("not running")
                    item.addString(self.failed.get(member.module, "starting"))
                elif hasattr(bridge, "stats_items"):  # a node of commands: its services
                    bridge.stats_items(item)
                else:
                    stats_items(item, bridge, self.meters[member.module])
        elif word in ("quit", "exit", "bye"):
            self.log("asked to quit on the RPC port")
            self.quit_asked = True
            self.request_stop()
            reply.addVocab32("bye")
        else:
            reply.addString("unknown command %r; the commands: help, stats, quit" % word)


def describe(name, members):
    """The description of a composed module's --help."""
    lines = ["%s: %d bridges in one process (ybgc compose):" % (name, len(members))]
    lines.extend("  %s, from %s" % (m.module, m.config) for m in members)
    return "\n".join(lines)


def run_bridges(name, members, argv, load):
    """Run the YARP bridges ``members`` (each loaded by ``load(member)``, a
    module of the ``py`` backend) in this process until SIGINT, SIGTERM or
    `quit` on ``/<name>/rpc:i``; the exit status. Each runs with its
    config's options (its own port prefix, rate, timeouts)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    sys.setswitchinterval(SWITCH_INTERVAL)
    parser = argparse.ArgumentParser(
        prog=os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else name,
        description=describe(name, members),
        epilog="Each bridge runs with its config's options. `yarp rpc /%s/rpc:i` answers help, stats and quit."
               % name,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_args(argv)
    composer = Composer(name, members)
    yarp.Network.init()
    composer.handle_signals()
    if not yarp.Network.checkNetwork(3.0):
        composer.log("cannot reach the YARP name server (is yarpserver running?)")
        return 1
    if not composer.open_rpc():
        return 1
    ros1 = None
    for member in members:
        if composer.stop_event.is_set():
            break
        try:
            module = load(member)
            spec = module.SPEC
            options = parse_options(spec, [], "/" + spec.module)
            bridge = YarpBridge(spec, options, module.make_output(), module.build_message, module.compute)
        except (Exception, SystemExit) as e:
            composer.refuse(member, load_failure(member, e))
            continue
        if getattr(bridge.output, "kind", None) == "ros1" or any(i.spec.kind == "ros1" for i in bridge.inputs):
            if ros1 is None:
                ros1 = ros1_problem() or ""
            if ros1:
                composer.refuse(member, "cannot use ROS 1 topics: " + ros1)
                continue
        composer.start(member, bridge)
    return composer.serve()
