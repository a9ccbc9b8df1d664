"""The ROS 2 side of the ros2 backend's stream nodes: the bridge run inside
an rclpy node, a part of the process shell (shell.py, ros2_shell.py). ROS 2
topics as mux inputs, a typed message filled field by field and published
with the config's QoS, stamps from the node's clock (use_sim_time is
respected), the node's parameters in place of the command-line options,
QoS overridden by ``qos_overrides`` parameters, and the bridge's totals on
/diagnostics; camera images both ways (sensor_msgs/Image topics read and
published, with their CameraInfo: the frames are images.py's)
(docs/runtime.md)."""

import argparse
import collections
import operator
import time

import rclpy.time
from diagnostic_msgs.msg import DiagnosticStatus
from rclpy.event_handler import PublisherEventCallbacks, SubscriptionEventCallbacks
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSOverridingOptions, QoSPolicyKind

from .base import _FLOAT_TYPES, _INT_TYPES, call_count  # ybgc:runtime-import
from .core import BridgeSpec, InputState, parse_accept, seconds_to_ns  # ybgc:runtime-import
from .core import PUBLISHERS_TEXT, SUBSCRIBERS_TEXT  # ybgc:runtime-import
from .images import ImageInput, append_rows, fit_calibration, frame_of, message_frame  # ybgc:runtime-import
from .ros2_events import EndpointWatch, event_values  # ybgc:runtime-import
from .ros2_shell import DIAGNOSTICS_PERIOD, NODE_KINDS, NodeKind, Parameter, ParameterError  # ybgc:runtime-import
from .ros2_shell import declare, epilog, node_parameters, number, run_alone, run_composed  # ybgc:runtime-import
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



class NodeBridge(YarpBridge):
    """The runtime's Bridge, with ROS 2 topics for the inputs of kind ros2
    and the message stamped from the node's clock; its state on
    /diagnostics (``statuses``)."""

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
        # (time, published) of the last /diagnostics: the rate achieved over RATE_WINDOW of them
        self.samples = collections.deque([(time.monotonic(), 0)], maxlen=RATE_WINDOW + 1)

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

    def statuses(self, now):
        """/diagnostics: one status per input, and one for the output (the
        rate achieved over the last RATE_WINDOW statuses)."""
        with self.cond:
            self.samples.append((now, self.published))
            statuses = [("input %s" % inp.source,) + _with_events(input_status(inp, now), inp) for inp in self.inputs]
            (t0, n0), (t1, n1) = self.samples[0], self.samples[-1]
            achieved = (n1 - n0) / (t1 - t0) if t1 > t0 else 0.0
            statuses.append(("output %s" % self.output.port_name,)
                            + _with_events(output_status(self, achieved), self.output))
        return statuses


# --- /diagnostics ------------------------------------------------------------------

#: diagnostic_updater's FrequencyStatus tolerance: a fixed-rate output below
#: (1 - tolerance) x its configured rate is a warning
RATE_TOLERANCE = 0.1
#: the number of periods the achieved rate is measured over
RATE_WINDOW = 5


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


# --- the node of a stream bridge ----------------------------------------------------

def _rate(value, name):
    value = number(value, name)
    if value < 0:
        raise ParameterError("parameter rate must be 0 (event-driven) or positive")
    return value


def _timeout(value, name):
    value = number(value, name)
    if value < 0:
        raise ParameterError("parameter timeout must be positive (or 0: the config's)")
    return value


def _accept(value, name):
    if isinstance(value, str):
        value = [a.strip() for a in value.split(",") if a.strip()]
    if not isinstance(value, (list, tuple)) or not all(isinstance(a, str) for a in value):
        raise ParameterError("parameter accept must be a string or a list of strings, PORT=OTHER")
    return value


class StreamNode(NodeKind):
    """A stream bridge's node as the shell runs it (ros2_shell.NodeKind):
    its parameters in place of a YARP module's options (docs/runtime.md,
    "Command line") and its bridge (NodeBridge)."""

    def __init__(self, spec, node_name, default_prefix, default_rate, topic_inputs, make_output, build, compute):
        self.spec = spec
        self.name = spec.module
        self.node_name = node_name
        self.description = "\n".join(spec.description)
        self.default_prefix = default_prefix
        self.default_rate = default_rate
        self.topic_inputs = topic_inputs
        self.make_output = make_output
        self.build = build
        self.compute = compute

    @classmethod
    def of_module(cls, module):
        """The kind of a stream node's generated module."""
        return cls(module.SPEC, module.NODE_NAME, module.DEFAULT_PREFIX, module.DEFAULT_RATE, module.TOPIC_INPUTS,
                   module.make_output, module.build_message, module.compute)

    def parameters(self):
        common = node_parameters(self.default_prefix, ("print every value after conversion, for every mux",
                                                       "print every value after conversion"),
                                 "publish the bridge's state on /diagnostics")
        return (
            Parameter("rate", self.default_rate, "fixed output rate in Hz; 0 = event-driven", _rate,
                      "  rate          fixed output rate in Hz, 0 for event-driven (default: %g)\n" % self.default_rate),
            Parameter("timeout", 0.0, "freshness timeout of every input in seconds; 0 = each input's own from the "
                                      "config", _timeout,
                      "  timeout       freshness timeout of every input in seconds, 0 for the\n"
                      "                config's (default: 0)\n"),
        ) + common[:2] + (
            Parameter("accept", "", "other ports whose Bottles an input takes too: PORT=OTHER items (a list, or "
                                    "one string separated by commas)", _accept,
                      "  accept        PORT=OTHER: the input of YARP port PORT also takes the Bottles\n"
                      "                of port OTHER (a list, or one string separated by commas)\n"),
        ) + common[2:]

    def epilog(self):
        return epilog(self.parameters(),
                      "  qos_overrides./TOPIC.publisher.POLICY (.subscription. for inputs)\n"
                      "                history, depth, reliability, durability over the config's\n"
                      "  use_sim_time  stamp messages with the simulated time of /clock\n"
                      "Generated by ybgc from %s." % self.spec.config)

    def options(self, node):
        """The options of docs/runtime.md from the node's parameters."""
        values = declare(node, self.parameters())
        try:
            accept = parse_accept(self.spec, values["accept"])
        except ValueError as e:
            raise ParameterError("parameter accept: %s" % e) from None
        return argparse.Namespace(prefix=values["prefix"], rate=values["rate"], timeout=values["timeout"] or None,
                                  verbose=values["verbose"], diagnostics_period=values["diagnostics_period"],
                                  accept=accept)

    def part(self, node, options):
        return NodeBridge(self.spec, options, node, self.make_output(node), self.build, self.compute,
                          self.topic_inputs)


NODE_KINDS[BridgeSpec] = StreamNode.of_module


def run_node(spec, argv, node_name, default_prefix, default_rate, topic_inputs, make_output, build, compute):
    """Start rclpy and the node, run the bridge until SIGINT, SIGTERM or
    `quit`; the exit status. (A composed node's bridges: run_composed.)"""
    return run_alone(StreamNode(spec, node_name, default_prefix, default_rate, topic_inputs, make_output, build,
                               compute), argv)
