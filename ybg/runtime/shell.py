"""The process every Python module runs in, one for every kind of bridge (a
stream, a node of commands), alone or several in one process (``ybgc
compose``, docs/compose.md): the signals that stop it, its RPC port
(`help`, `stats`, `quit`), the start of each bridge, their loops, and the
stop within the exit's budget: every bridge's ports closed at once, its
totals printed, a port that does not close unregistered by name and the
process ended at once (docs/runtime.md, "Shutdown").

A kind of bridge is a :class:`Part` (``yarp_io.YarpBridge``, a stream;
``services.CommandsBridge``, a node of commands); :class:`Process` runs
parts alone or together; ``ros2_shell`` adds the rclpy node of each."""

import collections
import os
import signal
import sys
import threading
import time

import yarp

from .base import say  # ybgc:runtime-import

#: one bridge of a process: its module's name, its config file, where in the
#: config its output is (``file:line:column``), and where its generated
#: module is (a file of the composed module's folder, or a module of its
#: package); a bridge alone has only its name
Member = collections.namedtuple("Member", "module config at where", defaults=(None, None, None))

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
#: the commands of the RPC port, as an unknown command's reply names them
RPC_COMMANDS = "help, stats, quit"

#: the seconds every bridge has to stop taking work and close its ports, all at once
CLOSE_BUDGET = 1.5
#: the seconds from a stop (SIGINT, SIGTERM, `quit`) to the exit, at most
EXIT_BUDGET = 1.8
#: the interpreter's switch interval in a process of several bridges: a
#: bridge's loop waiting for the interpreter lock gets it within about this
#: (Python's default, 5 ms, let a loop of 100 Hz that several threads kept
#: waiting miss its cycle)
SWITCH_INTERVAL = 0.001


def first_word(bottle):
    """A command's first item as a word ('' for none; a number as its text)."""
    if bottle.size() == 0:
        return ""
    v = bottle.get(0)
    if v.isString():
        return v.asString()
    if v.isVocab32():
        return yarp.decode(v.asVocab32())
    return v.toString()


def unknown_reply(word):
    """The reply of the RPC port to a command it does not know: the commands."""
    reply = yarp.Bottle()
    reply.addString("unknown command %r; the commands: %s" % (word, RPC_COMMANDS))
    return reply


def describe(name, members):
    """The description of a composed module's --help."""
    lines = ["%s: %d bridges in one process (ybgc compose):" % (name, len(members))]
    lines.extend("  %s, from %s" % (m.module, m.config) for m in members)
    return "\n".join(lines)


def load_failure(member, e):
    """Why a bridge's module did not load (a message type that is not
    installed, a runtime of another version): the reason, one line."""
    if isinstance(e, SystemExit):
        text = str(e.code)
    else:
        text = "%s: %s" % (type(e).__name__, e)
    return "cannot load its module %s (%s)" % (member.where, text.strip().splitlines()[0] if text.strip() else text)


class Part:
    """One bridge as the process runs it, whatever its kind: what the
    process asks of it, the same alone or beside others. A kind overrides
    what it does (``yarp_io.YarpBridge``, a stream; ``services.CommandsBridge``,
    a node of commands)."""

    #: its module's name, which heads its log lines (and its totals among others)
    name = "bridge"
    #: `stats` of it alone begins with the vocab ``many`` (a stream's
    #: totals); a node of commands answers its services' lists alone
    stats_many = True

    def log(self, text):
        say(self.name, text)

    def check(self):
        """None, or why this process cannot run it (before anything opens)."""
        return None

    def open(self, rpc=None):
        """Opens its ports, services and threads (``rpc``: the name of the
        process's RPC port when the part is alone, whose commands it may
        answer too): None, or what could not open."""
        raise NotImplementedError

    def serve(self):
        """Its loop, until it is stopped."""
        raise NotImplementedError

    def request_stop(self, *_):
        """Stop (from a signal, `quit`, or the process): returns at once."""
        raise NotImplementedError

    def halt(self, within):
        """Takes no more work, and what is under way ends within ``within``
        seconds (a message being published is finished; a call in flight
        is answered); before its ports close."""

    def close(self):
        """Closes its ports within 1 s: (its threads stopped, [the names of
        the ports that did not close])."""
        raise NotImplementedError

    def port_names(self):
        """The names of every port it opened."""
        return []

    def unregister(self, names):
        """Ports that did not close in time, unregistered by name (said)."""
        for name in names:
            self.log("%s did not close in time (a stalled reader?); unregistering it" % name)
            yarp.Network.unregisterName(name)

    def answer(self, port, word, command):
        """The reply to ``command`` (its first word ``word``) when the part
        serves it on ``port``, else None."""
        return None

    def help_lines(self, port):
        """What `help` answers on ``port``, the RPC port of it alone."""
        return ()

    def stats_items(self, reply):
        """What `stats` answers of it, appended to ``reply``."""

    def unknown(self, port, word):
        """The reply to a command no one serves on the RPC port of it alone."""
        return unknown_reply(word)

    def totals_lines(self):
        """Its totals, printed at exit."""
        return []


class _CommandReader(yarp.PortReader):
    """What YARP calls for each command on a served port, in the thread of
    the connection it came by."""

    def __init__(self, served):
        yarp.PortReader.__init__(self)
        self.served = served

    def read(self, connection):
        return self.served.read(connection)


class ServedPort:
    """A YARP port whose commands are answered by ``answer(command)`` (the
    reply Bottle) in the thread of the connection each came by, so that the
    connections of several callers are answered at once and a `quit` is
    not kept waiting by a call in flight; the loops and inputs never wait
    for it. ``after_reply`` (a `quit`: the stop) is called once a reply is
    on its way. The module's RPC port, and each port a node of commands
    serves."""

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
        answered (a binding call keeps the interpreter lock: closing while
        YARP's thread waits for it to answer would deadlock)."""
        self.stopping = True
        end = time.monotonic() + grace
        while not self.idle() and time.monotonic() < end:
            time.sleep(0.005)
        time.sleep(0.05)  # the last reply (`bye` of quit) on its way before the port goes
        self.port.interrupt()

    def close(self):
        self.port.close()


class Process:
    """The bridges of one process (:class:`Part`, each of a :class:`Member`):
    started one after the other, each loop in a thread of its own, the RPC
    port, the stop (SIGINT, SIGTERM, `quit`) and the close of every bridge
    at once within the exit's budget, each printing its totals.

    ``alone``: one bridge, the module of its config: the RPC port is its own
    (``<prefix>/rpc:i``) and answers as it does, its totals are printed as
    they are, and a bridge that cannot start ends the process (status 1).
    Else a composed module (``/<name>/rpc:i``): `stats` lists every bridge,
    each bridge's totals are headed by its name, and a bridge that cannot
    start is said with its config while the others run (status 1 at the
    end)."""

    def __init__(self, name, members, alone=False):
        self.name = name
        self.alone = alone
        self.members = tuple(members)
        self.parts = {}     # module -> its part, once it started (alone: also one that could not)
        self.failed = {}    # module -> why it is not running
        self.threads = []
        self.stop_event = threading.Event()
        self.stopped_at = None  # when the stop was asked (time.monotonic())
        self.stopping = False
        self.quit_asked = False
        self.rpc = None
        #: called in each part's closing thread once it has halted, before its
        #: ports close (ros2_shell: its node's executor stopped)
        self.halted = lambda part: None

    def log(self, text):
        say(self.name, text)

    def handle_signals(self):
        signal.signal(signal.SIGINT, self.request_stop)
        signal.signal(signal.SIGTERM, self.request_stop)

    def request_stop(self, *_):
        if self.stopped_at is None:
            self.stopped_at = time.monotonic()
        self.stopping = True
        self.stop_event.set()
        for part in list(self.parts.values()):
            part.request_stop()

    def time_left(self):
        """The seconds left before the exit is due (EXIT_BUDGET after the stop)."""
        if self.stopped_at is None:
            self.stopped_at = time.monotonic()
        return self.stopped_at + EXIT_BUDGET - time.monotonic()

    # -- start
    def connect(self):
        """The YARP network: False (said) when its name server cannot be reached."""
        yarp.Network.init()
        if not yarp.Network.checkNetwork(3.0):
            self.log("cannot reach the YARP name server (is yarpserver running?)")
            return False
        return True

    def open_rpc(self, name):
        """The process's RPC port; False (said) when it cannot open."""
        rpc = ServedPort(name, self.answer, self.log)
        if not rpc.open():
            self.log("cannot open the RPC port %s" % name)
            return False
        self.rpc = rpc
        return True

    def refuse(self, member, reason):
        """A bridge that cannot start: alone, said; else said with its config
        while the others run."""
        self.failed[member.module] = reason
        if self.alone:
            self.log(reason)
            self.request_stop()
        else:
            self.log("bridge %s (%s) cannot start: %s; the other bridges run" % (member.module, member.at, reason))

    def start(self, member, part):
        """Open the part (not the RPC port: the process has one): True once it
        runs. When something cannot open, what it opened is closed (alone:
        with the process, which then ends) and the bridge is refused."""
        problem = part.check()
        if problem is None:
            problem = part.open(self.rpc.name if self.alone and self.rpc is not None else None)
        if problem is not None:
            if self.alone:
                self.parts[member.module] = part  # closed, and its totals printed, with the process
            else:
                part.halt(0.0)
                _, unclosed = part.close()
                part.unregister(unclosed)
            self.refuse(member, problem)
            return False
        self.parts[member.module] = part
        if self.stopping:
            part.request_stop()
        return True

    # -- run
    def _loop(self, module, part):
        try:
            part.serve()
        except Exception as e:  # this bridge stops; the others run on
            reason = "stopped: %s: %s" % (type(e).__name__, e)
            part.log(reason)
            self.failed[module] = reason
            if self.alone:
                self.request_stop()

    def serve(self, finish=None):
        """Run every bridge that started until stopped; close them all, each
        printing its totals; ``finish(stuck)`` then (the ROS 2 side). The
        exit status: 0, or 1 if a bridge could not start or stopped."""
        if not self.alone:
            running = len(self.parts)
            self.log("%d bridge%s running%s" % (running, "" if running == 1 else "s",
                                                 "; not running: %s" % ", ".join(self.failed) if self.failed else ""))
        for module, part in self.parts.items():
            if module in self.failed:
                continue
            thread = threading.Thread(target=self._loop, args=(module, part), name="loop " + module, daemon=True)
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
    def shut_down(self):
        """Stop every bridge and close its ports, all at once (a bridge whose
        reader stalls delays no other's), then print each one's totals:
        (a port did not close in time, every watcher stopped)."""
        if self.stopped_at is None:
            self.stopped_at = time.monotonic()
        self.stopping = True
        self.stop_event.set()
        parts = list(self.parts.items())
        for _, part in parts:
            part.request_stop()
        if self.rpc is not None:
            if self.quit_asked:
                # its `bye` is sent once its read has returned: not dropped by a
                # port closed at once (the caller would not know it was heard)
                self.rpc.stop(0.5)
            else:
                self.rpc.stop()
            self.rpc.close()
        results = {}
        end = time.monotonic() + CLOSE_BUDGET

        def close(module, part):
            part.halt(max(0.05, min(0.5, end - time.monotonic())))
            self.halted(part)
            results[module] = part.close()

        closers = []
        for module, part in parts:
            closer = threading.Thread(target=close, args=(module, part), name="close " + module, daemon=True)
            closer.start()
            closers.append(closer)
        for closer in closers:
            closer.join(max(0.0, end - time.monotonic()))
        for thread in self.threads:
            thread.join(max(0.0, min(0.2, end - time.monotonic())))
        for member in self.members:
            part = self.parts.get(member.module)
            if part is None:
                if not self.alone:
                    print("%s: not started (%s)" % (member.module, self.failed.get(member.module, "stopped before")),
                          flush=True)
                continue
            prefix = "" if self.alone else member.module + ": "
            print("\n".join(prefix + line for line in part.totals_lines()), flush=True)
        stuck = False
        watchers_done = True
        for module, part in parts:
            result = results.get(module)
            if result is None:  # still closing: every port of it unregistered by name
                stuck = True
                watchers_done = False
                part.unregister(part.port_names())
                continue
            done, unclosed = result
            watchers_done = watchers_done and done
            if unclosed:
                stuck = True
                part.unregister(unclosed)
        return stuck, watchers_done

    # -- the RPC port
    def answer(self, command):
        """The reply to ``command`` on the process's RPC port."""
        word = first_word(command)
        part = next(iter(self.parts.values()), None) if self.alone else None
        if part is not None:
            reply = part.answer(self.rpc.name, word, command)
            if reply is not None:
                return reply
        reply = yarp.Bottle()
        if word == "help":
            reply.addVocab32("many")
            for line in (part.help_lines(self.rpc.name) if part is not None else COMPOSED_HELP):
                reply.addString(line)
        elif word == "stats":
            if part is not None:
                if part.stats_many:
                    reply.addVocab32("many")
                part.stats_items(reply)
            else:
                reply.addVocab32("many")
                self._stats(reply)
        elif word in ("quit", "exit", "bye"):
            self.log("asked to quit on the RPC port")
            self.quit_asked = True
            self.rpc.after_reply = self.request_stop
            reply.addVocab32("bye")
        elif part is not None:
            return part.unknown(self.rpc.name, word)
        else:
            return unknown_reply(word)
        return reply

    def _stats(self, reply):
        """`stats` of a composed module: one list per bridge, its name first."""
        for member in self.members:
            item = reply.addList()
            item.addString(member.module)
            part = self.parts.get(member.module)
            if member.module in self.failed or part is None:
                item.addString("not running")
                item.addString(self.failed.get(member.module, "starting"))
            else:
                part.stats_items(item)
