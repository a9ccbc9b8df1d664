"""The incompatible peers of a ROS 2 node's publishers and subscriptions
(the ros2 node's output and the topics it reads): the events ROS 2 raises
when a peer can never match, counted and the first of each kind said with
both sides' QoS or type hashes (docs/runtime.md, "Incompatible peers (ROS 2)")."""

from rclpy.event_handler import UnsupportedEventTypeError
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from rclpy.qos_overriding_options import QoSPolicyKind

from .core import INCOMPATIBLE_QOS_TEXT, INCOMPATIBLE_TYPE_TEXT, EndpointEvents  # ybgc:runtime-import


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
