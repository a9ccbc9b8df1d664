"""Pass ``program``, the last: what can be said only once everything else
is checked, and the checked :class:`~ybg.compiler.ir.Program`.

Checks: muxes that no field uses (W501, only on an error-free config),
problems of the .msg files read (E301), and, on an otherwise error-free
config, [output]'s timing and policy keys (`rate`, `trigger`, `queue`,
`on_stale`, `on_nan`, `publish`: W510, N602) and that something makes the
module publish: an input, or a rate (E216).
Reads every field. Sets ``program`` when there is no error.
"""

from __future__ import annotations

from ybg.compiler import ir
from ybg.compiler.passes import output as output_keys
from ybg.compiler.passes.context import Context


def run(ctx: Context) -> None:
    s = ctx.sink
    for name, sec in ctx.mux_sections.items():
        if name in ctx.muxes and name not in ctx.used_muxes and not s.has_errors:
            s.warning("W501", f"mux `{name}` is not used by [message]", sec.span,
                      f"use it in a field (`position = {name}`) or remove the section")
    for p in ctx.store.problems:
        s.error("E301", f"{p.path}:{p.line}:{p.column}: {p.message}", None,
                "fix the .msg file, or remove its folder from --msg-path")
    output, message = ctx.output, ctx.message
    if s.has_errors or output is None or message is None:
        return
    rate = output_keys.rate(ctx)
    timing = ir.Timing(
        rate=rate,
        trigger=output_keys.chosen(ctx, "trigger", ir.DEFAULT_TRIGGER),
        queue=output_keys.queue(ctx),
        publish=_publish(ctx, output, rate),
    )
    policy = ir.Policy(
        on_stale=output_keys.chosen(ctx, "on_stale", ir.DEFAULT_ON_STALE),
        on_nan=output_keys.chosen(ctx, "on_nan", ir.DEFAULT_ON_NAN),
    )
    if s.has_errors:
        return
    muxes = tuple(ctx.muxes.values())
    if timing.rate is None and not any(m.inputs for m in muxes):
        sec = ctx.sections.get("output")
        s.error("E216", "no input and no `rate`: nothing would make the module publish", sec.span if sec else None,
                "set `rate = <Hz>` in [output] to publish at a fixed rate, or read an input "
                "(`[mux <name>]` with `ports = ...`)")
        return
    ctx.program = ir.Program(
        module=ctx.module, source=ctx.source, muxes=muxes, message=message,
        output=output, timing=timing, policy=policy,
        ros=ctx.ros if (output.kind != "yarp" or any(i.kind != "yarp" for m in muxes for i in m.inputs)
                        or message.msg_type) else None,
        distro=ctx.distro,
    )


def _publish(ctx: Context, output: ir.Output, rate: float | None) -> str:
    """[output] publish; by default "new" for a bridge from ROS topics to a
    YARP port (it carries commands: the original tool wrote once per new
    input), "always" otherwise (a state stream, published every cycle)."""
    entry = ctx.output_keys.get("publish")
    if entry is not None:
        if rate is None:
            ctx.sink.warning("W510", "`publish` chooses what a cycle of a fixed rate does, and this "
                             "output has no `rate`: it publishes once per new data", entry.span,
                             "add `rate = <Hz>`, or remove `publish`")
        return output_keys.chosen(ctx, "publish", "always")
    inputs = [i for m in ctx.muxes.values() if m.name in ctx.used_muxes for i in m.inputs]
    commands = output.kind == "yarp" and inputs and all(i.kind != "yarp" for i in inputs)
    if not commands:
        return "always"
    if rate is not None:
        rate_entry = ctx.output_keys.get("rate")
        ctx.sink.note("N602", f"ROS topics to a YARP port: at {rate:g} Hz the module publishes only when "
                      "new data arrived, not the same command at every cycle (`publish = new`)",
                      rate_entry.span if rate_entry else None,
                      "`publish = always` repeats the newest values at every cycle")
    return "new"
