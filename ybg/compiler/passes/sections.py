"""Pass ``sections``: the sections of a named-form config and their keys.

Checks: entries outside a section (E107), unknown sections (E201), the
name of [mux <name>], [service <name>] and [action <name>] and that other
sections have none (E104), duplicate sections (E205), missing [output] or
[message] (E203), sections of two kinds of bridge in one config (E354), and
unknown or duplicate
keys of [module], [output] and each mux (E202, E206).
Reads the document. Sets ``sections``, ``mux_sections``, ``service_sections``,
``action_sections``, ``module_keys``, ``output_keys`` and ``mux_keys``.
"""

from __future__ import annotations

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import did_you_mean
from ybg.compiler.passes.context import Context
from ybg.compiler.values import check_keys

#: section -> its keys ([message] takes field paths, checked by the message passes)
SECTION_KEYS: dict[str, tuple[str, ...]] = {
    "module": ("name", "distro"),
    "output": ("topic", "port", "connect", "type", "via", "node", "rate", "trigger", "queue",
               "on_stale", "on_nan", "publish", "timeout", "reliability", "durability", "depth", "image"),
    "mux": ("ports", "topics", "via", "convert", "verbose", "timeout", "accept", "reliability", "durability", "depth"),
    "message": (),
    # fields of sensor_msgs/CameraInfo, and `topic`, `calibration`: checked by the images pass
    "camera_info": (),
    # a command between a YARP RPC port and a ROS 2 service: checked by the services pass
    "service": (),
    # a ROS 2 action carried out on a robot's ports: checked by the actions pass
    "action": (),
}
#: the sections of a config of streams, which a config of commands has none of
STREAM_SECTIONS = ("output", "mux", "message", "camera_info")

#: key -> the words it takes
CHOICES: dict[str, tuple[str, ...]] = {
    "via": ("ros2", "ros1", "yarp"),
    "trigger": ("all", "any"),
    "on_stale": ("skip", "hold"),
    "on_nan": ("pass", "drop"),
    "publish": ("always", "new"),
    "reliability": ir.RELIABILITIES,
    "durability": ir.DURABILITIES,
}


def run(ctx: Context) -> None:
    s = ctx.sink
    for e in ctx.doc.loose:
        s.error("E107", f"`{e.key}` is not inside a section", e.key_span,
                "put it under a header such as `[output]`")
    out: dict[str, ast.Section] = {}
    muxes: dict[str, ast.Section] = {}
    named: dict[str, dict[str, ast.Section]] = {"service": {}, "action": {}}
    for sec in ctx.doc.sections:
        if sec.name not in SECTION_KEYS:
            s.error("E201", f"unknown section [{sec.title}]", sec.span,
                    did_you_mean(sec.name, SECTION_KEYS) or "sections: [module], [output], [mux <name>], [message], "
                                                            "[camera_info]; for commands [service <name>]; for "
                                                            "actions [action <name>]")
            continue
        if sec.name in named:
            seen = named[sec.name]
            if sec.label is None:
                s.error("E104", f"a{'n' if sec.name == 'action' else ''} {sec.name} section needs a name: "
                                f"`[{sec.name} <name>]`", sec.span,
                        "e.g. `[service home]`; on a YARP port the module serves, the name is the command's word"
                        if sec.name == "service" else "e.g. `[action follow_joint_trajectory]`")
                continue
            if sec.label in seen:
                s.error("E205", f"[{sec.name} {sec.label}] is defined twice", sec.span,
                        f"first defined on line {seen[sec.label].span.line}")
                continue
            seen[sec.label] = sec
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
    services, actions = named["service"], named["action"]
    ctx.service_sections = services
    ctx.action_sections = actions if not services else {}
    if services or actions:
        kind = "commands" if services else "actions"
        for sec in ctx.doc.sections:
            if sec.name in STREAM_SECTIONS or (services and sec.name == "action"):
                s.error("E354", f"[{sec.title}] in a config of {kind}", sec.span,
                        "a config holds one kind of bridge: [service] sections (commands), [action] sections "
                        "or a stream ([output], [mux], [message]): put each in its own config")
        ctx.sections = {k: v for k, v in out.items() if k == "module"}
        module_sec = out.get("module")
        ctx.module_keys = check_keys(module_sec, SECTION_KEYS["module"], s) if module_sec else {}
        return
    image_port = "output" in out and any(e.key == "image" for e in out["output"].entries)
    for need in ("output",) if image_port else ("output", "message"):
        if need not in out:
            s.error("E203", f"missing section [{need}]", None,
                    "a named config has [output], one or more [mux <name>] and [message]")
    ctx.sections = out
    ctx.mux_sections = muxes
    module_sec = out.get("module")
    ctx.module_keys = check_keys(module_sec, SECTION_KEYS["module"], s) if module_sec else {}
    out_sec = out.get("output")
    ctx.output_keys = check_keys(out_sec, SECTION_KEYS["output"], s) if out_sec else {}
    ctx.mux_keys = {name: check_keys(sec, SECTION_KEYS["mux"], s) for name, sec in muxes.items()}
