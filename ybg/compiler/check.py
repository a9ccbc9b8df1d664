"""Stage 3: named-form :class:`~ybg.compiler.ast.Document` -> checked
:class:`~ybg.compiler.ir.Program`.

Every problem becomes a diagnostic with its own code, span and hint; the pass
goes on after a problem, so one run reports all of them. A legacy file reaches
this stage already converted to the named form (``legacy.py``), with the spans
of its own lines. The language is described in ``docs/config.md``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field

from ybg.compiler import ast, ir, values
from ybg.compiler.diagnostics import Sink, Span, did_you_mean
from ybg.compiler.msgtypes import DISTROS, MsgDef, TypeStore, load_store, normalize_name, numeric_leaves
from ybg.compiler.names import identifier_problem, port_problem, sanitize_identifier, topic_problem
from ybg.compiler.options import Options

SECTION_KEYS: dict[str, tuple[str, ...]] = {
    "module": ("name", "distro"),
    "output": ("topic", "port", "connect", "type", "via", "node", "rate", "trigger", "queue",
               "on_stale", "on_nan", "timeout", "reliability", "durability", "depth"),
    "mux": ("ports", "topics", "via", "convert", "verbose", "timeout"),
    "message": (),
}
CHOICES = {
    "via": ("ros2", "ros1", "yarp"),
    "trigger": ("all", "any"),
    "on_stale": ("skip", "hold"),
    "on_nan": ("pass", "drop"),
    "reliability": ("reliable", "best_effort"),
    "durability": ("volatile", "transient_local"),
}
DEFAULT_TIMEOUT = 1.0
MAX_QUEUE = 100_000

#: converter name -> (number of parameters, scale, offset, to_float)
CONVERTERS: dict[str, tuple[int, float, float, bool]] = {
    "none": (0, 1.0, 0.0, False),
    "none_double": (0, 1.0, 0.0, True),
    "deg_to_rad": (0, math.pi / 180.0, 0.0, True),
    "rad_to_deg": (0, 180.0 / math.pi, 0.0, True),
    "scale": (1, 1.0, 0.0, True),
    "offset": (1, 1.0, 0.0, True),
}

#: sequences of a message that must be empty or of one length
SAME_LENGTH = {
    "sensor_msgs/JointState": ("name", "position", "velocity", "effort"),
    "sensor_msgs/MultiDOFJointState": ("joint_names", "transforms", "twists", "wrench"),
}

#: QoS by message kind: sensor streams are best effort, depth 5 (rclpy's qos_profile_sensor_data)
SENSOR_DATA_TYPES = frozenset({
    "sensor_msgs/Image", "sensor_msgs/CompressedImage", "sensor_msgs/PointCloud2",
    "sensor_msgs/LaserScan", "sensor_msgs/Imu", "sensor_msgs/PointCloud",
})

_INT_RANGE = {
    "int8": (-2**7, 2**7 - 1), "uint8": (0, 2**8 - 1), "byte": (0, 255), "char": (0, 255),
    "int16": (-2**15, 2**15 - 1), "uint16": (0, 2**16 - 1),
    "int32": (-2**31, 2**31 - 1), "uint32": (0, 2**32 - 1),
    "int64": (-2**63, 2**63 - 1), "uint64": (0, 2**64 - 1),
}


@dataclass
class _Stores:
    options: Options
    cache: dict = field(default_factory=dict)

    def get(self, ros: str, distro: str | None) -> TypeStore:
        key = (ros, distro)
        if key not in self.cache:
            env = self.options.environ if self.options.environ is not None else os.environ
            self.cache[key] = load_store(ros, distro, self.options.msg_path, env)
        return self.cache[key]


# --------------------------------------------------------------------------
# the pass


class _Checker:
    def __init__(self, doc: ast.Document, source: str, sink: Sink, options: Options,
                 module_default: str):
        self.doc = doc
        self.source = source
        self.sink = sink
        self.options = options
        self.stores = _Stores(options)
        self.module_default = module_default
        self.used_muxes: set[str] = set()

    # ---- sections
    def sections(self) -> dict[str, ast.Section] | None:
        s = self.sink
        for e in self.doc.loose:
            s.error("E107", f"`{e.key}` is not inside a section", e.key_span,
                    "put it under a header such as `[output]`")
        out: dict[str, ast.Section] = {}
        muxes: dict[str, ast.Section] = {}
        for sec in self.doc.sections:
            if sec.name not in SECTION_KEYS:
                s.error("E201", f"unknown section [{sec.title}]", sec.span,
                        did_you_mean(sec.name, SECTION_KEYS) or "sections: [module], [output], [mux <name>], [message]")
                continue
            if sec.name == "mux":
                if sec.label is None:
                    s.error("E104", "a mux section needs a name: `[mux <name>]`", sec.span,
                            "e.g. `[mux arm]`; the name is what [message] refers to")
                    continue
                if sec.label in muxes:
                    s.error("E205", f"[mux {sec.label}] is defined twice", sec.span,
                            f"first defined on line {muxes[sec.label].span.line}")
                    continue
                muxes[sec.label] = sec
                continue
            if sec.label is not None:
                s.error("E104", f"[{sec.name}] takes no name", sec.span, f"write `[{sec.name}]`")
            if sec.name in out:
                s.error("E205", f"[{sec.name}] is given twice", sec.span,
                        f"first given on line {out[sec.name].span.line}")
                continue
            out[sec.name] = sec
        for need in ("output", "message"):
            if need not in out:
                s.error("E203", f"missing section [{need}]", None,
                        "a named config has [output], one or more [mux <name>] and [message]")
        self.mux_sections = muxes
        return out

    def run(self) -> ir.Program | None:
        secs = self.sections()
        module_sec = secs.get("module")
        module_keys = values.check_keys(module_sec, SECTION_KEYS["module"], self.sink) if module_sec else {}
        module = self.module_default
        if "name" in module_keys:
            name = values.word(module_keys["name"], self.sink)
            if name is not None:
                problem = identifier_problem(name)
                if problem:
                    self.sink.error("E214", f"module name `{name}` {problem}", module_keys["name"].items[0].span,
                                    f"e.g. `name = {sanitize_identifier(name)}`")
                else:
                    module = name
        out_sec = secs.get("output")
        out_keys = values.check_keys(out_sec, SECTION_KEYS["output"], self.sink) if out_sec else {}
        mux_keys = {name: values.check_keys(sec, SECTION_KEYS["mux"], self.sink)
                    for name, sec in self.mux_sections.items()}

        # dialect: ROS 2 if the output or any input lives there, else ROS 1
        via = self.output_via(out_keys)
        mux_via = {}
        for name, keys in mux_keys.items():
            mux_via[name] = values.choice(keys["via"], self.sink, CHOICES["via"]) if "via" in keys else None
            if mux_via[name] == "yarp" and "topics" in keys:
                self.sink.error("E208", "topics are read from ROS: `via` is ros1 or ros2",
                                keys["via"].span)
        ros = "ros2" if via == "ros2" or "ros2" in mux_via.values() else "ros1"
        distro = self.options.distro
        if distro is None and "distro" in module_keys:
            distro = values.word(module_keys["distro"], self.sink)
            if distro is not None and distro not in DISTROS:
                self.sink.error("E208", f"unknown distro `{distro}`", module_keys["distro"].items[0].span,
                                did_you_mean(distro, DISTROS) or f"known: {', '.join(DISTROS)}")
                distro = None
        if distro is not None and DISTROS.get(distro) != ros:
            where = module_keys["distro"].items[0].span if "distro" in module_keys else None
            self.sink.error("E208", f"distro `{distro}` is {DISTROS.get(distro)}, but this config uses {ros}",
                            where, "ROS 1: noetic; ROS 2: humble, jazzy, kilted")
            distro = None
        self.ros = ros
        self.store = self.stores.get(ros, distro)
        self.distro = self.store.distro

        muxes = []
        for name, sec in self.mux_sections.items():
            m = self.mux(name, sec, mux_keys[name], mux_via[name] or (via if via in ("ros1", "ros2") else ros),
                         out_keys)
            if m is not None:
                muxes.append(m)
        self.muxes = {m.name: m for m in muxes}

        self.out_span = out_sec.span if out_sec else None
        output, msgdef, type_known = self.output(module, via, out_keys)
        message = None
        if "message" in secs:
            message = self.message(secs["message"], msgdef, output, type_known)

        for name, sec in self.mux_sections.items():
            if name in self.muxes and name not in self.used_muxes and not self.sink.has_errors:
                self.sink.warning("W501", f"mux `{name}` is not used by [message]", sec.span,
                                  f"use it in a field (`position = {name}`) or remove the section")
        for p in self.store.problems:
            self.sink.error("E301", f"{p.path}:{p.line}:{p.column}: {p.message}", None,
                            "fix the .msg file, or remove its folder from --msg-path")
        if self.sink.has_errors or output is None or message is None:
            return None
        timing = ir.Timing(
            rate=self.rate(out_keys),
            trigger=values.choice(out_keys["trigger"], self.sink, CHOICES["trigger"]) if "trigger" in out_keys else "all",
            queue=self.queue(out_keys),
        )
        policy = ir.Policy(
            on_stale=(values.choice(out_keys["on_stale"], self.sink, CHOICES["on_stale"]) if "on_stale" in out_keys else None) or "skip",
            on_nan=(values.choice(out_keys["on_nan"], self.sink, CHOICES["on_nan"]) if "on_nan" in out_keys else None) or "pass",
        )
        if self.sink.has_errors:
            return None
        return ir.Program(
            module=module, source=self.source, muxes=tuple(muxes), message=message,
            output=output, timing=timing, policy=policy,
            ros=ros if (output.kind != "yarp" or any(i.kind != "yarp" for m in muxes for i in m.inputs)
                        or message.msg_type) else None,
            distro=self.distro,
        )

    def queue(self, keys: dict[str, ast.Entry]) -> int:
        """[output] queue: a whole number from 1 (the newest Bottle only) to MAX_QUEUE."""
        if "queue" not in keys:
            return ir.DEFAULT_QUEUE
        n = values.whole(keys["queue"], self.sink, 1, MAX_QUEUE,
                   "1 keeps only the newest Bottle of each input; the default, "
                   f"{ir.DEFAULT_QUEUE}, relays a burst whole")
        return ir.DEFAULT_QUEUE if n is None else n

    # ---- output
    def output_via(self, keys: dict[str, ast.Entry]) -> str | None:
        if "via" in keys:
            return values.choice(keys["via"], self.sink, CHOICES["via"])
        if "port" in keys:
            return "yarp"
        if "topic" in keys:
            return "ros2"
        return None

    def rate(self, keys: dict[str, ast.Entry]) -> float | None:
        if "rate" not in keys:
            return None
        r = values.number(keys["rate"], self.sink, 0.0, allow_zero=True)
        return None if not r else r

    def output(self, module: str, via: str | None, keys: dict[str, ast.Entry]):
        s = self.sink
        for k in ("timeout",):
            if k in keys:
                values.number(keys[k], s)
        if "topic" in keys and "port" in keys:
            s.error("E208", "give either `topic` (ROS) or `port` (YARP), not both", keys["port"].key_span)
            return None, None, False
        if "topic" not in keys and "port" not in keys:
            if keys or "output" in {x.name for x in self.doc.sections}:
                s.error("E204", "[output] needs `topic = /name` (ROS) or `port = /name` (YARP)",
                        self.out_span, "e.g. `topic = /joint_states` with `via = ros2`")
            return None, None, False
        kind = via
        name_entry = keys.get("topic") or keys.get("port")
        name = values.word(name_entry, s, "name")
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
            connect = values.word(keys["connect"], s, "port")
            if kind != "yarp":
                s.error("E208", "`connect` is for YARP outputs", keys["connect"].key_span)
            elif connect is not None and port_problem(connect):
                s.error("E401", f"invalid YARP port name `{connect}`: {port_problem(connect)}",
                        keys["connect"].items[0].span)
        node = None
        if kind == "ros1":
            node = f"/yarp/{module}"
            if "node" in keys:
                node = values.word(keys["node"], s)
                if node is not None and topic_problem(node):
                    s.error("E402", f"invalid ROS node name `{node}`: {topic_problem(node)}",
                            keys["node"].items[0].span)
        elif "node" in keys:
            s.warning("W506", "`node` only applies to `via = ros1`", keys["node"].key_span,
                      "the ROS 2 node is named after the module; remove the key")
        msg_type, msgdef, known = self.resolve_type(keys.get("type"), kind, name)
        qos = None
        if kind == "ros2":
            sensor = msg_type in SENSOR_DATA_TYPES
            rel = values.choice(keys["reliability"], s, CHOICES["reliability"]) if "reliability" in keys else None
            dur = values.choice(keys["durability"], s, CHOICES["durability"]) if "durability" in keys else None
            depth = values.whole(keys["depth"], s, 1) if "depth" in keys else None
            qos = ir.QoS(rel or ("best_effort" if sensor else "reliable"), dur or "volatile",
                         depth if depth else (5 if sensor else 10))
        else:
            for k in ("reliability", "durability", "depth"):
                if k in keys:
                    s.warning("W506", f"`{k}` only applies to `via = ros2`", keys[k].key_span)
        return ir.Output(kind, name, msg_type, node, qos, connect), msgdef, known

    def resolve_type(self, entry: ast.Entry | None, kind: str, name: str):
        """(msg_type, MsgDef or None, type known)"""
        s = self.sink
        if entry is None:
            if kind == "ros2":
                s.error("E204", "[output] needs `type` for a ROS 2 topic", self.out_span,
                        "e.g. `type = sensor_msgs/JointState`")
            return None, None, False
        text = values.word(entry, s, "message type")
        if text is None:
            return None, None, False
        span = entry.items[0].span
        if "/" not in text:
            cands = self.store.candidates(text)
            if len(cands) == 1:
                s.warning("W502", f"message type `{text}` given without its package: taken as `{cands[0]}`",
                          span, f"write `{cands[0]}`")
                return cands[0], self.store.resolve(cands[0]), True
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
        msgdef = self.store.resolve(norm)
        if msgdef is not None:
            return norm, msgdef, True
        pkg = norm.split("/")[0]
        known_pkgs = {n.split("/")[0] for n in self.store.all_names()}
        if pkg in known_pkgs and self.store.path_of(norm) is None:
            s.error("E301", f"unknown message type `{norm}` ({self.ros}, {self.store.distro})", span,
                    did_you_mean(norm, self.store.all_names()) or f"see the messages of {pkg}")
            return None, None, False
        if self.store.path_of(norm) is not None:  # its file has problems, reported separately
            return None, None, False
        s.warning("W503", f"message type `{norm}` not found: its fields are not checked", span,
                  "give the folder of its .msg files with --msg-path or YBG_MSG_PATH")
        return norm, None, False

    # ---- muxes
    def mux(self, name: str, sec: ast.Section, keys: dict[str, ast.Entry], topic_via: str,
            out_keys) -> ir.Mux | None:
        s = self.sink
        problem = identifier_problem(name)
        if problem:
            s.error("E214", f"mux name `{name}` {problem}", sec.span, f"e.g. `[mux {sanitize_identifier(name)}]`")
            return None
        timeout = DEFAULT_TIMEOUT
        if "timeout" in out_keys:
            timeout = values.number(out_keys["timeout"], Sink()) or DEFAULT_TIMEOUT
        if "timeout" in keys:
            timeout = values.number(keys["timeout"], s) or timeout
        if "ports" in keys and "topics" in keys:
            s.error("E208", "a mux reads either `ports` (YARP) or `topics` (ROS), not both",
                    keys["topics"].key_span, "split them into two muxes")
            return None
        entry = keys.get("ports") or keys.get("topics")
        if entry is None:
            s.error("E204", f"[mux {name}] needs `ports = /port1, /port2` (or `topics = ...`)", sec.span)
            return None
        if not entry.items:
            s.error("E208", f"`{entry.key}` lists no input", entry.span)
            return None
        inputs = []
        ok = True
        for item in entry.items:
            inp = self.input(item, entry.key == "topics", topic_via, timeout)
            if inp is None:
                ok = False
            else:
                inputs.append(inp)
        seen: dict[str, int] = {}
        for inp, item in zip(inputs, entry.items):
            if inp.name in seen:
                s.warning("W506", f"`{inp.name}` is read twice by mux `{name}`", item.span)
            seen[inp.name] = 1
        if not ok:
            return None
        verbose = False
        if "verbose" in keys:
            verbose = bool(values.boolean(keys["verbose"], s))
        mux = ir.Mux(name, tuple(inputs), (), verbose)
        convs = self.converters(mux, keys.get("convert"))
        return ir.Mux(name, tuple(inputs), tuple(convs), verbose)

    def input(self, item: ast.Item, is_topic: bool, via: str, timeout: float) -> ir.Input | None:
        s = self.sink
        decl: tuple[tuple[ast.Atom, ...], ...] | None = None
        head = item
        if isinstance(item, ast.Call):
            head, decl = item.func, item.args
        if not isinstance(head, (ast.Word, ast.Str)):
            s.error("E213", "an input is a name, optionally followed by its declaration `(float64 x6)`",
                    item.span)
            return None
        name = head.text if isinstance(head, ast.Word) else head.value
        if is_topic:
            problem = topic_problem(name)
            if problem:
                s.error("E402", f"invalid ROS topic name `{name}`: {problem}", head.span)
                return None
            ros_type = None
            fields = None
            layout = None
            positions = None
            if decl:
                ros_type, fields, layout = self.topic_decl(name, decl, item.span, via)
                if ros_type is None:
                    return None
                if via == "ros1" and fields:
                    positions = bottle_positions(self.stores.get("ros1", None), ros_type, fields)
            elif via == "ros2":
                s.error("E319", f"ROS 2 topic `{name}` needs its message type", head.span,
                        f"write `{name} (geometry_msgs/Point)`, or `{name} (sensor_msgs/JointState position)` "
                        "to take one numeric field")
                return None
            return ir.Input(name, via, layout, ros_type, fields, timeout, positions)
        problem = port_problem(name)
        if problem:
            s.error("E401", f"invalid YARP port name `{name}`: {problem}", head.span,
                    "e.g. `/icub/left_arm/state:o`")
            return None
        layout = None
        if decl is not None:
            layout = self.layout(decl, item.span)
            if layout is None:
                return None
        return ir.Input(name, "yarp", layout, None, None, timeout)

    def layout(self, decl, span: Span) -> tuple[ir.ElementGroup, ...] | None:
        s = self.sink
        groups = []
        if not decl:
            s.error("E213", "empty declaration `()`", span, "e.g. `(float64 x6)` or `(float64 x6, int32 x3)`")
            return None
        for arg in decl:
            words = [a.text if isinstance(a, ast.Word) else None for a in arg]
            if None in words or len(words) not in (1, 2):
                s.error("E213", "a declaration group is `<type> x<count>`, e.g. `float64 x6`", arg[0].span)
                return None
            typ = words[0]
            count = 1
            if len(words) == 2:
                w = words[1]
                if not (w.startswith("x") and w[1:].isdigit()):
                    s.error("E213", f"`{w}` is not a count: write `x<count>`, e.g. `x6`", arg[1].span)
                    return None
                count = int(w[1:])
                if count < 1:
                    s.error("E213", "a count is at least 1", arg[1].span)
                    return None
            if typ not in ir.ELEMENT_TYPES:
                s.error("E213", f"unknown element type `{typ}`", arg[0].span,
                        did_you_mean(typ, sorted(ir.ELEMENT_TYPES)) or
                        "element types: float64 float32 int8..int64 uint8..uint64 bool string")
                return None
            groups.append(ir.ElementGroup(typ, count))
        return tuple(groups)

    def topic_decl(self, name: str, decl, span: Span, via: str):
        s = self.sink
        if len(decl) != 1 or not all(isinstance(a, ast.Word) for a in decl[0]) or len(decl[0]) > 2:
            s.error("E213", "a topic is declared with its type and optionally one numeric field: "
                    "`(pkg/Name)` or `(pkg/Name field)`", span)
            return None, None, None
        words = [a.text for a in decl[0]]
        store = self.stores.get(via, self.options.distro if DISTROS.get(self.options.distro or "") == via else None)
        norm = normalize_name(words[0])
        msgdef = store.resolve(norm) if norm else None
        if msgdef is None:
            s.error("E301", f"unknown message type `{words[0]}` ({via})", decl[0][0].span,
                    did_you_mean(words[0], store.all_names()) or "write `pkg/Name`")
            return None, None, None
        if len(words) == 2:
            path = words[1]
            cur: MsgDef | None = msgdef
            ftype = None
            for part in path.split("."):
                f = cur.field(part) if cur else None
                if f is None:
                    s.error("E302", f"`{msgdef.name}` has no field `{path}`", decl[0][1].span,
                            did_you_mean(part, [x.name for x in (cur.fields if cur else ())]))
                    return None, None, None
                ftype = f.type
                cur = store.resolve(f.type.base) if f.type.is_message else None
            assert ftype is not None
            if ftype.base not in ir.NUMERIC_TYPES or (ftype.array is None and ftype.is_message):
                leaves = numeric_leaves(store, ftype.base) if ftype.is_message and ftype.array is None else None
                if leaves is None:
                    s.error("E309", f"field `{path}` of `{msgdef.name}` is not numeric", decl[0][1].span)
                    return None, None, None
                return norm, tuple(f"{path}.{p}" for p, _ in leaves), tuple(ir.ElementGroup(t, 1) for _, t in leaves)
            if ftype.array is None:
                return norm, (path,), (ir.ElementGroup(ftype.base, 1),)
            if ftype.array == "fixed":
                return norm, (path,), (ir.ElementGroup(ftype.base, ftype.size or 0),)
            return norm, (path,), None if ftype.base in ir.FLOAT_TYPES else None
        leaves = numeric_leaves(store, msgdef)
        if leaves is None:
            s.error("E309", f"`{msgdef.name}` is not all numbers: name the numeric field to read",
                    decl[0][0].span, f"e.g. `{name} ({msgdef.name} {next((f.name for f in msgdef.fields if f.type.base in ir.NUMERIC_TYPES), 'field')})`")
            return None, None, None
        return norm, tuple(p for p, _ in leaves), tuple(ir.ElementGroup(t, 1) for _, t in leaves)

    def converters(self, mux: ir.Mux, entry: ast.Entry | None) -> list[ir.Converter]:
        if entry is None:
            return []
        s = self.sink
        out = []
        width = mux.width
        types = mux.element_types
        for item in entry.items:
            start, stop, rng_span = 0, None, None
            base = item
            if isinstance(item, ast.Subscript):
                base = item.base
                rng_span = item.span
                if item.is_slice:
                    start, stop = item.start or 0, item.stop
                else:
                    start, stop = item.start, (item.start or 0) + 1
            args: tuple = ()
            if isinstance(base, ast.Call):
                args = base.args
                base = base.func
            if not isinstance(base, ast.Word):
                s.error("E313", "a converter is a name, e.g. `deg_to_rad` or `scale(0.5)`", item.span)
                continue
            name = base.text
            if name not in CONVERTERS:
                s.error("E313", f"unknown converter `{name}`", base.span,
                        did_you_mean(name, CONVERTERS) or f"converters: {', '.join(CONVERTERS)}")
                continue
            nparams, scale, offset, to_float = CONVERTERS[name]
            if len(args) != nparams:
                s.error("E208", f"`{name}` takes {nparams or 'no'} parameter{'s' if nparams != 1 else ''}",
                        item.span, f"e.g. `{name}(0.5)`" if nparams else f"write `{name}`")
                continue
            if nparams:
                arg = args[0]
                k = arg[0].number() if len(arg) == 1 and isinstance(arg[0], ast.Word) else None
                if k is None or isinstance(k, bool) or not math.isfinite(k):
                    s.error("E208", f"`{name}` takes a number", arg[0].span if arg else item.span)
                    continue
                if name == "scale":
                    scale = float(k)
                else:
                    offset = float(k)
            if start is not None and start < 0 or (stop is not None and stop < 0):
                s.error("E315", "element ranges count from 0 and are not negative", rng_span)
                continue
            if stop is not None and stop <= start:
                s.error("E315", f"empty element range [{start}:{stop}]", rng_span)
                continue
            if width is not None and (start >= width or (stop is not None and stop > width)):
                s.error("E315", f"range [{start}:{'' if stop is None else stop}] is outside mux `{mux.name}`"
                        f" of {width} elements", rng_span, f"elements are 0..{width - 1}")
                continue
            if types is not None and name != "none":
                hi = width if stop is None else stop
                bad = sorted({t for t in types[start:hi] if t not in ir.NUMERIC_TYPES})
                if bad:
                    s.error("E314", f"`{name}` applied to {', '.join(bad)} elements of mux `{mux.name}`",
                            item.span, "give it a range of numeric elements, e.g. `deg_to_rad[0:6]`")
                    continue
            if name == "none":
                continue
            out.append(ir.Converter(name, scale, offset, to_float, start, stop))
        return out

    # ---- message
    def message(self, sec: ast.Section, msgdef: MsgDef | None, output: ir.Output | None,
                type_known: bool) -> ir.Struct | None:
        s = self.sink
        entries: dict[tuple[str, ...], ast.Entry] = {}
        for e in sec.entries:
            path = tuple(e.key.split("."))
            if any(not p for p in path):
                s.error("E302", f"`{e.key}` is not a field path", e.key_span, "e.g. `header.frame_id`")
                continue
            if path in entries:
                s.error("E206", f"`{e.key}` is given twice in [message]", e.key_span,
                        f"first given on line {entries[path].span.line}")
                continue
            entries[path] = e
        # a field set as a whole and in parts: report the later line
        for path in sorted(entries, key=lambda p: entries[p].span.line):
            for k in range(1, len(path)):
                short = path[:k]
                if short in entries and path in entries:
                    a, b = entries[short], entries[path]
                    later = b if b.span.line >= a.span.line else a
                    s.error("E215", f"`{'.'.join(short)}` is set as a whole and `{'.'.join(path)}` by itself",
                            later.key_span, "set either the whole field or its parts")
                    del entries[path if later is b else short]
                    break
        if not entries and msgdef is None:
            s.error("E204", "[message] sets no field", sec.span, "e.g. `position = arm`")
            return None
        if msgdef is not None:
            struct = self.typed_struct(msgdef, (), entries)
            self.check_lengths(msgdef, struct, entries)
            # anything left was not a field
            return struct
        self.splice = output is None or output.kind == "yarp"
        return self.untyped_struct((), entries, output.msg_type if (output and not type_known) else None)

    def typed_struct(self, msgdef: MsgDef, prefix: tuple[str, ...],
                     entries: dict[tuple[str, ...], ast.Entry]) -> ir.Struct:
        s = self.sink
        below = self.below(entries)
        mine = below.get(prefix, {})
        names = [f.name for f in msgdef.fields]
        for p, e in mine.items():
            head = p[len(prefix)]
            if msgdef.field(head) is None:
                other = self.other_dialect_field(msgdef.name, head)
                if other:
                    s.error("E311", f"`{'.'.join(p)}`: {other}", e.key_span, self.other_dialect_hint(msgdef.name, head))
                else:
                    s.error("E302", f"`{msgdef.name}` has no field `{head}`", e.key_span,
                            did_you_mean(head, names) or f"fields: {', '.join(names)}")
        fields = []
        for f in msgdef.fields:
            path = prefix + (f.name,)
            if path in entries:
                fields.append(ir.Field(f.name, self.typed_value(entries[path], f.type), f.type))
            elif path in below:
                if not f.type.is_message or f.type.array is not None:
                    p, e = next(iter(below[path].items()))
                    s.error("E302", f"`{'.'.join(path)}` is a {f.type}, it has no field `{p[len(path)]}`",
                            e.key_span)
                    fields.append(ir.Field(f.name, ir.Default(), f.type))
                    continue
                sub = self.store.resolve(f.type.base)
                if sub is None:
                    fields.append(ir.Field(f.name, ir.Default(), f.type))
                    continue
                fields.append(ir.Field(f.name, self.typed_struct(sub, path, entries), f.type))
            else:
                fields.append(ir.Field(f.name, self.default(f, path), f.type))
        return ir.Struct(tuple(fields), msgdef.name)

    def default(self, f, path: tuple[str, ...]):
        """The default of an unset field: a nested message becomes a struct of
        its own defaults, so that backends see the layout."""
        t = f.type
        if t.is_message and t.array is None:
            sub = self.store.resolve(t.base)
            if sub is not None:
                return self.typed_struct(sub, path, {})
        if t.is_message and t.array == "fixed":
            self.sink.error("E304", f"`{'.'.join(path)}` is {t}, a fixed-size array of messages, "
                            "which cannot be filled yet", None)
        return ir.Default(f.default)

    def below(self, entries) -> dict[tuple[str, ...], dict[tuple[str, ...], ast.Entry]]:
        """prefix -> the entries strictly below it (computed once)."""
        if getattr(self, "_below_of", None) is not entries:
            index: dict[tuple[str, ...], dict[tuple[str, ...], ast.Entry]] = {}
            for p, e in entries.items():
                for k in range(len(p)):
                    index.setdefault(p[:k], {})[p] = e
            self._below_of, self._below = entries, index
        return self._below

    def other_dialect_field(self, msg: str, field_name: str) -> str | None:
        other = "ros1" if self.ros == "ros2" else "ros2"
        try:
            store = self.stores.get(other, None)
        except ValueError:
            return None
        d = store.resolve(msg)
        if d is not None and d.field(field_name) is not None:
            here = "ROS 2" if self.ros == "ros2" else "ROS 1"
            there = "ROS 1" if other == "ros1" else "ROS 2"
            return f"`{msg}` has no field `{field_name}` in {here}; it exists only in {there}"
        return None

    def other_dialect_hint(self, msg: str, field_name: str) -> str:
        if msg == "std_msgs/Header" and field_name == "seq":
            if self.ros == "ros2":
                return ("ROS 2 headers have no sequence number: remove the line (the stamp and "
                        "frame_id remain); a legacy file converts with `ybgc fmt --to named --ros2 FILE`")
            return "for ROS 1 add `header.seq = counter`"
        return "remove the line, or compile for the other ROS version"

    # values of typed fields
    def typed_value(self, e: ast.Entry, t: ir.TypeRef):
        s = self.sink
        items = e.items
        span = e.span
        if t.is_message and t.array is None and t.base not in ("builtin_interfaces/Time",):
            # a whole nested message: only a mux of the same width
            if len(items) == 1 and self.is_mux_ref(items[0]):
                return self.mux_into_message(items[0], t, e)
            s.error("E308", f"`{e.key}` is a {t.base}: set its fields one by one", span,
                    f"e.g. `{e.key}.<field> = ...`, or give a mux of its width")
            return ir.Default()
        if len(items) == 1 and isinstance(items[0], ast.Word) and items[0].text == "counter":
            if t.base not in ir.INTEGER_TYPES or t.array is not None:
                s.error("E306", f"`counter` is an integer, but `{e.key}` is {t}", items[0].span,
                        "use counter for an integer field such as header.seq (ROS 1)")
            return ir.Counter(t.base if t.base in ir.INTEGER_TYPES else "uint32")
        if len(items) == 1 and self.is_timestamp(items[0]):
            ts = self.timestamp(items[0])
            if t.array is not None or t.base not in ("time", "builtin_interfaces/Time"):
                s.error("E307", f"`timestamp` is a time, but `{e.key}` is {t}", items[0].span,
                        "use it for a time field such as header.stamp")
            return ts
        if len(items) == 1 and isinstance(items[0], ast.Word) and items[0].text == "time":
            if t.array is not None or t.base not in ir.FLOAT_TYPES:
                s.error("E304", f"`time` is seconds as float64, but `{e.key}` is {t}", items[0].span)
            return ir.Seconds()
        if t.base in ("time", "duration", "builtin_interfaces/Time", "builtin_interfaces/Duration") and t.array is None:
            s.error("E307", f"`{e.key}` is a {t.base}: give `timestamp` or `timestamp(<mux>)`", span)
            return ir.Default()
        if any(self.is_mux_ref(i) for i in items):
            if len(items) != 1:
                s.error("E305", "a field takes one mux reference, not a list mixing muxes and values",
                        span, "concatenate inputs in one mux instead")
                return ir.Default()
            return self.mux_into_field(items[0], t, e)
        # literals
        if len(items) == 1 and isinstance(items[0], ast.Bracket):
            items = items[0].items
            as_list = True
        else:
            as_list = t.array is not None
        if t.is_message:
            s.error("E304", f"`{e.key}` is a list of {t.base} messages; only muxes and literals of "
                    "primitive types are supported", span)
            return ir.Default()
        values = []
        for it in items:
            v = self.literal(it, t.base, e.key)
            if v is None:
                return ir.Default()
            values.append(v)
        if t.array is None:
            if as_list or len(values) != 1:
                if len(values) == 0 and t.base == "string":
                    return ir.Literal(("",), "string", False)
                s.error("E304", f"`{e.key}` is one {t.base}, not {len(values) or 'no'} values", span,
                        f"write `{e.key} = <one {t.base}>`")
                return ir.Default()
            return ir.Literal(tuple(values), t.base, False)
        if t.array == "fixed" and len(values) != t.size:
            s.error("E310", f"`{e.key}` is {t}: it needs exactly {t.size} values, not {len(values)}", span)
        if t.array == "sequence" and t.size is not None and len(values) > t.size:
            s.error("E310", f"`{e.key}` is {t}: at most {t.size} values, not {len(values)}", span)
        return ir.Literal(tuple(values), t.base, True)

    def literal(self, item: ast.Item, base: str, key: str):
        s = self.sink
        if base in ("string", "wstring"):
            if isinstance(item, ast.Str):
                return item.value
            s.error("E304", f"`{key}` takes text: quote it", item.span,
                    f'write `"{item.text}"`' if isinstance(item, ast.Word) else None)
            return None
        if isinstance(item, ast.Str):
            s.error("E304", f"`{key}` is {base}, not text", item.span,
                    "remove the quotes" if _looks_number(item.value) else None)
            return None
        if not isinstance(item, ast.Word):
            s.error("E304", f"`{key}` takes {base} values", item.span)
            return None
        if base == "bool":
            b = item.boolean()
            n = item.number()
            if b is None and n in (0, 1) and isinstance(n, int):
                b = bool(n)
            if b is None:
                s.error("E304", f"`{key}` is bool: true or false, not `{item.text}`", item.span)
            return b
        n = item.number()
        if n is None:
            if item.text in ("counter", "timestamp", "time"):
                s.error("E304", f"`{item.text}` cannot be an item of a list", item.span)
            elif identifier_problem(item.text) is None:
                self.unknown_mux(item.text, item.span)
            else:
                s.error("E304", f"`{key}` is {base}, not `{item.text}`", item.span)
            return None
        if base in ir.FLOAT_TYPES:
            return float(n)
        if isinstance(n, float):
            if n.is_integer() and math.isfinite(n):
                n = int(n)
            else:
                s.error("E304", f"`{key}` is {base}, an integer, not `{item.text}`", item.span)
                return None
        lo, hi = _INT_RANGE.get(base, (-2**63, 2**64))
        if not lo <= n <= hi:
            s.error("E317", f"{n} is out of range for {base} ({lo}..{hi})", item.span)
            return None
        return n

    # mux references
    def is_mux_ref(self, item: ast.Item) -> bool:
        if isinstance(item, ast.Subscript):
            item = item.base
        return isinstance(item, ast.Word) and item.text in self.mux_sections

    def is_timestamp(self, item: ast.Item) -> bool:
        if isinstance(item, ast.Call):
            item = item.func
        return isinstance(item, ast.Word) and item.text == "timestamp"

    def timestamp(self, item: ast.Item) -> ir.Timestamp:
        style = "ros2" if self.ros == "ros2" else "ros1"
        if isinstance(item, ast.Call):
            args = item.args
            if len(args) != 1 or len(args[0]) != 1 or not isinstance(args[0][0], ast.Word):
                self.sink.error("E208", "`timestamp(<mux>)` takes the name of one mux", item.span)
                return ir.Timestamp("wall", None, style)
            name = args[0][0].text
            if name not in self.muxes:
                self.unknown_mux(name, args[0][0].span)
                return ir.Timestamp("wall", None, style)
            self.used_muxes.add(name)
            return ir.Timestamp("envelope", name, style)
        return ir.Timestamp("wall", None, style)

    def unknown_mux(self, name: str, span: Span) -> None:
        if name in self.mux_sections:  # defined, but broken: already reported
            return
        self.sink.error("E212", f"no mux named `{name}`", span,
                        did_you_mean(name, list(self.mux_sections)) or
                        (f"muxes: {', '.join(self.mux_sections)}" if self.mux_sections else
                         f"define it: `[mux {name}]` with `ports = ...`; quote text: `\"{name}\"`"))

    def mux_slice(self, item: ast.Item):
        """(mux, start, stop, index) or None; reports problems."""
        s = self.sink
        start, stop, index = 0, None, None
        base = item
        if isinstance(item, ast.Subscript):
            base = item.base
            if item.is_slice:
                start, stop = item.start or 0, item.stop
            else:
                index = item.start
        assert isinstance(base, ast.Word)
        name = base.text
        if name not in self.muxes:
            self.unknown_mux(name, base.span)
            return None
        self.used_muxes.add(name)
        mux = self.muxes[name]
        width = mux.width
        if (index is not None and index < 0) or start < 0 or (stop is not None and stop < 0):
            s.error("E316", "mux positions count from 0 and are not negative", item.span)
            return None
        if stop is not None and stop <= start:
            s.error("E315", f"empty range [{start}:{stop}]", item.span)
            return None
        if width is not None:
            if index is not None and index >= width:
                s.error("E316", f"index {index} is outside mux `{name}` of {width} elements", item.span,
                        f"elements are 0..{width - 1}")
                return None
            if start >= width and not (start == 0 and width == 0) or (stop is not None and stop > width):
                s.error("E315", f"range [{start}:{'' if stop is None else stop}] is outside mux `{name}` "
                        f"of {width} elements", item.span)
                return None
        return mux, start, stop, index

    def slice_types(self, mux: ir.Mux, start: int, stop: int | None, index: int | None):
        types = mux.element_types
        if types is None:
            return None
        if index is not None:
            return types[index: index + 1]
        return types[start: stop]

    def mux_into_field(self, item: ast.Item, t: ir.TypeRef, e: ast.Entry):
        s = self.sink
        got = self.mux_slice(item)
        if got is None:
            return ir.Default()
        mux, start, stop, index = got
        types = self.slice_types(mux, start, stop, index)
        if index is None and t.array is None:
            s.error("E305", f"`{e.key}` is one {t.base}, but `{mux.name}` is a list of elements", item.span,
                    f"take one element: `{mux.name}[0]`")
            return ir.Default()
        if index is not None and t.array is not None:
            s.error("E305", f"`{e.key}` is {t}, but `{mux.name}[{index}]` is one element", item.span,
                    f"take a range: `{mux.name}[{index}:{index + 1}]`")
            return ir.Default()
        if types is not None:
            bad = sorted({x for x in types if not _fits(x, t.base)})
            if bad:
                s.error("E305", f"`{e.key}` is {t}, but mux `{mux.name}` gives {', '.join(bad)}", item.span,
                        "declare the port element types to match, or convert them (`none_double`)")
                return ir.Default()
            if t.array == "fixed" and len(types) != t.size:
                s.error("E310", f"`{e.key}` is {t}: it needs exactly {t.size} elements, mux `{mux.name}`"
                        f" gives {len(types)}", item.span)
        return ir.MuxRef(mux.name, start, stop, index, False, t.base)

    def mux_into_message(self, item: ast.Item, t: ir.TypeRef, e: ast.Entry):
        s = self.sink
        got = self.mux_slice(item)
        if got is None:
            return ir.Default()
        mux, start, stop, index = got
        leaves = numeric_leaves(self.store, t.base)
        if leaves is None:
            s.error("E309", f"`{e.key}` is a {t.base}, which is not all numbers: a mux cannot fill it",
                    item.span, f"set its fields one by one: `{e.key}.<field> = ...`")
            return ir.Default()
        if index is not None:
            s.error("E309", f"`{e.key}` is a {t.base} of {len(leaves)} numbers, not one element", item.span)
            return ir.Default()
        types = self.slice_types(mux, start, stop, None)
        if types is not None:
            if len(types) != len(leaves):
                s.error("E309", f"`{e.key}` is a {t.base} of {len(leaves)} numbers "
                        f"({', '.join(p for p, _ in leaves)}), but mux `{mux.name}` gives {len(types)}",
                        item.span, f"take a range: `{mux.name}[0:{len(leaves)}]`")
                return ir.Default()
            bad = sorted({x for x, (_, ft) in zip(types, leaves) if not _fits(x, ft)})
            if bad:
                s.error("E305", f"`{e.key}` holds {', '.join(sorted({ft for _, ft in leaves}))}, "
                        f"mux `{mux.name}` gives {', '.join(bad)}", item.span)
                return ir.Default()
        return ir.MuxRef(mux.name, start, stop, None, False, "float64",
                         tuple(p for p, _ in leaves), tuple(ft for _, ft in leaves))

    def check_lengths(self, msgdef: MsgDef, struct: ir.Struct, entries) -> None:
        group = SAME_LENGTH.get(msgdef.name)
        if not group:
            return
        lengths: dict[str, int] = {}
        for f in struct.fields:
            if f.name not in group:
                continue
            n = self.static_length(f.source)
            if n:
                lengths[f.name] = n
        if len(set(lengths.values())) > 1:
            first, n0 = next(iter(lengths.items()))
            for name, n in lengths.items():
                if n != n0:
                    e = entries.get((name,))
                    self.sink.error(
                        "E312", f"`{name}` has {n} elements but `{first}` has {n0}",
                        e.span if e else None,
                        f"in {msgdef.name}, {', '.join(group)} are empty or of one length")

    def static_length(self, src) -> int | None:
        if isinstance(src, ir.Literal):
            return len(src.values) if src.is_list else None
        if isinstance(src, ir.MuxRef):
            if src.index is not None:
                return 1
            w = self.muxes[src.mux].width
            if w is None:
                if src.stop is not None:
                    return src.stop - src.start
                return None
            stop = w if src.stop is None else src.stop
            return stop - src.start
        return None

    # untyped Bottles
    def untyped_struct(self, prefix: tuple[str, ...], entries, msg_type: str | None) -> ir.Struct:
        order: dict[str, None] = {}
        for p in self.below(entries).get(prefix, {}):
            order.setdefault(p[len(prefix)], None)
        fields = []
        for name in order:
            path = prefix + (name,)
            if path in entries:
                fields.append(ir.Field(name, self.untyped_value(entries[path]), None))
            else:
                fields.append(ir.Field(name, self.untyped_struct(path, entries, None), None))
        return ir.Struct(tuple(fields), msg_type)

    def untyped_value(self, e: ast.Entry):
        items = e.items
        if len(items) == 1:
            return self.untyped_item(items[0], e, top=True)
        if not items:
            return ir.Literal((), "float64", True)
        return self.untyped_list(items, e)

    def untyped_list(self, items, e: ast.Entry):
        s = self.sink
        # a list of sources: literals only, or sources like [counter, time]
        if all(isinstance(i, (ast.Str, ast.Word)) and not self.is_mux_ref(i)
               and not (isinstance(i, ast.Word) and i.text in ("counter", "time", "timestamp")) for i in items):
            values = []
            types = set()
            for i in items:
                v, t = self.untyped_literal(i)
                if v is None:
                    return ir.Default()
                values.append(v)
                types.add(t)
            if len(types) > 1:
                if types <= {"int32", "int64", "float64"}:
                    values = [float(v) for v in values]
                    types = {"float64"}
                else:
                    s.error("E304", "a list holds values of one type", e.span,
                            "quote all items for text, or write only numbers")
                    return ir.Default()
            return ir.Literal(tuple(values), types.pop(), True)
        fields = []
        for k, i in enumerate(items):
            fields.append(ir.Field(str(k), self.untyped_item(i, e, top=False), None))
        return ir.Struct(tuple(fields), None)

    def untyped_item(self, item: ast.Item, e: ast.Entry, top: bool):
        s = self.sink
        if isinstance(item, ast.Bracket):
            if not item.items:
                return ir.Literal((), "float64", True)
            if len(item.items) == 1 and self.is_mux_ref(item.items[0]):
                got = self.mux_slice(item.items[0])
                if got is None:
                    return ir.Default()
                mux, start, stop, index = got
                return ir.MuxRef(mux.name, start, stop, index, False, _common_type(self.slice_types(mux, start, stop, index)))
            return self.untyped_list(item.items, e)
        if isinstance(item, ast.Word) and item.text == "counter":
            return ir.Counter("int32")
        if isinstance(item, ast.Word) and item.text == "time":
            return ir.Seconds()
        if self.is_timestamp(item):
            return self.timestamp(item)
        if self.is_mux_ref(item):
            got = self.mux_slice(item)
            if got is None:
                return ir.Default()
            mux, start, stop, index = got
            return ir.MuxRef(mux.name, start, stop, index, index is None and self.splice,
                             _common_type(self.slice_types(mux, start, stop, index)))
        if isinstance(item, (ast.Str, ast.Word)):
            v, t = self.untyped_literal(item)
            if v is None:
                return ir.Default()
            return ir.Literal((v,), t, False)
        s.error("E105", "unexpected value in [message]", item.span,
                "values are text, numbers, lists `[a, b]`, mux names, counter, time or timestamp")
        return ir.Default()

    def untyped_literal(self, item):
        if isinstance(item, ast.Str):
            return item.value, "string"
        b = item.boolean()
        if b is not None:
            return b, "bool"
        n = item.number()
        if n is None:
            if identifier_problem(item.text) is None and did_you_mean(item.text, list(self.mux_sections)):
                self.unknown_mux(item.text, item.span)
            else:
                self.sink.error("E304", f"`{item.text}` is neither a number nor a mux", item.span,
                                f'quote text: `"{item.text}"`')
            return None, None
        if isinstance(n, float):
            return n, "float64"
        return n, "int32" if -2**31 <= n < 2**31 else "int64"


def bottle_positions(store: TypeStore, msg_type: str, fields) -> tuple[tuple[int, ...], ...]:
    """Index path of each field (``point.x``, ``position``, ``covariance[3]``)
    in the Bottle of a ROS 1 message: YARP's wire mapping, a message is a list
    of its fields in order."""
    out = []
    for path in fields:
        cur = store.resolve(msg_type)
        at: list[int] = []
        for part in path.split("."):
            name, _, rest = part.partition("[")
            assert cur is not None, (msg_type, path)
            names = [f.name for f in cur.fields]
            k = names.index(name)
            at.append(k)
            t = cur.fields[k].type
            if rest:
                at.append(int(rest.rstrip("]")))
                t = t.element()
            cur = store.resolve(t.base) if t.is_message and t.array is None else None
        out.append(tuple(at))
    return tuple(out)


def _looks_number(text: str) -> bool:
    return ast.Word(text).number() is not None


def _fits(elem: str, field_base: str) -> bool:
    """Can a mux element of type ``elem`` go into a field element of ``field_base``?"""
    if elem == field_base:
        return True
    if field_base in ir.FLOAT_TYPES:
        return elem in ir.NUMERIC_TYPES
    if field_base in ir.INTEGER_TYPES:
        if elem not in ir.INTEGER_TYPES:
            return False
        lo, hi = _INT_RANGE[field_base]
        elo, ehi = _INT_RANGE[elem]
        return lo <= elo and ehi <= hi
    if field_base == "bool":
        return elem == "bool"
    if field_base in ("string", "wstring"):
        return elem == "string"
    return False


def _common_type(types) -> str:
    if not types:
        return "float64"
    ts = set(types)
    return ts.pop() if len(ts) == 1 else "mixed"


def check_named(doc: ast.Document, source: str, sink: Sink, options: Options,
                module_default: str) -> ir.Program | None:
    """Check a named-form document; the Program, or None when there are errors."""
    return _Checker(doc, source, sink, options, module_default).run()
