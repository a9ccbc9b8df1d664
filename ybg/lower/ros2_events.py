"""What the native module and the rclpy node say alike of the incompatible
peers of their ROS 2 publishers and subscriptions (docs/runtime.md,
"Incompatible peers (ROS 2)").

The texts are made at run time only (the peer's QoS and type hash come from
the ROS graph), so each runtime keeps a copy, ``ybg/runtime/core.py`` for the
Python node and ``ybg/runtime/cpp/ybgc_ros2.cpp`` and ``ybgc_totals.cpp`` for
the native module, and tests/test_ros2_events.py holds both copies to these.

Said once per publisher or subscription, the first peer of each kind::

    ROS 2 {kind} {topic}: a {peer} of an incompatible QoS (...)
    ROS 2 {kind} {topic}: a {peer} of another definition of {type} (...)

Said by a publisher each time its matched subscriptions change, and by a
subscription each time its matched publishers change (a message published
before both sides have matched is not delivered; {s} is "" for one, "s"
otherwise)::

    {topic}: {n} subscriber{s}
    {topic}: {n} publisher{s}

Exit totals, one line per publisher or subscription that had any, after the
``published`` line::

    ros2 KIND TOPIC: incompatible QoS N, incompatible type N

``stats`` on the module's RPC port, one list per publisher then subscription::

    (ros2 KIND TOPIC incompatible_qos N incompatible_type N)
"""

from __future__ import annotations

#: the first peer of an incompatible QoS: {kind} publisher or subscription,
#: {peer} the other; {policy} rmw's name of the last policy that did not
#: match; {theirs} and {ours} reliability and durability ("reliable, volatile")
INCOMPATIBLE_QOS_TEXT = ("ROS 2 {kind} {topic}: a {peer} of an incompatible QoS ({policy}; the {peer}'s: "
                         "{theirs}; this {kind}'s: {ours}): no messages between them; further incompatible "
                         "QoS events of it are only counted")
#: the first peer of the type's name and another definition: {theirs} and
#: {ours} type hashes (RIHS01_...)
INCOMPATIBLE_TYPE_TEXT = ("ROS 2 {kind} {topic}: a {peer} of another definition of {type} (its type hash "
                          "{theirs}; this {kind}'s: {ours}): no messages between them; further incompatible "
                          "type events of it are only counted")
#: a publisher's matched subscriptions, when they change: {topic} as the
#: config names it, {n} how many, {s} "" for one and "s" otherwise
SUBSCRIBERS_TEXT = "{topic}: {n} subscriber{s}"
#: a subscription's matched publishers, when they change (as above)
PUBLISHERS_TEXT = "{topic}: {n} publisher{s}"
#: the exit totals' line (Python %-format: kind, topic, QoS count, type count)
EVENTS_TOTALS_LINE = "ros2 %s %s: incompatible QoS %d, incompatible type %d"
#: the keys of one `stats` list, after ``ros2 KIND TOPIC``
STATS_KEYS = ("incompatible_qos", "incompatible_type")
#: the key-values of /diagnostics, after a status's own
DIAGNOSTICS_KEYS = ("incompatible QoS", "incompatible type")
