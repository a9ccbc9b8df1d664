"""Pass ``output``: [output], its message type and its QoS.

Checks: `topic` or `port` and not both (E204, E208), each against `via`
(E208), port, topic and node names (E401, E402), `connect` (YARP only),
`node` (ROS 1 only) and the QoS keys (ROS 2 only) (W506), `timeout`, and
the message `type` against the definitions (E204, E301, W502, W503).
Also the readers of [output]'s timing keys, which the ``program`` pass
reads last. Reads ``sections``, ``output_keys``, ``output_via``,
``module``, ``ros`` and ``store``. Sets ``output``, ``msgdef`` and
``type_known``.
"""

from __future__ import annotations

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import Span, did_you_mean
from ybg.compiler.msgtypes import normalize_name
from ybg.compiler.names import port_problem, topic_problem
from ybg.compiler.passes.context import Context
from ybg.compiler.passes.sections import CHOICES
from ybg.compiler.values import choice, number, whole, word

#: the output types of sensor data, published with ir.SENSOR_DATA_QOS (best
#: effort, depth 5: rclpy's qos_profile_sensor_data) unless the config says
SENSOR_DATA_TYPES = frozenset({
    "sensor_msgs/Image", "sensor_msgs/CompressedImage", "sensor_msgs/PointCloud2",
    "sensor_msgs/LaserScan", "sensor_msgs/Imu", "sensor_msgs/PointCloud",
})
MAX_QUEUE = 100_000
#: the ROS node of a ROS 1 output's port (`<topic>@<node>`), unless [output] names one
ROS1_NODE = "/yarp/{module}"


def run(ctx: Context) -> None:
    ctx.output, ctx.msgdef, ctx.type_known = _output(ctx)


def _output(ctx: Context):
    """(Output, MsgDef or None, type known); (None, None, False) when [output] does not check."""
    s = ctx.sink
    keys = ctx.output_keys
    out_sec = ctx.sections.get("output")
    out_span = out_sec.span if out_sec else None
    if "timeout" in keys:
        number(keys["timeout"], s)
    if "topic" in keys and "port" in keys:
        s.error("E208", "give either `topic` (ROS) or `port` (YARP), not both", keys["port"].key_span)
        return None, None, False
    if "topic" not in keys and "port" not in keys:
        if keys or "output" in {x.name for x in ctx.doc.sections}:
            s.error("E204", "[output] needs `topic = /name` (ROS) or `port = /name` (YARP)",
                    out_span, "e.g. `topic = /joint_states` with `via = ros2`")
        return None, None, False
    kind = ctx.output_via
    name_entry = keys.get("topic") or keys.get("port")
    name = word(name_entry, s, "name")
    if name is None or kind is None:
        return None, None, False
    if "topic" in keys:
        if kind == "yarp":
            s.error("E208", "`via = yarp` writes a YARP port: use `port = ...` instead of `topic`",
                    keys["via"].span)
            return None, None, False
        problem = topic_problem(name)
        if problem:
            s.error("E402", f"invalid ROS topic name `{name}`: {problem}", name_entry.items[0].span,
                    "e.g. `/joint_states` or `/robot/joint_states`")
    else:
        if kind != "yarp":
            s.error("E208", f"`via = {kind}` publishes a ROS topic: use `topic = ...` instead of `port`",
                    keys["via"].span)
            return None, None, False
        problem = port_problem(name)
        if problem:
            s.error("E401", f"invalid YARP port name `{name}`: {problem}", name_entry.items[0].span,
                    "e.g. `/my_module/out:o`")
    connect = None
    if "connect" in keys:
        connect = word(keys["connect"], s, "port")
        if kind != "yarp":
            s.error("E208", "`connect` is for YARP outputs", keys["connect"].key_span)
        elif connect is not None and port_problem(connect):
            s.error("E401", f"invalid YARP port name `{connect}`: {port_problem(connect)}",
                    keys["connect"].items[0].span)
    node = None
    if kind == "ros1":
        node = ROS1_NODE.format(module=ctx.module)
        if "node" in keys:
            node = word(keys["node"], s)
            if node is not None and topic_problem(node):
                s.error("E402", f"invalid ROS node name `{node}`: {topic_problem(node)}",
                        keys["node"].items[0].span)
    elif "node" in keys:
        s.warning("W506", "`node` only applies to `via = ros1`", keys["node"].key_span,
                  "the ROS 2 node is named after the module; remove the key")
    msg_type, msgdef, known = _resolve_type(ctx, keys.get("type"), kind, out_span)
    qos = None
    if kind == "ros2":
        sensor = msg_type in SENSOR_DATA_TYPES
        rel = choice(keys["reliability"], s, CHOICES["reliability"]) if "reliability" in keys else None
        dur = choice(keys["durability"], s, CHOICES["durability"]) if "durability" in keys else None
        depth = whole(keys["depth"], s, 1) if "depth" in keys else None
        default = ir.SENSOR_DATA_QOS if sensor else ir.OUTPUT_QOS
        qos = ir.QoS(rel or default.reliability, dur or default.durability, depth if depth else default.depth)
    else:
        for k in ("reliability", "durability", "depth"):
            if k in keys:
                s.warning("W506", f"`{k}` only applies to `via = ros2`", keys[k].key_span)
    return ir.Output(kind, name, msg_type, node, qos, connect), msgdef, known


def _resolve_type(ctx: Context, entry: ast.Entry | None, kind: str, out_span: Span | None):
    """(msg_type, MsgDef or None, type known)"""
    s = ctx.sink
    store = ctx.store
    if entry is None:
        if kind == "ros2":
            s.error("E204", "[output] needs `type` for a ROS 2 topic", out_span,
                    "e.g. `type = sensor_msgs/JointState`")
        return None, None, False
    text = word(entry, s, "message type")
    if text is None:
        return None, None, False
    span = entry.items[0].span
    if "/" not in text:
        cands = store.candidates(text)
        if len(cands) == 1:
            s.warning("W502", f"message type `{text}` given without its package: taken as `{cands[0]}`",
                      span, f"write `{cands[0]}`")
            return cands[0], store.resolve(cands[0]), True
        if len(cands) > 1:
            s.error("E301", f"`{text}` is ambiguous: {', '.join(cands)}", span, "write `pkg/Name`")
            return None, None, False
        s.warning("W503", f"message type `{text}` not found, and it has no package: its fields are not checked",
                  span, "write `pkg/Name`, and give its .msg folder with --msg-path or YBG_MSG_PATH")
        return text, None, False
    norm = normalize_name(text)
    if norm is None:
        s.error("E301", f"`{text}` is not a message type name", span, "write `pkg/Name`, e.g. `sensor_msgs/JointState`")
        return None, None, False
    msgdef = store.resolve(norm)
    if msgdef is not None:
        return norm, msgdef, True
    pkg = norm.split("/")[0]
    known_pkgs = {n.split("/")[0] for n in store.all_names()}
    if pkg in known_pkgs and store.path_of(norm) is None:
        s.error("E301", f"unknown message type `{norm}` ({ctx.ros}, {store.distro})", span,
                did_you_mean(norm, store.all_names()) or f"see the messages of {pkg}")
        return None, None, False
    if store.path_of(norm) is not None:  # its file has problems, reported separately
        return None, None, False
    s.warning("W503", f"message type `{norm}` not found: its fields are not checked", span,
              "give the folder of its .msg files with --msg-path or YBG_MSG_PATH")
    return norm, None, False


def rate(ctx: Context) -> float | None:
    """[output] rate in Hz; None (and 0): publish when new data arrives."""
    keys = ctx.output_keys
    if "rate" not in keys:
        return None
    r = number(keys["rate"], ctx.sink, 0.0, allow_zero=True)
    return None if not r else r


def queue(ctx: Context) -> int:
    """[output] queue: a whole number from 1 (the newest Bottle only) to MAX_QUEUE."""
    keys = ctx.output_keys
    if "queue" not in keys:
        return ir.DEFAULT_QUEUE
    n = whole(keys["queue"], ctx.sink, 1, MAX_QUEUE,
              "1 keeps only the newest Bottle of each input; the default, "
              f"{ir.DEFAULT_QUEUE}, relays a burst whole")
    return ir.DEFAULT_QUEUE if n is None else n


def chosen(ctx: Context, key: str, default: str) -> str:
    """One of the words [output] ``key`` takes; ``default`` when absent or wrong."""
    entry = ctx.output_keys.get(key)
    return (choice(entry, ctx.sink, CHOICES[key]) if entry is not None else None) or default
