"""The ROS 2 side of the ros2 backend's nodes: the bridge run inside an
rclpy node. ROS 2 topics as mux inputs, a typed message filled field by
field and published with the config's QoS, stamps from the node's clock
(use_sim_time is respected), the node's parameters in place of the
command-line options, QoS overridden by ``qos_overrides`` parameters, and the
bridge's totals on /diagnostics; camera images both ways (sensor_msgs/Image
topics read and published, with their CameraInfo: the frames are images.py's)
(docs/runtime.md)."""

import argparse
import collections
import operator
import os
import signal
import sys
import threading
import time

import rclpy
import rclpy.time
import rclpy.utilities
import yarp
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.clock import Clock, ClockType
from rclpy.event_handler import (PublisherEventCallbacks, SubscriptionEventCallbacks,
                                 UnsupportedEventTypeError)
from rclpy.executors import SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions, QoSPolicyKind
from rclpy.signals import SignalHandlerOptions

from .compose import SWITCH_INTERVAL, Composer, describe, load_failure  # ybgc:runtime-import
from .core import _FLOAT_TYPES, _INT_TYPES, InputState, call_count, parse_accept, seconds_to_ns  # ybgc:runtime-import
from .core import INCOMPATIBLE_QOS_TEXT, INCOMPATIBLE_TYPE_TEXT, EndpointEvents  # ybgc:runtime-import
from .core import PUBLISHERS_TEXT, SUBSCRIBERS_TEXT  # ybgc:runtime-import
from .images import ImageInput, append_rows, fit_calibration, frame_of, message_frame  # ybgc:runtime-import
from .yarp_io import YarpBridge  # ybgc:runtime-import


#: Subscriptions keep only the newest message (like the YARP inputs); best
#: effort matches reliable and best-effort publishers alike.
INPUT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                       reliability=ReliabilityPolicy.BEST_EFFORT,
                       durability=DurabilityPolicy.VOLATILE)

#: The QoS policies a user overrides on top of the config's, as rclcpp and
#: rclpy nodes offer: read-only parameters
#: ``qos_overrides./<topic>.publisher.<policy>`` (``.subscription.`` for
#: the inputs), given at start (``--ros-args -p ...`` or a parameter file).
QOS_OVERRIDES = QoSOverridingOptions(policy_kinds=(
    QoSPolicyKind.HISTORY, QoSPolicyKind.DEPTH, QoSPolicyKind.RELIABILITY,
    QoSPolicyKind.DURABILITY))


class FillError(ValueError):
    """The converted values do not fit a field of the message."""


# --- values of the right Python type for each field ----------------------------

def floats(values):
    return [float(x) for x in values]


def ints(values):
    return [int(x) for x in values]


def bools(values):
    return [bool(x) for x in values]


def strs(values):
    return [str(x) for x in values]


def byte(x):
    return bytes((int(x),))


def byte_list(values):
    return [bytes((int(x),)) for x in values]


def sized(values, size, field):
    if len(values) != size:
        raise FillError("field %s holds exactly %d values, got %d" % (field, size, len(values)))
    return values


def bounded(values, bound, field):
    if len(values) > bound:
        raise FillError("field %s holds at most %d values, got %d" % (field, bound, len(values)))
    return values


class Stamps:
    """The times of one message: the node's clock read once (ROS time, so
    simulated time with use_sim_time), and the newest envelope stamp of
    each mux's inputs."""

    def __init__(self, now, envelopes):
        self._now = now
        self._envelopes = envelopes
        self.seconds = now.nanoseconds / 1e9

    def now(self):
        return self._now.to_msg()

    def envelope(self, mux):
        """The newest envelope stamp of ``mux``'s inputs (the node's clock if none has one)."""
        t = self._envelopes.get(mux)
        ns = None if t is None else seconds_to_ns(t)
        if ns is None:
            return self._now.to_msg()
        return rclpy.time.Time(nanoseconds=ns).to_msg()


# --- incompatible peers ----------------------------------------------------------

def _policy_value(value):
    """A reliability or durability policy as rmw names it (``reliable``, ``transient_local``)."""
    name = getattr(value, "name", None)
    return name.lower() if name else "unknown"


def _qos_words(qos):
    return "%s, %s" % (_policy_value(qos.reliability), _policy_value(qos.durability))


def _conflicts(publisher, subscription):
    """Whether a publisher of QoS ``publisher`` gives nothing to a subscription
    of QoS ``subscription`` by their reliability or durability."""
    return ((publisher.reliability == ReliabilityPolicy.BEST_EFFORT
             and subscription.reliability == ReliabilityPolicy.RELIABLE)
            or (publisher.durability == DurabilityPolicy.VOLATILE
                and subscription.durability == DurabilityPolicy.TRANSIENT_LOCAL))


class EndpointWatch:
    """Listens for the incompatible-QoS and incompatible-type events of one
    ROS 2 publisher or subscription (``kind``) of ``topic``: counted in its
    EndpointEvents (the bridge's `stats`, exit totals and /diagnostics), the
    first of each kind said with the peer's QoS (the first peer in the graph
    whose reliability or durability does not match) or type hash."""

    def __init__(self, bridge, node, kind, topic, type_name):
        self.bridge = bridge
        self.node = node
        self.kind = kind
        self.peer = "subscription" if kind == "publisher" else "publisher"
        self.type_name = type_name
        self.counts = EndpointEvents(kind, topic)
        bridge.endpoints.append(self.counts)
        self.entity = None  # its rclpy publisher or subscription, once made

    def callbacks(self, make, **events):
        """``make(callbacks)`` (PublisherEventCallbacks or
        SubscriptionEventCallbacks) with its events and ``events``; again
        without ``events`` on an rmw that has no such events (rclpy leaves
        out an incompatible-QoS or -type event the rmw lacks by itself)."""
        own = dict(incompatible_qos=self.on_qos, incompatible_type=self.on_type)
        try:
            return make(**own, **events)
        except UnsupportedEventTypeError:
            return make(**own)

    def _peers(self):
        """The graph's endpoints of the other kind on its topic, and its own."""
        topic = self.entity.topic_name
        if self.kind == "publisher":
            return self.node.get_subscriptions_info_by_topic(topic), self.node.get_publishers_info_by_topic(topic)
        return self.node.get_publishers_info_by_topic(topic), self.node.get_subscriptions_info_by_topic(topic)

    def _ours(self, own):
        for e in own:
            if e.node_name == self.node.get_name() and e.node_namespace == self.node.get_namespace():
                return e
        return None

    def on_qos(self, info):
        self.bridge.on_incompatible(self.counts, "qos", info.total_count, lambda: self._qos_text(info))

    def on_type(self, info):
        self.bridge.on_incompatible(self.counts, "type", info.total_count, self._type_text)

    def _qos_text(self, info):
        ours = self.entity.qos_profile if self.entity is not None else None
        theirs = "unknown (not in the graph yet)"
        if ours is not None:
            peers = self._peers()[0]
            pick = [e for e in peers if (_conflicts(ours, e.qos_profile) if self.kind == "publisher"
                                         else _conflicts(e.qos_profile, ours))] or peers
            if pick:
                theirs = _qos_words(pick[0].qos_profile)
        try:
            policy = QoSPolicyKind(int(info.last_policy_kind)).name.lower()
        except ValueError:
            policy = "policy %s" % info.last_policy_kind
        return INCOMPATIBLE_QOS_TEXT.format(kind=self.kind, topic=self.counts.topic, peer=self.peer, policy=policy,
                                            theirs=theirs, ours="unknown" if ours is None else _qos_words(ours))

    def _type_text(self):
        theirs = ours = "unknown"
        if self.entity is not None:
            peers, own = self._peers()
            mine = self._ours(own)
            if mine is not None:
                ours = str(mine.topic_type_hash)
            other = [e for e in peers if str(e.topic_type_hash) != ours]
            if other:
                theirs = str(other[0].topic_type_hash)
        return INCOMPATIBLE_TYPE_TEXT.format(kind=self.kind, topic=self.counts.topic, peer=self.peer,
                                             type=self.type_name, theirs=theirs, ours=ours)


def event_values(counts):
    """The key-values of /diagnostics of a ROS 2 endpoint's incompatible peers."""
    return (("incompatible QoS", str(counts.qos)), ("incompatible type", str(counts.type)))


# --- ROS 2 topics as mux inputs ------------------------------------------------

def _leaf_numbers(value):
    if isinstance(value, (bool, int, float)):
        return [value]
    if hasattr(value, "sec") and hasattr(value, "nanosec"):  # a time or duration: seconds
        return [value.sec + value.nanosec / 1e9]
    if hasattr(value, "tolist"):  # array.array, numpy arrays
        value = value.tolist()
    if isinstance(value, (list, tuple)):
        return list(value)
    return None


def message_values(msg, getters, types, drop_nan):
    """(values, None) from the numeric leaves of ``msg`` if they match the
    input's layout, else (None, reason); the same checks as a Bottle's."""
    items = []
    for path, get in getters:
        found = _leaf_numbers(get(msg))
        if found is None:
            return None, "field %s is not a number" % path
        items.extend(found)
    out = []
    if types is None:
        for k, x in enumerate(items):
            if isinstance(x, bool) or not isinstance(x, (int, float)):
                return None, "element %d is not a number" % k
            out.append(float(x))
    else:
        if len(items) != len(types):
            return None, "%d elements, expected %d" % (len(items), len(types))
        for k, (x, t) in enumerate(zip(items, types)):
            if t in _FLOAT_TYPES:
                if isinstance(x, bool) or not isinstance(x, (int, float)):
                    return None, "element %d is not a number, expected %s" % (k, t)
                out.append(float(x))
            elif t in _INT_TYPES:
                if isinstance(x, bool) or not isinstance(x, int):
                    return None, "element %d is not an integer, expected %s" % (k, t)
                out.append(int(x))
            elif t == "bool":
                if isinstance(x, bool) or (isinstance(x, int) and x in (0, 1)):
                    out.append(bool(x))
                else:
                    return None, "element %d is not a bool (0 or 1)" % k
            else:
                return None, "element %d has the type %s, not read from ROS 2" % (k, t)
    if drop_nan:
        for k, x in enumerate(out):
            if isinstance(x, float) and x != x:
                return None, "element %d is NaN" % k
    return out, None


class Ros2Input(InputState):
    """A ROS 2 topic read by a mux: the same state as a YARP input (envelope =
    the message's header.stamp if it has one); the subscription's callback
    runs on the node's executor thread."""

    def __init__(self, bridge, spec, node, msg_class, leaves, timeout, each=None, qos=None):
        self.init_state(bridge, spec, timeout)
        self.qos = INPUT_QOS if qos is None else qos
        self.local = spec.source
        self.node = node
        self.msg_class = msg_class
        self.getters = tuple((path, operator.attrgetter(path)) for path in leaves)
        # an array of messages whose elements give one row each
        self.elements = operator.attrgetter(each) if each else None
        self.subscription = None
        self.watch = EndpointWatch(bridge, node, "subscription", spec.source, _type_name(msg_class))

    def open(self):
        count = call_count()
        if count is not None:  # the cost guard's count (tests/test_cost.py)
            self._on_message = count.counted(self._on_message)

        def make(**events):
            return self.node.create_subscription(
                self.msg_class, self.source, self._on_message, self.qos,
                event_callbacks=SubscriptionEventCallbacks(**events), qos_overriding_options=QOS_OVERRIDES)

        try:
            self.subscription = self.watch.entity = self.watch.callbacks(make, matched=self._on_matched)
        except Exception as e:  # an rclpy error: report it, never a traceback
            self.bridge.log("cannot subscribe to %s: %s" % (self.source, e))
            return False
        return True

    def _on_matched(self, info):
        n = info.current_count
        self.bridge.log(PUBLISHERS_TEXT.format(topic=self.source, n=n, s="" if n == 1 else "s"))

    def _on_message(self, msg):
        now = time.monotonic()
        try:
            if self.elements is None:
                values, reason = message_values(msg, self.getters, self.spec.types,
                                                self.bridge.spec.on_nan == "drop")
            else:
                values, reason = self._rows(msg)
        except Exception as e:
            values, reason = None, "cannot read its fields (%s)" % e
        envelope = None
        stamp = getattr(getattr(msg, "header", None), "stamp", None)
        if stamp is not None and (stamp.sec or stamp.nanosec):
            envelope = stamp.sec + stamp.nanosec * 1e-9
        self.bridge.on_bottle(self, values, reason, now, envelope)

    def _rows(self, msg):
        """(one row per element, None), or (None, reason): a message with an
        element that does not check is dropped whole."""
        rows = []
        for k, element in enumerate(self.elements(msg)):
            row, reason = message_values(element, self.getters, self.spec.types,
                                         self.bridge.spec.on_nan == "drop")
            if reason is not None:
                return None, "element %d: %s" % (k, reason)
            rows.append(row)
        return rows, None

    def interrupt(self):
        pass

    def close(self):
        pass  # destroyed with the node, once its executor has stopped


class Ros2ImageInput(Ros2Input):
    """A ROS 2 topic of sensor_msgs/Image read by an image mux: each message
    whose encoding YARP has a pixel type for becomes a frame (its data not
    copied: the message's buffer), its header.stamp the envelope; any other
    is refused, counted and said once (images.message_frame says why)."""

    def __init__(self, bridge, spec, node, msg_class, timeout, qos=None):
        Ros2Input.__init__(self, bridge, spec, node, msg_class, (), timeout, None, qos)

    def _on_message(self, msg):
        now = time.monotonic()
        stamp = msg.header.stamp
        envelope = stamp.sec + stamp.nanosec * 1e-9 if (stamp.sec or stamp.nanosec) else None
        try:
            frame, reason = message_frame(msg.width, msg.height, msg.encoding, msg.step, msg.is_bigendian,
                                          msg.data, envelope)
        except Exception as e:
            frame, reason = None, "cannot read its fields (%s)" % e
        if frame is None:
            self.bridge.on_refused(self, reason)
        else:
            self.bridge.on_bottle(self, [frame], None, now, envelope)


def fill_image(msg, values, encoding):
    """The fields of a sensor_msgs/Image from the frame of an image mux's
    ``values``: its size, ``encoding``, little-endian, its rows packed
    (step = width x pixel size), copied once into the message's own
    ``data`` (an ``array('B')``: assigning one would copy it again)."""
    frame = frame_of(values)
    row = frame.row_bytes()
    data = msg.data
    if len(data):
        del data[:]
    append_rows(data, frame.data, frame.step, row, frame.height)
    msg.height = frame.height
    msg.width = frame.width
    msg.encoding = encoding
    msg.is_bigendian = 0
    msg.step = row


def _type_name(msg_class):
    """pkg/msg/Name of a message class."""
    return "%s/msg/%s" % (msg_class.__module__.split(".")[0], msg_class.__name__)


def _publisher(node, msg_class, topic, qos, on_matched, bridge):
    """The publisher, its matched and incompatible peers watched (said and
    counted by ``bridge``)."""
    watch = EndpointWatch(bridge, node, "publisher", topic, _type_name(msg_class))

    def make(**events):
        return node.create_publisher(msg_class, topic, qos, event_callbacks=PublisherEventCallbacks(**events),
                                     qos_overriding_options=QOS_OVERRIDES)

    publisher = watch.entity = watch.callbacks(make, matched=on_matched)
    return publisher, watch


class CameraInfoOutput:
    """A sensor_msgs/CameraInfo published on its own topic right after each
    image, with the image's header: ``calibration()`` gives the message (its
    header unset); when it says a size (width and height) and a frame has
    another, the focal lengths and principal point of k and p are scaled to
    the frame, whose size it then says."""

    type_name = "sensor_msgs/msg/CameraInfo"

    def __init__(self, topic, calibration):
        self.topic = topic
        self.calibration = calibration
        self.message = None
        self.publisher = None

    def prepare(self):
        """The calibration's message, and what of it each frame may change."""
        self.message = m = self.calibration()
        self.size = (m.width, m.height)
        self.k, self.p = list(m.k), list(m.p)

    def open(self, node, qos, on_matched, bridge):
        self.prepare()
        self.publisher, self.watch = _publisher(node, type(self.message), self.topic, qos, on_matched, bridge)

    def publish(self, image):
        m = self.message
        m.header.stamp = image.header.stamp
        m.header.frame_id = image.header.frame_id
        width, height = self.size
        if width and height and (image.width, image.height) != (width, height):
            m.width, m.height = image.width, image.height
            m.k, m.p = fit_calibration(self.k, self.p, width, height, image.width, image.height)
        else:
            m.width, m.height = width, height
            m.k, m.p = self.k, self.p
        self.publisher.publish(m)


class Ros2Output:
    """Publishes each message on a ROS 2 topic (a camera image with its
    ``camera_info``, a CameraInfoOutput, when given); says when subscribers
    come and go (a message published before a subscriber is matched is not
    delivered to it)."""

    def __init__(self, node, msg_class, type_name, topic, qos, camera_info=None):
        self.node = node
        self.msg_class = msg_class
        self.type_name = type_name
        self.port_name = topic
        self.qos = qos
        self.camera_info = camera_info
        self.publisher = None
        self.watch = None
        self.bridge = None  # the bridge that says and counts its incompatible peers (NodeBridge)
        self.log = lambda text: print(text, flush=True)

    def open(self):
        try:
            self.publisher, self.watch = _publisher(self.node, self.msg_class, self.port_name, self.qos,
                                                    self._on_matched, self.bridge)
            if self.camera_info is not None:
                info = self.camera_info
                info.open(self.node, self.qos, lambda event: self._on_matched(event, info.topic), self.bridge)
        except Exception as e:
            self.log("cannot advertise %s: %s" % (self.port_name, e))
            return False
        return True

    def _on_matched(self, info, topic=None):
        n = info.current_count
        self.log(SUBSCRIBERS_TEXT.format(topic=topic or self.port_name, n=n, s="" if n == 1 else "s"))

    def connections(self):
        return []

    def describe(self):
        text = "%s on the ROS 2 topic %s" % (self.type_name, self.port_name)
        if self.camera_info is not None:
            text += ", with %s on %s" % (self.camera_info.type_name, self.camera_info.topic)
        return text

    def publish(self, message):
        self.publisher.publish(message)
        if self.camera_info is not None:
            self.camera_info.publish(message)

    def stalled(self):
        return False  # rclpy never waits for a subscriber

    def close(self):
        pass  # destroyed with the node


class Spinner(threading.Thread):
    """Runs the node's executor (subscriptions, the /clock of simulated
    time) until stopped."""

    def __init__(self, node, log, timeout=0.1):
        threading.Thread.__init__(self, name="ros 2 executor", daemon=True)
        self.executor = SingleThreadedExecutor()
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

    def stop(self, timeout=1.0):
        self.done.set()
        if self.is_alive():
            self.join(timeout)
        self.executor.shutdown(timeout_sec=0.1)


class NodeBridge(YarpBridge):
    """The runtime's Bridge, with ROS 2 topics for the inputs of kind ros2
    and the message stamped from the node's clock."""

    def __init__(self, spec, options, node, output, build, compute, topic_inputs):
        self.node = node
        self.topic_inputs = topic_inputs
        self.make_message = build
        self.stamps = None
        self.fill_reported = False
        YarpBridge.__init__(self, spec, options, output, self._build, compute)
        if hasattr(output, "log"):
            output.log = self.log
        if isinstance(output, Ros2Output):
            output.bridge = self

    def make_input(self, mux, spec, local, timeout):
        if spec.kind == "ros2":
            # (message class, leaves[, each[, the QoS its mux asks]])
            msg_class, leaves, *rest = self.topic_inputs[(mux.name, spec.index)]
            each, qos = (list(rest) + [None, None])[:2]
            if spec.image:
                return Ros2ImageInput(self, spec, self.node, msg_class, timeout, qos)
            return Ros2Input(self, spec, self.node, msg_class, leaves, timeout, each, qos)
        if spec.image:
            return ImageInput(self, spec, local, timeout)
        return YarpBridge.make_input(self, mux, spec, local, timeout)

    def _build(self, ctx):
        return self.make_message(ctx, self.stamps)

    def _publish(self, raw, envelopes):
        # one reading of the node's clock (simulated with use_sim_time) for
        # the ROS 2 message's stamps and a YARP Bottle's `time` and `timestamp`
        now = self.node.get_clock().now()
        self.stamps = Stamps(now, envelopes)
        try:
            YarpBridge._publish(self, raw, envelopes, now.nanoseconds)
        except (FillError, AssertionError, TypeError, ValueError, OverflowError) as e:
            # a value that the message's field refuses: count it, never crash
            self.build_errors += 1
            if not self.fill_reported:
                self.fill_reported = True
                text = str(e)
                if len(text) > 200:
                    text = text[:200] + "..."
                self.log("cannot fill the message (%s: %s); further failures are only counted"
                         % (type(e).__name__, text))


# --- /diagnostics ------------------------------------------------------------------

#: diagnostic_updater's FrequencyStatus tolerance: a fixed-rate output below
#: (1 - tolerance) x its configured rate is a warning
RATE_TOLERANCE = 0.1
#: the number of periods the achieved rate is measured over
RATE_WINDOW = 5
#: the seconds between two /diagnostics messages, unless the parameter
#: diagnostic_updater.period says (diagnostic_updater's own default)
DIAGNOSTICS_PERIOD = 1.0


def _key_values(pairs):
    return [KeyValue(key=k, value=v) for k, v in pairs]


def input_status(inp, now):
    """The (level, message, key-values) of one input from its totals: OK
    while fresh, WARN while stale, ERROR before its first Bottle or message."""
    if inp.state == "waiting":
        level, text = DiagnosticStatus.ERROR, "no data received yet"
    elif inp.state == "stale":
        level, text = DiagnosticStatus.WARN, "stale: no data for %.1f s" % (now - inp.arrival)
    else:
        level, text = DiagnosticStatus.OK, "fresh"
    age = "" if inp.arrival is None else "%.3f" % (now - inp.arrival)
    return level, text, (
        ("received", str(inp.received)), ("dropped", str(inp.dropped)),
        ("stale periods", str(inp.stale_periods)), ("unused", str(inp.unused)),
        ("refused", str(inp.refused)), ("age (s)", age), ("timeout (s)", "%g" % inp.timeout))


def output_status(bridge, achieved):
    """The (level, message, key-values) of the output: the rate achieved over
    the last periods against the rate configured (none when event-driven)."""
    rate = bridge.rate
    if rate is None:
        level, text = DiagnosticStatus.OK, "event-driven: %.2f Hz" % achieved
    elif achieved < rate * (1.0 - RATE_TOLERANCE):
        level, text = DiagnosticStatus.WARN, "rate too low: %.2f Hz of %g Hz" % (achieved, rate)
    else:
        level, text = DiagnosticStatus.OK, "%.2f Hz of %g Hz" % (achieved, rate)
    return level, text, (
        ("published", str(bridge.published)), ("rate achieved (Hz)", "%.3f" % achieved),
        ("rate configured (Hz)", "event-driven" if rate is None else "%g" % rate),
        ("skipped cycles", str(bridge.skipped_cycles)), ("build failures", str(bridge.build_errors)),
        ("missed by readers", str(bridge.missed)))


def _with_events(status, endpoint):
    """A status of an input or the output with the counts of its
    incompatible peers when it is a ROS 2 subscription or publisher."""
    watch = getattr(endpoint, "watch", None)
    if watch is None:
        return status
    level, text, values = status
    return level, text, tuple(values) + event_values(watch.counts)


class Diagnostics:
    """Publishes the bridge's totals on /diagnostics as a DiagnosticArray
    every ``period`` seconds of the steady clock, as diagnostic_updater does:
    one status per input (``<node>: input <source>``) and one for the output
    (``<node>: output <topic or port>``), hardware_id the module's name."""

    def __init__(self, bridge, node, period):
        self.bridge = bridge
        self.node = node
        self.name = node.get_name()
        self.hardware_id = bridge.spec.module
        self.samples = collections.deque(maxlen=RATE_WINDOW + 1)  # (time, published)
        with bridge.cond:
            self.samples.append((time.monotonic(), bridge.published))
        self.publisher = node.create_publisher(DiagnosticArray, "/diagnostics", 1)
        self.timer = node.create_timer(period, self.publish, clock=Clock(clock_type=ClockType.STEADY_TIME))

    def _status(self, name, level, text, values):
        return DiagnosticStatus(level=level, name="%s: %s" % (self.name, name), message=text,
                                hardware_id=self.hardware_id, values=_key_values(values))

    def array(self):
        """The DiagnosticArray of the bridge's state now."""
        bridge = self.bridge
        now = time.monotonic()
        with bridge.cond:
            self.samples.append((now, bridge.published))
            statuses = [self._status("input %s" % inp.source, *_with_events(input_status(inp, now), inp))
                        for inp in bridge.inputs]
            (t0, n0), (t1, n1) = self.samples[0], self.samples[-1]
            achieved = (n1 - n0) / (t1 - t0) if t1 > t0 else 0.0
            statuses.append(self._status("output %s" % bridge.output.port_name,
                                         *_with_events(output_status(bridge, achieved), bridge.output)))
        msg = DiagnosticArray(status=statuses)
        msg.header.stamp = self.node.get_clock().now().to_msg()
        return msg

    def publish(self):
        self.publisher.publish(self.array())


# --- parameters, start and shutdown ----------------------------------------------

class ParameterError(ValueError):
    pass


def _parameter_number(value, name):
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ParameterError("parameter %s must be a number, got %r" % (name, value))
    return float(value)


def node_options(node, default_prefix, default_rate, spec=None):
    """The options of docs/runtime.md from the node's parameters (``spec``:
    the bridge's, to check `accept` against its inputs)."""
    def declare(name, default, text):
        descriptor = ParameterDescriptor(description=text, dynamic_typing=True)
        return node.declare_parameter(name, default, descriptor).value

    rate = _parameter_number(declare("rate", default_rate, "fixed output rate in Hz; 0 = event-driven"),
                   "rate")
    if rate < 0:
        raise ParameterError("parameter rate must be 0 (event-driven) or positive")
    timeout = _parameter_number(declare("timeout", 0.0, "freshness timeout of every input in seconds; "
                                              "0 = each input's own from the config"), "timeout")
    if timeout < 0:
        raise ParameterError("parameter timeout must be positive (or 0: the config's)")
    prefix = declare("prefix", default_prefix, "prefix of the node's own YARP port names")
    if not isinstance(prefix, str) or not prefix.startswith("/"):
        raise ParameterError("parameter prefix must be a string starting with /")
    verbose = declare("verbose", False, "print every value after conversion, for every mux")
    if not isinstance(verbose, bool):
        raise ParameterError("parameter verbose must be true or false")
    diagnostics = declare("diagnostics", True, "publish the bridge's state on /diagnostics")
    if not isinstance(diagnostics, bool):
        raise ParameterError("parameter diagnostics must be true or false")
    period = _parameter_number(declare("diagnostic_updater.period", DIAGNOSTICS_PERIOD,
                                       "seconds between two /diagnostics messages"),
                               "diagnostic_updater.period")
    if period <= 0:
        raise ParameterError("parameter diagnostic_updater.period must be positive")
    accept = declare("accept", "", "other ports whose Bottles an input takes too: PORT=OTHER items "
                                   "(a list, or one string separated by commas)")
    if isinstance(accept, str):
        accept = [a.strip() for a in accept.split(",") if a.strip()]
    if not isinstance(accept, (list, tuple)) or not all(isinstance(a, str) for a in accept):
        raise ParameterError("parameter accept must be a string or a list of strings, PORT=OTHER")
    try:
        accept = parse_accept(spec, accept) if spec is not None else {}
    except ValueError as e:
        raise ParameterError("parameter accept: %s" % e) from None
    return argparse.Namespace(prefix=prefix, rate=rate, timeout=timeout or None, verbose=verbose,
                              diagnostics_period=period if diagnostics else None, accept=accept)


def _parse_command_line(spec, args, default_prefix, default_rate):
    parser = argparse.ArgumentParser(
        prog=os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else spec.module,
        description="\n".join(spec.description),
        epilog="ROS parameters (--ros-args -p NAME:=VALUE):\n"
               "  rate          fixed output rate in Hz, 0 for event-driven (default: %g)\n"
               "  timeout       freshness timeout of every input in seconds, 0 for the\n"
               "                config's (default: 0)\n"
               "  prefix        prefix of the node's own YARP port names (default: %s)\n"
               "  verbose       print every value after conversion (default: false)\n"
               "  accept        PORT=OTHER: the input of YARP port PORT also takes the Bottles\n"
               "                of port OTHER (a list, or one string separated by commas)\n"
               "  diagnostics   publish the bridge's state on /diagnostics (default: true)\n"
               "  diagnostic_updater.period\n"
               "                seconds between two /diagnostics messages (default: 1)\n"
               "  qos_overrides./TOPIC.publisher.POLICY (.subscription. for inputs)\n"
               "                history, depth, reliability, durability over the config's\n"
               "  use_sim_time  stamp messages with the simulated time of /clock\n"
               "Generated by ybgc from %s." % (default_rate, default_prefix, spec.config),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_args(args)


def run_node(spec, argv, node_name, default_prefix, default_rate, topic_inputs,
             make_output, build, compute):
    """Start rclpy and the node, run the bridge until SIGINT/SIGTERM; the exit status."""
    argv = list(sys.argv[1:] if argv is None else argv)
    started = []
    pending = []

    def on_signal(signum, frame):
        # until the bridge runs (it installs its own handlers): remember the request
        if started:
            started[0].request_stop()
        else:
            pending.append(signum)

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    prog = sys.argv[0] if sys.argv and sys.argv[0] else spec.module
    _parse_command_line(spec, rclpy.utilities.remove_ros_args([prog] + argv)[1:],
                        default_prefix, default_rate)
    try:
        rclpy.init(args=[prog] + argv, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as e:
        print("%s: cannot start ROS 2: %s" % (spec.module, e), flush=True)
        return 2
    node = None
    spinner = None
    try:
        node = rclpy.create_node(node_name)
        try:
            options = node_options(node, default_prefix, default_rate, spec)
        except ParameterError as e:
            print("%s: %s" % (spec.module, e), flush=True)
            return 2
        bridge = NodeBridge(spec, options, node, make_output(node), build, compute, topic_inputs)
        if options.diagnostics_period:
            Diagnostics(bridge, node, options.diagnostics_period)
        started.append(bridge)
        if pending:
            bridge.request_stop()
        spinner = Spinner(node, bridge.log)
        spinner.start()
        return bridge.run()
    finally:
        if spinner is not None:
            spinner.stop()
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()


# --- several nodes in one process (ybgc compose) ------------------------------------

def _parse_composed_command_line(name, members, args):
    parser = argparse.ArgumentParser(
        prog=os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else name,
        description=describe(name, members),
        epilog="Each bridge is a node of its own name with the parameters of its node alone (rate,\n"
               "timeout, prefix, verbose, accept, diagnostics, diagnostic_updater.period,\n"
               "qos_overrides.*, use_sim_time), given for one node as\n"
               "  --ros-args -p NODE:NAME:=VALUE   or in a --params-file keyed by node name\n"
               "(-p NAME:=VALUE gives every node the value). `yarp rpc /%s/rpc:i` answers\n"
               "help, stats and quit." % name,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_args(args)


#: the longest wait of a composed node's executor for an event: a dozen
#: executors waking ten times a second each with nothing to do would take a
#: tenth of a core
COMPOSED_SPIN_TIMEOUT = 1.0


def _stop_nodes(spinners, nodes):
    """Every executor stopped at once, then the nodes destroyed."""
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


def run_composed(name, members, argv, load):
    """Run the bridges ``members`` (each loaded by ``load(member)``, a node
    of the ``ros2`` backend) in this process: one rclpy context (one DDS
    participant), one node per bridge with its own name, parameters,
    executor thread and /diagnostics status; the YARP side is
    compose.Composer's. Until SIGINT, SIGTERM or `quit` on
    ``/<name>/rpc:i``; the exit status (2: a bad parameter, nothing opened)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    sys.setswitchinterval(SWITCH_INTERVAL)
    composer = Composer(name, members)
    composer.handle_signals()
    prog = sys.argv[0] if sys.argv and sys.argv[0] else name
    _parse_composed_command_line(name, members, rclpy.utilities.remove_ros_args([prog] + argv)[1:])
    try:
        rclpy.init(args=[prog] + argv, signal_handler_options=SignalHandlerOptions.NO)
    except Exception as e:
        print("%s: cannot start ROS 2: %s" % (name, e), flush=True)
        return 2
    nodes = []
    spinners = []
    finished = []

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
            _stop_nodes(spinners, nodes)
            rclpy.try_shutdown()
            done.set()

        threading.Thread(target=stop_ros, name="stop ROS 2", daemon=True).start()
        if not done.wait(max(0.1, composer.time_left())):
            sys.stdout.flush()
            sys.stderr.flush()
            os._exit(1 if composer.failed else 0)

    try:
        prepared = []
        for member in members:
            try:
                module = load(member)
                # a node of commands (its spec lists services): its runtime is
                # the module its run_commands comes from
                commands = sys.modules[module.run_commands.__module__] if hasattr(module.SPEC, "services") \
                    else None
                node_name = module.SPEC.node_name if commands is not None else module.NODE_NAME
            except (Exception, SystemExit) as e:
                composer.refuse(member, load_failure(member, e))
                continue
            node = rclpy.create_node(node_name)
            nodes.append(node)
            try:
                if commands is not None:
                    options = commands.node_options(node, module.SPEC.default_prefix)
                else:
                    options = node_options(node, module.DEFAULT_PREFIX, module.DEFAULT_RATE, module.SPEC)
            except (ParameterError, getattr(commands, "ParameterError", ParameterError)) as e:
                print("%s: %s" % (module.SPEC.module, e), flush=True)
                return 2
            try:
                if commands is not None:
                    bridge = commands.ComposedCommands(module.SPEC, node, options)
                else:
                    bridge = NodeBridge(module.SPEC, options, node, module.make_output(node), module.build_message,
                                        module.compute, module.TOPIC_INPUTS)
            except Exception as e:
                composer.refuse(member, "%s: %s" % (type(e).__name__, e))
                nodes.remove(node)
                node.destroy_node()
                continue
            prepared.append((member, node, bridge, options))
        yarp.Network.init()
        if not yarp.Network.checkNetwork(3.0):
            composer.log("cannot reach the YARP name server (is yarpserver running?)")
            return 1
        if not composer.open_rpc():
            return 1
        for member, node, bridge, options in prepared:
            if composer.stop_event.is_set():
                break
            if not composer.start(member, bridge):
                nodes.remove(node)
                node.destroy_node()
                continue
            if not isinstance(bridge, NodeBridge):  # a node of commands: its loop runs its executor
                bridge.start_diagnostics(options.diagnostics_period)
                continue
            if options.diagnostics_period:
                Diagnostics(bridge, node, options.diagnostics_period)
            spinner = Spinner(node, bridge.log, COMPOSED_SPIN_TIMEOUT)
            spinner.start()
            spinners.append(spinner)
        return composer.serve(finish)
    finally:
        if not finished:
            _stop_nodes(spinners, nodes)
            rclpy.try_shutdown()
