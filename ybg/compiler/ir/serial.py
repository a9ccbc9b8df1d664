"""The IR as JSON, the form ``ybgc ir`` prints: :func:`to_json` and its
inverse :func:`from_json`."""

from __future__ import annotations

import dataclasses
import json
from typing import Any

from ybg.compiler.diagnostics import Span
from ybg.compiler.ir.actions import Actions, TrajectoryAction
from ybg.compiler.ir.commands import BottleItem, Commands, FieldRef, Fill, Service
from ybg.compiler.ir.streams import (IR_VERSION, CameraInfo, Converter, Counter, Default, ElementGroup, ExprConverter,
                                     ExprNode, Field, GeometryConverter, ImageFrame, Input, Literal, MessageArray, Mux,
                                     MuxRef, Output, Policy, Program, QoS, Seconds, Struct, Timestamp, Timing, TypeRef)

_SOURCE_KINDS = {
    "literal": Literal,
    "mux": MuxRef,
    "counter": Counter,
    "timestamp": Timestamp,
    "seconds": Seconds,
    "default": Default,
    "struct": Struct,
    "message_array": MessageArray,
    "image": ImageFrame,
}
_KIND_OF = {cls: kind for kind, cls in _SOURCE_KINDS.items()}
_CONVERTER_KINDS = {"geometry": GeometryConverter, "expr": ExprConverter}
_KIND_OF.update({cls: kind for kind, cls in _CONVERTER_KINDS.items()})


_SPAN_KEYS = ("span", "type_span")


def _span(d: dict[str, Any], key: str = "span") -> Span | None:
    v = d.get(key)
    return None if v is None else Span(*v)


def _encode(obj: Any) -> Any:
    if isinstance(obj, Span):
        return [obj.line, obj.column, obj.end_line, obj.end_column]
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        out: dict[str, Any] = {}
        kind = _KIND_OF.get(type(obj))
        if kind is not None:
            out["kind"] = kind
        for f in dataclasses.fields(obj):
            value = getattr(obj, f.name)
            if f.name in _SPAN_KEYS and value is None:
                continue  # no position: a program built by hand, not from a config
            out[f.name] = _encode(value)
        return out
    if isinstance(obj, tuple):
        return [_encode(x) for x in obj]
    if isinstance(obj, float) and (obj != obj or obj in (float("inf"), float("-inf"))):
        return repr(obj)
    return obj


def to_dict(program: "Program | Commands | Actions") -> dict[str, Any]:
    """The JSON object of ``program``; ``bridge`` says its kind, but for a
    stream (the first kind, whose programs had no ``bridge``)."""
    d = _encode(program)
    if program.kind != Program.kind:
        return {"ir_version": IR_VERSION, "bridge": program.kind, **d}
    return {"ir_version": IR_VERSION, **d}


def to_json(program: "Program | Commands | Actions") -> str:
    return json.dumps(to_dict(program), indent=2, ensure_ascii=False) + "\n"


def _tuple(xs, f):
    return tuple(f(x) for x in xs)


def _source(d: dict[str, Any]) -> Any:
    kind = d["kind"]
    if kind == "struct":
        return _struct(d)
    if kind == "message_array":
        return MessageArray(_tuple(d["elements"], _source), d["msg_type"])
    if kind == "literal":
        return Literal(tuple(d["values"]), d["element_type"], d["is_list"])
    if kind == "mux":
        args = dict(d)
        args.pop("kind")
        for k in ("into_fields", "into_types"):
            if args[k] is not None:
                args[k] = tuple(args[k])
        return MuxRef(**args)
    if kind == "default":
        v = d.get("value")
        return Default(tuple(v) if isinstance(v, list) else v)
    cls = _SOURCE_KINDS[kind]
    return cls(**{k: v for k, v in d.items() if k != "kind"})


def _typeref(d):
    return None if d is None else TypeRef(**d)


def _struct(d: dict[str, Any]) -> Struct:
    return Struct(
        _tuple(d["fields"], lambda f: Field(f["name"], _source(f["source"]), _typeref(f["type"]), _span(f))),
        d["msg_type"], _span(d),
    )


def _commands(d: dict[str, Any]) -> Commands:
    def ref(x):
        return FieldRef(tuple(x["path"]), _typeref(x["type"]), _span(x))

    def item(x):
        return BottleItem(x["kind"], x["value"], x["type"], None if x["ref"] is None else ref(x["ref"]),
                          None if x["converter"] is None else Converter(**{**x["converter"],
                                                                           "span": _span(x["converter"])}),
                          _tuple(x["items"], item), _span(x))

    def fill(x):
        v = x["value"]
        return Fill(ref(x["ref"]), x["source"], x["start"], x["stop"], x["slice"],
                    tuple(v) if isinstance(v, list) else v, _span(x))

    def service(x):
        layout = None if x["layout"] is None else _tuple(x["layout"], lambda g: ElementGroup(**g))
        return Service(x["name"], x["serves"], x["service"], x["srv_type"], x["port"], x["timeout"], layout,
                       _tuple(x["converters"], lambda c: Converter(**{**c, "span": _span(c)})),
                       _tuple(x["bottle"], item), _tuple(x["fills"], fill), _tuple(x["failure_fills"], fill),
                       _tuple(x["failure_bottle"], item), tuple(x["true_words"]), _span(x),
                       _span(x, "type_span"))

    return Commands(d["module"], d["source"], _tuple(d["services"], service), d["distro"], d["ros"])


def _actions(d: dict[str, Any]) -> Actions:
    def action(x):
        layout = None if x["layout"] is None else _tuple(x["layout"], lambda g: ElementGroup(**g))
        return TrajectoryAction(
            x["name"], x["action"], x["action_type"], tuple(x["joints"]), x["state"], x["command"], layout,
            _tuple(x["converters"], lambda c: Converter(**{**c, "span": _span(c)})), x["rate"], x["feedback_rate"],
            x["path_tolerance"], x["goal_tolerance"], x["goal_time_tolerance"], x["stale"], _span(x),
            _span(x, "type_span"))

    return Actions(d["module"], d["source"], _tuple(d["actions"], action), d["distro"], d["ros"])


def from_dict(d: dict[str, Any]) -> "Program | Commands | Actions":
    """Inverse of :func:`to_dict`."""
    if d.get("ir_version") != IR_VERSION:
        raise ValueError(f"unsupported ir_version {d.get('ir_version')!r}")
    read = {Program.kind: _program, Commands.kind: _commands, Actions.kind: _actions}.get(d.get("bridge", Program.kind))
    if read is None:
        raise ValueError(f"unknown kind of bridge {d.get('bridge')!r}")
    return read(d)


def _program(d: dict[str, Any]) -> Program:
    def inp(x):
        layout = None if x["layout"] is None else _tuple(x["layout"], lambda g: ElementGroup(**g))
        fields_ = None if x["fields"] is None else tuple(x["fields"])
        positions = None if x.get("positions") is None else tuple(tuple(p) for p in x["positions"])
        return Input(x["name"], x["kind"], layout, x["ros_type"], fields_, x["timeout"], positions,
                     x.get("reads"), x.get("each"), tuple(x.get("accepts") or ()), x.get("image"),
                     None if x.get("qos") is None else QoS(**x["qos"]), _span(x))

    def node(x):
        return ExprNode(x["op"], _tuple(x["args"], node), x["value"])

    def converter(c):
        args = dict(c)
        kind = args.pop("kind", None)
        args["span"] = _span(args)
        if kind == "expr":
            args["body"] = node(args["body"])
        return _CONVERTER_KINDS.get(kind, Converter)(**args)

    muxes = _tuple(
        d["muxes"],
        lambda m: Mux(m["name"], _tuple(m["inputs"], inp), _tuple(m["converters"], converter), m["verbose"],
                      _span(m)),
    )
    o = d["output"]
    output = Output(o["kind"], o["name"], o["msg_type"], o["node"],
                    None if o["qos"] is None else QoS(**o["qos"]), o["connect_to"], o.get("image"),
                    None if o.get("camera_info") is None else CameraInfo(
                        o["camera_info"]["topic"], _struct(o["camera_info"]["message"]), _span(o["camera_info"])),
                    _span(o), _span(o, "type_span"))
    return Program(
        module=d["module"],
        source=d["source"],
        muxes=muxes,
        message=_struct(d["message"]),
        output=output,
        timing=Timing(**d["timing"]),
        policy=Policy(**d["policy"]),
        ros=d["ros"],
        distro=d["distro"],
    )


def from_json(text: str) -> "Program | Commands | Actions":
    return from_dict(json.loads(text))


__all__ = [
    "ElementGroup", "Input", "Converter", "GeometryConverter", "ExprNode", "ExprConverter", "AnyConverter",
    "GeometryKind", "GEOMETRY", "GEOMETRY_WIDTHS", "QUATERNION_RESULTS", "EULER_AXES", "EXPR_FUNCTIONS", "Mux", "TypeRef", "Literal", "MuxRef",
    "Counter", "Timestamp", "Seconds", "Default", "Field", "Struct", "MessageArray", "QoS", "INPUT_QOS", "ImageFrame",
    "RELIABILITIES", "DURABILITIES", "OUTPUT_QOS", "SENSOR_DATA_QOS", "RELIABLE_INPUT_DEPTH",
    "CameraInfo", "IMAGE_ENCODINGS", "PIXEL_NAMES", "ANY_ENCODING", "IMAGE_TYPE", "FRAME_FIELDS",
    "DEFAULT_QUEUE", "DEFAULT_TRIGGER", "DEFAULT_ON_STALE", "DEFAULT_ON_NAN",
    "Output", "Timing", "Policy", "Program", "to_dict", "to_json", "from_dict",
    "from_json", "IR_VERSION", "NUMERIC_TYPES", "INTEGER_TYPES", "FLOAT_TYPES",
    "ELEMENT_TYPES", "FieldRef", "BottleItem", "Fill", "Service", "Commands", "TRUE_WORDS",
    "SERVICE_TIMEOUT", "RESERVED_COMMANDS",
]


__all__ = [
    "to_dict",
    "to_json",
    "from_dict",
    "from_json",
]
