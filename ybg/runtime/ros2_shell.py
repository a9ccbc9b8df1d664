"""The rclpy side of the process shell (shell.py), one for every kind of
bridge run in a ROS 2 node (a stream, ros2_io; a node of commands,
services), alone or several in one process: ROS 2 started from the command
line, a node for each bridge with its own name, its parameters declared and
checked (a bad one stops the process before anything opens, status 2), its
state on /diagnostics, its executor in a thread of its own, and the nodes
destroyed within the exit's budget (docs/runtime.md, "Diagnostics (ROS
2)"; docs/compose.md)."""

import argparse
import collections
import os
import sys
import threading
import time

import rclpy
import rclpy.utilities
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.clock import Clock, ClockType
from rclpy.executors import MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.signals import SignalHandlerOptions

from .shell import SWITCH_INTERVAL, Member, Process, describe, load_failure  # ybgc:runtime-import

#: the seconds between two /diagnostics messages, unless the parameter
#: diagnostic_updater.period says (diagnostic_updater's own default)
DIAGNOSTICS_PERIOD = 1.0
#: the longest wait of a composed node's executor for an event: a dozen
#: executors waking ten times a second each with nothing to do would take a
#: tenth of a core
COMPOSED_SPIN_TIMEOUT = 1.0
#: ... of a node alone
SPIN_TIMEOUT = 0.1


# --- parameters --------------------------------------------------------------------

class ParameterError(ValueError):
    """A parameter the node refuses: why (the process stops, status 2)."""


#: one parameter of a node: its name, its default, its description (the
#: node's ParameterDescriptor), ``check(value, name)`` -> its value or
#: ParameterError, and the lines --help gives it
Parameter = collections.namedtuple("Parameter", "name default description check help")


def number(value, name):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ParameterError("parameter %s must be a number, got %r" % (name, value))
    return float(value)


def flag(value, name):
    if not isinstance(value, bool):
        raise ParameterError("parameter %s must be true or false" % name)
    return value


def prefix(value, name):
    if not isinstance(value, str) or not value.startswith("/"):
        raise ParameterError("parameter %s must be a string starting with /" % name)
    return value


def period(value, name):
    value = number(value, name)
    if value <= 0:
        raise ParameterError("parameter %s must be positive" % name)
    return value


def node_parameters(default_prefix, verbose, diagnostics):
    """The parameters every node has: its YARP ports' prefix, ``verbose``
    and ``diagnostics`` (each (description, help text)), /diagnostics' period."""
    return (
        Parameter("prefix", default_prefix, "prefix of the node's own YARP port names", prefix,
                  "  prefix        prefix of the node's own YARP port names (default: %s)\n" % default_prefix),
        Parameter("verbose", False, verbose[0], flag, "  verbose       %s (default: false)\n" % verbose[1]),
        Parameter("diagnostics", True, diagnostics, flag,
                  "  diagnostics   %s (default: true)\n" % diagnostics),
        Parameter("diagnostic_updater.period", DIAGNOSTICS_PERIOD, "seconds between two /diagnostics messages",
                  period, "  diagnostic_updater.period\n"
                          "                seconds between two /diagnostics messages (default: 1)\n"),
    )


def declare(node, parameters):
    """{name: value} of ``parameters`` declared on ``node`` and checked
    (ParameterError), in their order; ``diagnostics_period``: the period of
    /diagnostics, None when turned off."""
    values = {}
    for p in parameters:
        descriptor = ParameterDescriptor(description=p.description, dynamic_typing=True)
        values[p.name] = p.check(node.declare_parameter(p.name, p.default, descriptor).value, p.name)
    values["diagnostics_period"] = values["diagnostic_updater.period"] if values["diagnostics"] else None
    return values


def epilog(parameters, more=""):
    """What --help says of ``parameters`` (and ``more`` lines after them)."""
    return "ROS parameters (--ros-args -p NAME:=VALUE):\n" + "".join(p.help for p in parameters) + more


def _parse_command_line(prog, description, text, args):
    parser = argparse.ArgumentParser(prog=os.path.basename(prog), description=description, epilog=text,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_args(args)


# --- a kind of bridge in a node ------------------------------------------------------

class NodeKind:
    """A kind of bridge run in an rclpy node: what the shell asks of one
    bridge to run it, alone (its module's ``main``) or composed (its module
    loaded). A kind overrides each (ros2_io.StreamNode, services.CommandsKind)."""

    #: its module's name
    name = "bridge"
    #: its node's name
    node_name = "bridge"
    #: the text of its --help
    description = ""

    def parameters(self):
        """Its node's parameters (Parameter)."""
        raise NotImplementedError

    def epilog(self):
        """What --help says after the usage: the parameters."""
        return epilog(self.parameters())

    def options(self, node):
        """Its parameters declared on ``node`` and checked (ParameterError)."""
        return argparse.Namespace(**{k.replace(".", "_"): v for k, v in declare(node, self.parameters()).items()})

    def part(self, node, options):
        """The bridge (a shell.Part) in ``node`` with ``options``."""
        raise NotImplementedError

    def executor(self):
        """The executor that runs its node's callbacks."""
        return SingleThreadedExecutor()


class SpecKind(NodeKind):
    """A kind whose generated module holds a ``SPEC`` naming its module,
    node, description, default prefix and config (a node of commands, of
    actions): its parameters are a node's own (prefix, verbose, diagnostics,
    diagnostic_updater.period), ``verbose`` saying ``verbose_text``."""

    verbose_text = "print what it does"
    diagnostics_text = "publish its counts on /diagnostics"

    def __init__(self, spec):
        self.spec = spec
        self.name = spec.module
        self.node_name = spec.node_name
        self.description = "\n".join(spec.description)

    @classmethod
    def of_module(cls, module):
        return cls(module.SPEC)

    def parameters(self):
        return node_parameters(self.spec.default_prefix, (self.verbose_text,) * 2, self.diagnostics_text)

    def epilog(self):
        return epilog(self.parameters(), "Generated by ybgc from %s." % self.spec.config)

    def options(self, node):
        values = declare(node, self.parameters())
        return argparse.Namespace(prefix=values["prefix"], verbose=values["verbose"],
                                  diagnostics_period=values["diagnostics_period"])


#: the kind of a bridge module by its SPEC's type (each kind's runtime module
#: adds itself: ros2_io, services, actions)
NODE_KINDS = {}


def node_kind(module):
    """The NodeKind of a bridge's generated module (``module.SPEC``'s kind)."""
    for spec_type, kind in NODE_KINDS.items():
        if isinstance(module.SPEC, spec_type):
            return kind(module)
    raise TypeError("%s is no bridge of a kind this runtime knows" % type(module.SPEC).__name__)


# --- /diagnostics ------------------------------------------------------------------

class Diagnostics:
    """Publishes the state of a bridge (its part's ``statuses(now)``: (name,
    level, message, key-values) each) on /diagnostics as a DiagnosticArray
    every ``period`` seconds of the steady clock, as diagnostic_updater
    does: each status named ``<node>: <name>``, hardware_id the module's name."""

    def __init__(self, part, node, period):
        self.part = part
        self.node = node
        self.name = node.get_name()
        self.publisher = node.create_publisher(DiagnosticArray, "/diagnostics", 1)
        self.timer = node.create_timer(period, self.publish, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def array(self):
        """The DiagnosticArray of the bridge's state now."""
        statuses = [DiagnosticStatus(level=level, name="%s: %s" % (self.name, name), message=text,
                                     hardware_id=self.part.name, values=[KeyValue(key=k, value=v) for k, v in values])
                    for name, level, text, values in self.part.statuses(time.monotonic())]
        msg = DiagnosticArray(status=statuses)
        msg.header.stamp = self.node.get_clock().now().to_msg()
        return msg

    def publish(self):
        self.publisher.publish(self.array())


# --- executors ---------------------------------------------------------------------

class Spinner(threading.Thread):
    """Runs a node's executor (its subscriptions, services, timers, the
    /clock of simulated time) until stopped; the first error is said."""

    def __init__(self, node, executor, log, timeout=SPIN_TIMEOUT):
        threading.Thread.__init__(self, name="ros 2 executor", daemon=True)
        self.executor = executor
        self.executor.add_node(node)
        self.log = log
        self.timeout = timeout  # the longest wait for an event (a stop wakes it: wake())
        self.done = threading.Event()

    def wake(self):
        """Its executor's wait ends at once (a task that does nothing)."""
        self.executor.create_task(lambda: None)

    def run(self):
        reported = False
        while not self.done.is_set():
            try:
                self.executor.spin_once(timeout_sec=self.timeout)
            except Exception as e:
                if self.done.is_set() or not rclpy.ok():
                    break
                if not reported:
                    reported = True
                    self.log("ROS 2 executor: %s" % e)

    def stop(self, within=0.5):
        """The executor stopped; the callbacks under way (the answer of a
        call in flight) finish within ``within`` seconds."""
        end = time.monotonic() + within
        self.done.set()
        self.wake()
        closer = threading.Thread(target=self.executor.shutdown, kwargs={"timeout_sec": within}, daemon=True)
        closer.start()
        closer.join(within)
        if self.is_alive():
            self.join(max(0.0, end - time.monotonic()))


# --- running nodes -------------------------------------------------------------------

def run_alone(kind, argv=None):
    """Run one bridge of ``kind`` in its node until SIGINT, SIGTERM or `quit`
    on its RPC port; the exit status (1: something could not open, 2: a bad
    parameter or ROS 2 could not start; nothing opened)."""
    return _run(kind.name, (Member(kind.name),), argv, lambda member: kind, True,
                lambda prog, args: _parse_command_line(prog, kind.description, kind.epilog(), args))


def run_composed(name, members, argv, load):
    """Run the bridges ``members`` (each loaded by ``load(member)``, a node
    module of the ``ros2`` backend of any kind) in this process: one rclpy
    context (one DDS participant), one node per bridge with its own name,
    parameters, executor thread and /diagnostics status; one RPC port
    ``/<name>/rpc:i``. Until SIGINT, SIGTERM or `quit`; the exit status
    (2: a bad parameter, nothing opened)."""
    text = ("Each bridge is a node of its own name with the parameters of its node alone (rate,\n"
            "timeout, prefix, verbose, accept, diagnostics, diagnostic_updater.period,\n"
            "qos_overrides.*, use_sim_time), given for one node as\n"
            "  --ros-args -p NODE:NAME:=VALUE   or in a --params-file keyed by node name\n"
            "(-p NAME:=VALUE gives every node the value). `yarp rpc /%s/rpc:i` answers\n"
            "help, stats and quit." % name)
    sys.setswitchinterval(SWITCH_INTERVAL)
    return _run(name, members, argv, lambda member: node_kind(load(member)), False,
                lambda prog, args: _parse_command_line(prog, describe(name, members), text, args))


def _run(name, members, argv, kind_of, alone, parse_command_line):
    argv = list(sys.argv[1:] if argv is None else argv)
    process = Process(name, members, alone)
    process.handle_signals()  # a stop while starting: remembered, the bridges stop once started
    prog = sys.argv[0] if sys.argv and sys.argv[0] else name
    parse_command_line(prog, rclpy.utilities.remove_ros_args([prog] + argv)[1:])
    try:
        rclpy.init(args=[prog] + argv, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as e:
        print("%s: cannot start ROS 2: %s" % (name, e), flush=True)
        return 2
    nodes = []
    spinners = {}  # part -> the Spinner of its node
    finished = []

    def halted(part):
        spinner = spinners.get(part)
        if spinner is not None:
            spinner.stop(max(0.05, min(0.4, process.time_left())))

    def finish(stuck):
        # the nodes destroyed within the exit's budget (each entity destroyed
        # is told to every participant, which on a busy machine can take
        # seconds for a dozen nodes): else the process exits at once, its
        # ports closed and its totals printed already
        finished.append(True)
        if stuck:
            return
        done = threading.Event()

        def stop_ros():
            _destroy(spinners.values(), nodes)
            rclpy.try_shutdown()
            done.set()

        threading.Thread(target=stop_ros, name="stop ROS 2", daemon=True).start()
        if not done.wait(max(0.1, process.time_left())):
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(1 if process.failed else 0)

    process.halted = halted
    try:
        prepared = []
        for member in members:
            try:
                kind = kind_of(member)
            except (Exception, SystemExit) as e:
                process.refuse(member, load_failure(member, e))
                continue
            node = rclpy.create_node(kind.node_name)
            nodes.append(node)
            try:
                options = kind.options(node)
            except ParameterError as e:
                print("%s: %s" % (kind.name, e), flush=True)
                return 2
            try:
                part = kind.part(node, options)
            except Exception as e:
                process.refuse(member, "%s: %s" % (type(e).__name__, e))
                continue
            prepared.append((member, kind, node, part, options))
        if not process.connect():
            return 1
        rpc = prepared[0][4].prefix + "/rpc:i" if alone and prepared else "/%s/rpc:i" % name
        if not process.open_rpc(rpc):
            return 1
        for member, kind, node, part, options in prepared:
            if process.stop_event.is_set() and not alone:
                break
            if not process.start(member, part):
                continue
            if options.diagnostics_period:
                Diagnostics(part, node, options.diagnostics_period)
            spinner = Spinner(node, kind.executor(), part.log, SPIN_TIMEOUT if alone else COMPOSED_SPIN_TIMEOUT)
            spinner.start()
            spinners[part] = spinner
        return process.serve(finish)
    finally:
        if not finished:
            _destroy(spinners.values(), nodes)
            rclpy.try_shutdown()


def _destroy(spinners, nodes):
    """Every executor stopped at once, then the nodes destroyed."""
    spinners = list(spinners)
    for spinner in spinners:
        spinner.done.set()
        spinner.wake()
    end = time.monotonic() + 1.0
    for spinner in spinners:
        spinner.join(max(0.0, end - time.monotonic()))
    for spinner in spinners:
        spinner.executor.shutdown(timeout_sec=0.05)
    for node in nodes:
        node.destroy_node()
