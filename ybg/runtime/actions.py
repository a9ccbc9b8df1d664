"""Actions: the rclpy node of a config of ``[action]`` sections
(docs/actions.md), a part of the process shell (shell.py, ros2_shell.py).

A FollowJointTrajectory served from a robot's ports (``TrajectorySpec``):
the encoders come on a YARP state port (each Bottle's first values, one a
joint, converted to the goal's units), the set points go to a YARP port at
the action's rate (one float64 a joint, converted back). A goal is checked,
sampled and watched by trajectory.py (plain code, its own tests); here it
is carried out in time: one goal at a time, a new goal preempting the one
under way, a cancel holding the joints where they are, feedback at its
rate, and a goal aborted when the encoders go quiet. Nothing of a goal
refused reaches the robot.

Counted per action (goals, succeeded, aborted by code, canceled,
preempted), in ``stats`` on the module's RPC port, in the exit totals and on
/diagnostics."""

import collections
import threading
import time

import yarp
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor

from .trajectory import (CODE_NAMES, INVALID_GOAL, PATH_TOLERANCE_VIOLATED, SUCCESSFUL, Defaults, Point,  # ybgc:runtime-import
                         Refusal, Tolerance, accept)  # ybgc:runtime-import
from .connections import Watcher  # ybgc:runtime-import
from .yarp_values import _not_a, _number  # ybgc:runtime-import
from .ros2_shell import NODE_KINDS, SpecKind, run_alone  # ybgc:runtime-import
from .shell import Part  # ybgc:runtime-import

#: A FollowJointTrajectory served as ``action`` (``action_class``, named
#: ``type_name``) for ``joints``: encoders from the YARP port ``state`` (its
#: first len(joints) values; ``width``: the values it is declared to hold,
#: None: not declared), in the goal's units ``value * scale + offset`` (one
#: scale and offset a joint), set points to the YARP port ``command``,
#: ``rate`` a second; feedback ``feedback_rate`` a second; the defaults
#: ``path_tolerance``, ``goal_tolerance`` (None: not checked) and
#: ``goal_time_tolerance``; ``stale``: seconds without encoders that abort.
TrajectorySpec = collections.namedtuple(
    "TrajectorySpec", "name action action_class type_name joints state command width scales offsets rate "
                      "feedback_rate path_tolerance goal_tolerance goal_time_tolerance stale description")
#: A config of actions: its module, config file, node name, the default
#: prefix of its YARP ports, what --help says, and its actions.
ActionsSpec = collections.namedtuple("ActionsSpec", "module config node_name default_prefix description actions")

#: the counts of one action, in this order in `stats` and the totals
ACTION_COUNT_KEYS = ("goals", "succeeded", "aborted", "canceled", "preempted", "refused")
ACTION_TOTALS_LINE = ("action {name}: goals {goals}, succeeded {succeeded}, aborted {aborted}, canceled {canceled}, "
                      "preempted {preempted}, refused {refused}")
#: the result's error_string of a goal a newer one replaced
PREEMPTED_TEXT = "preempted by a newer goal"


def _seconds(duration):
    return duration.sec + duration.nanosec * 1e-9


class _StateReader(yarp.BottleCallback):
    """What YARP calls for each Bottle of the state port, in its own thread."""

    def __init__(self, encoders):
        yarp.BottleCallback.__init__(self)
        self.encoders = encoders

    def onRead(self, bottle, *reader):
        self.encoders.on_bottle(bottle)


class Encoders:
    """The newest reading of a state port: the joints' positions in the
    goal's units and when it came (the monotonic clock)."""

    def __init__(self, spec, local, log):
        self.spec = spec
        self.local = local
        self.log = log
        self.port = yarp.BufferedPortBottle()
        self.reader = None
        self.lock = threading.Lock()
        self.positions = None
        self.at = None
        self.count = 0
        self.said = False

    def open(self):
        self.port.setReadOnly()
        self.reader = _StateReader(self)
        self.port.useCallback(self.reader)
        return self.port.open(self.local)

    def on_bottle(self, bottle):
        try:
            n = len(self.spec.joints)
            if bottle.size() < n or (self.spec.width is not None and bottle.size() != self.spec.width):
                raise ValueError("%d values, %s" % (bottle.size(), "%d declared" % self.spec.width
                                                    if self.spec.width is not None else "%d joints" % n))
            values = []
            for k in range(n):
                x = _number(bottle.get(k))
                if x is None:
                    raise ValueError(_not_a(k, bottle.get(k), "not a number"))
                values.append(x * self.spec.scales[k] + self.spec.offsets[k])
            with self.lock:
                self.positions = values
                self.at = time.monotonic()
                self.count += 1
                first = self.count == 1
            if first:
                self.log("%s: encoder values coming, %d joints" % (self.spec.state, n))
        except Exception as e:  # never a traceback into YARP's thread
            if not self.said:
                self.said = True
                self.log("%s: a Bottle that does not fit, ignored (said once): %s" % (self.spec.state, e))

    def latest(self):
        """(positions, when) of the newest reading, or (None, None)."""
        with self.lock:
            return self.positions, self.at

    def close(self):
        self.port.interrupt()
        self.port.close()


class TrajectoryServer:
    """One FollowJointTrajectory: its ports, its action server, its goals."""

    def __init__(self, bridge, spec):
        self.bridge = bridge
        self.spec = spec
        prefix = bridge.prefix
        self.encoders = Encoders(spec, "%s/%s/state:i" % (prefix, spec.name), bridge.log)
        self.out_name = "%s/%s/command:o" % (prefix, spec.name)
        self.out = yarp.BufferedPortBottle()
        self.lock = threading.Lock()
        self.active = None   # the goal handle being carried out
        self.counts = dict.fromkeys(ACTION_COUNT_KEYS, 0)
        self.last = None     # how the last goal ended
        self.server = None
        self.has_index = hasattr(spec.action_class.Feedback(), "index")

    def open(self, node, group):
        if not self.encoders.open():
            return "cannot open the port %s" % self.encoders.local
        self.out.setWriteOnly()
        if not self.out.open(self.out_name):
            return "cannot open the port %s" % self.out_name
        try:
            self.server = ActionServer(node, self.spec.action_class, self.spec.action, self.execute,
                                       goal_callback=lambda goal: GoalResponse.ACCEPT,
                                       handle_accepted_callback=self.accepted,
                                       cancel_callback=lambda handle: CancelResponse.ACCEPT,
                                       callback_group=group)
        except Exception as e:  # an rclpy error: said, never a traceback
            return "cannot serve the ROS 2 action %s: %s" % (self.spec.action, e)
        return None

    def links(self):
        """(source, destination) of its YARP connections."""
        return [(self.spec.state, self.encoders.local), (self.out_name, self.spec.command)]

    # -- goals
    def accepted(self, handle):
        """A new goal: the one under way is preempted (it ends with PREEMPTED_TEXT
        at its next tick), and the new one carried out."""
        with self.lock:
            self.active = handle
        handle.execute()

    def _count(self, key):
        with self.lock:
            self.counts[key] += 1

    def _result(self, handle, code, text, how):
        result = self.spec.action_class.Result()
        result.error_code = code
        result.error_string = text
        if how == "succeed":
            handle.succeed()
        elif how == "cancel":
            handle.canceled()
        else:
            handle.abort()
        with self.lock:
            if self.active is handle:
                self.active = None
            self.last = "%s%s" % (CODE_NAMES.get(code, code), ": " + text if text else "")
        if self.bridge.verbose or how == "abort":
            ended = {"succeed": "succeeded", "cancel": "canceled"}.get(how, "aborted")
            self.bridge.log("action %s: goal %s %s (%s)" % (self.spec.name, ended, CODE_NAMES.get(code, code),
                                                           text or "done"))
        return result

    def _write(self, positions):
        """The set points ``positions`` (goal units, every joint) to the robot."""
        b = self.out.prepare()
        b.clear()
        for k, y in enumerate(positions):
            b.addFloat64((y - self.spec.offsets[k]) / self.spec.scales[k])
        self.out.write()

    def execute(self, handle):
        spec = self.spec
        goal = handle.request
        names = list(goal.trajectory.joint_names)
        self._count("goals")
        actual, at = self.encoders.latest()
        now = time.monotonic()
        if actual is None or now - at > spec.stale:
            self._count("refused")
            return self._result(handle, INVALID_GOAL, "no encoder values from %s %s: where the joints "
                                "are is not known" % (spec.state, "yet" if actual is None else
                                                      "for %.3f s" % (now - at)), "abort")
        points = [Point(_seconds(p.time_from_start), p.positions, p.velocities, p.accelerations)
                  for p in goal.trajectory.points]
        stamp = goal.trajectory.header.stamp
        start_stamp = 0.0
        if stamp.sec or stamp.nanosec:  # the header's time on the node's clock, as a time of the monotonic one
            ros_now = self.bridge.node.get_clock().now().nanoseconds * 1e-9
            start_stamp = now + (stamp.sec + stamp.nanosec * 1e-9 - ros_now)
        tolerances = [[(t.name, t.position, t.velocity, t.acceleration) for t in tols]
                      for tols in (goal.path_tolerance, goal.goal_tolerance)]
        n = len(spec.joints)
        defaults = Defaults(
            n, [Tolerance(spec.path_tolerance)] * n, [Tolerance(spec.goal_tolerance)] * n,
            spec.goal_time_tolerance)
        plan = accept(spec.joints, names, points, actual, now, start_stamp, tolerances[0], tolerances[1],
                                 _seconds(goal.goal_time_tolerance), defaults)
        if isinstance(plan, Refusal):
            self._count("refused")
            return self._result(handle, plan.code, plan.text, "abort")
        return self._carry_out(handle, plan, names)

    def _carry_out(self, handle, plan, names):
        spec = self.spec
        period = 1.0 / spec.rate
        feedback_period = 1.0 / spec.feedback_rate
        next_tick = time.monotonic()
        next_feedback = next_tick
        stop = self.bridge.stop_event
        while True:
            now = time.monotonic()
            with self.lock:
                preempted = self.active is not handle
            if preempted or stop.is_set():
                self._count("preempted" if preempted else "aborted")
                return self._result(handle, INVALID_GOAL, PREEMPTED_TEXT if preempted else
                                    "%s stopped" % self.bridge.name, "abort")
            actual, at = self.encoders.latest()
            if handle.is_cancel_requested:
                self._write(actual)  # held where the joints are
                self._count("canceled")
                return self._result(handle, SUCCESSFUL, "canceled: the joints held where they were",
                                    "cancel")
            if now - at > spec.stale:
                self._write(actual)
                self._count("aborted")
                return self._result(handle, PATH_TOLERANCE_VIOLATED, "no encoder values from %s for "
                                    "%.3f s (stale after %g s): the joints held at their last known positions"
                                    % (spec.state, now - at, spec.stale), "abort")
            desired = plan.sample(now)[0]
            self._write(desired)
            verdict = plan.verdict(now, actual)
            if now >= next_feedback or verdict is not None:
                self._feedback(handle, plan, names, now, actual)
                next_feedback = max(next_feedback + feedback_period, now)
            if verdict is not None:
                code, text = verdict
                if code == SUCCESSFUL:
                    self._count("succeeded")
                    return self._result(handle, code, text, "succeed")
                self._write(actual)
                self._count("aborted")
                return self._result(handle, code, text, "abort")
            next_tick += period
            wait = next_tick - time.monotonic()
            if wait < -period:  # fell behind (a busy machine): the next tick from now, no burst
                next_tick = time.monotonic()
            elif wait > 0:
                stop.wait(wait)

    def _feedback(self, handle, plan, names, now, actual):
        desired, got, error, index = plan.feedback(now, actual)
        f = self.spec.action_class.Feedback()
        f.header.stamp = self.bridge.node.get_clock().now().to_msg()
        f.joint_names = names
        f.desired.positions = desired
        f.actual.positions = got
        f.error.positions = error
        if self.has_index:
            f.index = index
        handle.publish_feedback(f)

    def status(self):
        with self.lock:
            counts = dict(self.counts)
            busy = self.active is not None
        positions, at = self.encoders.latest()
        if positions is None or time.monotonic() - at > self.spec.stale:
            level, text = DiagnosticStatus.WARN, "no encoder values from %s" % self.spec.state
        else:
            level, text = DiagnosticStatus.OK, "carrying out a goal" if busy else "ready"
        values = [(k, str(counts[k])) for k in ACTION_COUNT_KEYS] + [("last", self.last or "none")]
        return level, text, values

    def close(self):
        if self.server is not None:
            self.server.destroy()
        self.encoders.close()
        self.out.interrupt()
        self.out.close()


class ActionsBridge(Part):
    """The actions of one config inside an rclpy node: a part of the
    process shell, alone or among the bridges of one process."""

    stats_many = False

    def __init__(self, spec, node, prefix, verbose=False):
        self.spec = spec
        self.name = spec.module
        self.node = node
        self.prefix = prefix
        self.verbose = verbose
        self.stop_event = threading.Event()
        self.servers = [TrajectoryServer(self, a) for a in spec.actions]
        self.watcher = None

    def open(self, rpc=None):
        group = ReentrantCallbackGroup()
        for s in self.servers:
            failed = s.open(self.node, group)
            if failed:
                return failed
        own = [s.encoders.port for s in self.servers] + [s.out for s in self.servers]
        self.watcher = Watcher([(src, dst, None) for s in self.servers for src, dst in s.links()], self.log, own)
        self.watcher.start()
        for a in self.spec.actions:
            self.log(a.description)
        if rpc is not None:
            self.log("its RPC port: %s (help, stats, quit)" % rpc)
        return None

    def serve(self):
        self.stop_event.wait()

    def request_stop(self, *_):
        self.stop_event.set()

    def halt(self, within):
        """No goal goes on: the one under way ends (aborted, the module stops)
        at its next tick."""
        self.stop_event.set()

    def port_names(self):
        return [s.encoders.local for s in self.servers] + [s.out_name for s in self.servers]

    def close(self):
        self.stop_event.set()
        watcher_done = self.watcher.stop() if self.watcher is not None else True
        for s in self.servers:
            s.close()
        return watcher_done, []

    def help_lines(self, port):
        return ("help: this list", "stats: the counts of each action: (action NAME goals N succeeded N ...)",
                "quit: stop the module (it closes its ports and exits 0, as on SIGINT)")

    def stats_items(self, reply):
        for s in self.servers:
            with s.lock:
                counts = dict(s.counts)
            item = reply.addList()
            item.addString("action")
            item.addString(s.spec.name)
            for k in ACTION_COUNT_KEYS:
                item.addString(k)
                item.addInt64(counts[k])

    def totals_lines(self):
        out = ["totals:"]
        for s in self.servers:
            with s.lock:
                out.append("  " + ACTION_TOTALS_LINE.format(name=s.spec.name, **s.counts))
        return out

    def statuses(self, now):
        return [("action %s" % s.spec.name,) + s.status() for s in self.servers]


class ActionsKind(SpecKind):
    """A node of actions as the shell runs it (ros2_shell.SpecKind): its
    parameters and its bridge, whose goals each run in an executor thread."""

    verbose_text = "print every goal and how it ended"
    diagnostics_text = "publish the actions' counts on /diagnostics"

    def part(self, node, options):
        return ActionsBridge(self.spec, node, options.prefix, options.verbose)

    def executor(self):
        """Threads for the executor: a goal runs in one until it ends, and a
        newer goal, a cancel or a result request must not wait for it."""
        return MultiThreadedExecutor(num_threads=4 + 4 * len(self.spec.actions))


NODE_KINDS[ActionsSpec] = ActionsKind.of_module


def run_actions(spec, argv=None):
    """Start rclpy, YARP and the node's action servers; run until SIGINT,
    SIGTERM or `quit`; the exit status (0 when stopped, 1 when something
    could not open, 2 for a bad parameter)."""
    return run_alone(ActionsKind(spec), argv)


__all__ = ["TrajectorySpec", "ActionsSpec", "run_actions"]
