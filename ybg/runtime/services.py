"""Commands: the rclpy node of a config of ``[service]`` sections
(docs/services.md), between YARP RPC ports and ROS 2 services, both ways,
as a part of the process shell (shell.py, ros2_shell.py), alone or among
the bridges of one process.

- A ROS 2 service served by the node (``ServeRos2``): each request becomes
  a command Bottle (the node's function), sent to a YARP RPC port
  (callers.YarpCaller: the calls to one port one after another, each
  within its own deadline); the reply fills the response (the node's
  function).
- A YARP RPC port served by the node (``ServeYarp``, shell.ServedPort): a
  command whose first word names a service fills the request from its
  arguments, calls the ROS 2 service (callers.Ros2Caller) and replies the
  Bottle the node's function builds; ``help`` lists the commands.

Never hang, never lie: every call ends within its timeout, with the
answer of success or the failure answer (the node's function, given the
reason): no server, no answer in time, a reply or command that does not
fit. Counted per service, in ``stats`` on the module's RPC port, in the
exit totals and on /diagnostics.

A node imports its names from here: the spec tables and the helpers of
its functions (commands.py), ``run_commands``."""

import threading
import time

import yarp
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor

# a node imports from here its spec tables and the helpers of its functions
# (CommandsSpec, Conv, PortSpec, ServeRos2, ServeYarp, add_converted,
# add_value, add_values), and run_commands
from .base import add_value, add_values  # ybgc:runtime-import
from .callers import Ros2Caller, YarpCaller  # ybgc:runtime-import
from .commands import COMMANDS_HELP, STATS_KEYS, STOPPED, CommandsSpec, Conv, Counts, Elements  # ybgc:runtime-import
from .commands import PortSpec, ServeRos2, ServeYarp, Unfit, add_converted, reason_text  # ybgc:runtime-import
from .commands import stats_reply, totals_lines  # ybgc:runtime-import
from .ros2_shell import DIAGNOSTICS_PERIOD, NODE_KINDS, SpecKind, run_alone  # ybgc:runtime-import
from .shell import Part, ServedPort, first_word  # ybgc:runtime-import

class CommandsBridge(Part):
    """The services of one config of commands inside an rclpy node: a part
    of the process shell (shell.Part), alone (the module's RPC port answers
    its commands too when the config serves them there) or among the
    bridges of one process."""

    stats_many = False

    def __init__(self, spec, node, prefix, verbose=False):
        self.spec = spec
        self.name = spec.module
        self.node = node
        self.prefix = prefix
        self.verbose = verbose
        self.stop_event = threading.Event()
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

    def _failure(self, s, key, text):
        """A call that failed: counted, said (the first, or every one when
        verbose), and its failure answer."""
        self._count(s, key, text)
        if self.verbose or self.counts[s.name].failed == 1:
            more = "" if self.verbose else "; further failures are only counted"
            self.log("service %s: %s%s" % (s.name, text, more))
        return s.failure(s.srv_class.Response(), text)

    def _answered(self, s, command, reply):
        self._count(s)
        if self.verbose:
            self.log("service %s: %s -> %s" % (s.name, command.toString(), reply.toString()))

    # -- a ROS 2 service served, a YARP port called
    def _serve(self, serve, s, what):
        """``serve(s, what, deadline)``, a call of ``s`` counted among those
        in flight, its deadline its arrival + its timeout."""
        arrival = time.monotonic()
        self._active(1)
        try:
            return serve(s, what, arrival + s.timeout)
        finally:
            self._active(-1)

    def serve_ros2(self, s, request, response):
        """The rclpy service's callback (an executor thread each)."""
        return self._serve(self._serve_ros2, s, request)

    def _serve_ros2(self, s, request, deadline):
        self._call_started(s)
        try:
            command = s.command(request)
        except Exception as e:
            text = reason_text(s.reasons["unfit_reply"], "nothing",
                               "the request does not fit the command (%s)" % e)
            return self._failure(s, "unfit", text)
        reply, key = self.callers[s.port].call(command, deadline, self.stop_event)
        if key is not None:
            return self._failure(s, key, self._reason(s, key))
        try:
            e = Elements(reply, 0, s.types, s.converters, s.true_words)
            out = s.fill(reply, e, s.srv_class.Response())
        except (Unfit, AssertionError, TypeError, ValueError, OverflowError, IndexError) as e:
            text = reason_text(s.reasons["unfit_reply"], reply.toString(), str(e))
            return self._failure(s, "unfit", text)
        self._answered(s, command, reply)
        return out

    # -- a YARP port served, a ROS 2 service called
    def answer(self, port, word, command):
        """The reply to a command of a service it serves on ``port``, else None."""
        s = self.by_port.get(port, {}).get(word)
        return None if s is None else self.serve_yarp(s, command)

    def help_lines(self, port):
        return self.help.get(port) or COMMANDS_HELP

    def unknown(self, port, word):
        """On a served port: the failure reply (of its first command), and why."""
        text = self.spec.unknown_command.replace("{word}", word)
        commands = self.by_port.get(port)
        if commands:
            first = next(iter(commands.values()))
            return first.failure(first.srv_class.Response(), text)
        reply = yarp.Bottle()
        reply.addVocab32("fail")
        reply.addString(text)
        return reply

    def _served(self, port, command):
        """The reply to a command on a port it serves (not the module's RPC port)."""
        word = first_word(command)
        reply = self.answer(port, word, command)
        if reply is not None:
            return reply
        if word != "help":
            return self.unknown(port, word)
        reply = yarp.Bottle()
        reply.addVocab32("many")
        for line in self.help_lines(port):
            reply.addString(line)
        return reply

    def serve_yarp(self, s, command):
        """A command of ``s`` on a port it serves (in the connection's thread)."""
        return self._serve(self._serve_yarp, s, command)

    def _serve_yarp(self, s, command, deadline):
        self._call_started(s)
        try:
            args = Elements(command, 1, s.types, s.converters, s.true_words)
            request = s.request(args, s.srv_class.Request())
        except (Unfit, AssertionError, TypeError, ValueError, OverflowError, IndexError) as e:
            return self._failure(s, "unfit", reason_text(s.reasons["bad_arguments"], why=str(e)))
        response, key = self.ros_callers[s.name].call(request, deadline, self.stop_event)
        if key is not None:
            return self._failure(s, key, self._reason(s, key))
        try:
            reply = s.reply(response)
        except (AssertionError, TypeError, ValueError, OverflowError, IndexError) as e:
            return self._failure(s, "unfit", reason_text(s.reasons["unfit_reply"], str(response), str(e)))
        self._answered(s, command, reply)
        return reply

    # -- a part of the process
    def open(self, rpc=None):
        """Open every port, service and client (``rpc``: the module's RPC
        port, the process's, whose commands it answers too): None, or what
        could not open."""
        group = ReentrantCallbackGroup()
        local_names = {}
        timeouts = {}
        for s in self.spec.services:
            if isinstance(s, ServeRos2):
                local_names.setdefault(s.port, "%s/%s/rpc:o" % (self.prefix, s.name))
                timeouts[s.port] = max(timeouts.get(s.port, 0.0), float(s.timeout))
        for port, local in local_names.items():
            caller = YarpCaller(local, port, timeouts[port], self.log)
            if not caller.open():
                return "cannot open the port %s" % local
            self.callers[port] = caller
        for p in self.spec.ports:
            if p.name == rpc:
                continue
            served = ServedPort(p.name, lambda command, name=p.name: self._served(name, command), self.log)
            if not served.open():
                return "cannot open the port %s" % p.name
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
                return "cannot %s the ROS 2 service %s: %s" % ("serve" if isinstance(s, ServeRos2) else "call",
                                                               s.service, e)
        for s in self.spec.services:
            self.log(s.description)
        if rpc is not None:
            self.log("its RPC port: %s (help, stats, quit)" % rpc)
        return None

    def serve(self):
        """Its calls are answered in its node's executor threads and its
        ports' YARP threads: it waits until stopped."""
        self.stop_event.wait()

    def request_stop(self, *_):
        self.stop_event.set()

    def halt(self, within):
        """Stop taking calls; the calls in flight are answered (the failure
        answer, ``stopped``) within ``within`` seconds."""
        self.stop_event.set()
        for caller in self.callers.values():
            caller.stop()
        for served in self.served:
            served.stopping = True
        end = time.monotonic() + within
        while time.monotonic() < end:
            with self.lock:
                if self.active == 0:
                    break
            time.sleep(0.01)

    def port_names(self):
        return [p.name for p in self.served] + [c.local for c in self.callers.values()]

    def close(self):
        """Close every port within 1 s: (True, the names of those not closed)."""
        self.halt(0.0)
        closed = []
        names = self.port_names()

        def close_all():
            for served in self.served:
                served.stop()
            for served in self.served:
                served.close()
                closed.append(served.name)
            for caller in self.callers.values():
                if caller.busy:
                    continue  # a write waiting for its server: unregistered by name
                caller.close()
                closed.append(caller.local)

        closer = threading.Thread(target=close_all, name="close ports", daemon=True)
        closer.start()
        closer.join(1.0)
        return True, [name for name in names if name not in closed]

    def unregister(self, names):
        for name in names:
            yarp.Network.unregisterName(name)

    def stats_items(self, reply):
        """What `stats` answers of it: one list per service."""
        with self.lock:
            stats_reply(reply, self.spec.services, self.counts)

    def totals_lines(self):
        with self.lock:
            return ["totals:"] + totals_lines(self.spec.services, self.counts)

    def statuses(self, now):
        """/diagnostics: one status per service."""
        with self.lock:
            return [("service %s" % s.name,) + service_status(s, self.counts[s.name]) for s in self.spec.services]


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


class CommandsKind(SpecKind):
    """A node of commands as the shell runs it (ros2_shell.SpecKind): its
    parameters (prefix, verbose, diagnostics, diagnostic_updater.period)
    and its bridge, whose requests each wait in an executor thread."""

    verbose_text = "print every call and its answer"
    diagnostics_text = "publish the services' counts on /diagnostics"

    def part(self, node, options):
        return CommandsBridge(self.spec, node, options.prefix, options.verbose)

    def executor(self):
        """Threads for the executor: each request of a ROS 2 service served
        waits in one for its YARP call, so that a slow server delays no other."""
        served = sum(1 for s in self.spec.services if isinstance(s, ServeRos2))
        return MultiThreadedExecutor(num_threads=min(64, 4 + 8 * served))


NODE_KINDS[CommandsSpec] = CommandsKind.of_module


def run_commands(spec, argv=None):
    """Start rclpy, YARP and the node's services; run until SIGINT, SIGTERM
    or `quit`; the exit status (0 when stopped, 1 when something could not
    open, 2 for a bad parameter)."""
    return run_alone(CommandsKind(spec), argv)
