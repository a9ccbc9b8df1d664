"""Pass ``dialect``: the module name, and which ROS the config speaks.

The config is ROS 2 when its output or any mux's topics go through ROS 2,
else ROS 1; its message definitions are those of that ROS version and of
the distro from the command line or [module] distro.
Checks: the module name (E214), `via` of [output] and of each mux, topics
read `via = yarp`, and the distro against the ROS version (E208).
Reads ``module_keys``, ``output_keys``, ``mux_keys``. Sets ``module``,
``output_via``, ``mux_via``, ``ros``, ``store`` and ``distro``.
"""

from __future__ import annotations

from ybg.compiler.diagnostics import did_you_mean
from ybg.compiler.msgtypes import DISTROS
from ybg.compiler.names import identifier_problem, sanitize_identifier
from ybg.compiler.passes.context import Context
from ybg.compiler.passes.sections import CHOICES
from ybg.compiler.values import choice, word


def run(ctx: Context) -> None:
    s = ctx.sink
    module_keys = ctx.module_keys
    ctx.module = ctx.module_default
    if "name" in module_keys:
        name = word(module_keys["name"], s)
        if name is not None:
            problem = identifier_problem(name)
            if problem:
                s.error("E214", f"module name `{name}` {problem}", module_keys["name"].items[0].span,
                        f"e.g. `name = {sanitize_identifier(name)}`")
            else:
                ctx.module = name

    via = ctx.output_via = _output_via(ctx)
    mux_via = {}
    for name, keys in ctx.mux_keys.items():
        mux_via[name] = choice(keys["via"], s, CHOICES["via"]) if "via" in keys else None
        if mux_via[name] == "yarp" and "topics" in keys:
            s.error("E208", "topics are read from ROS: `via` is ros1 or ros2", keys["via"].span)
    # commands bridge ROS 2 services; actions serve ROS 2 actions
    ros = "ros2" if via == "ros2" or "ros2" in mux_via.values() or ctx.service_sections or ctx.action_sections \
        else "ros1"
    # topics of a mux without `via` live where the output does, or in the config's ROS
    ctx.mux_via = {name: v or (via if via in ("ros1", "ros2") else ros) for name, v in mux_via.items()}

    distro = ctx.options.distro
    if distro is None and "distro" in module_keys:
        distro = word(module_keys["distro"], s)
        if distro is not None and distro not in DISTROS:
            s.error("E208", f"unknown distro `{distro}`", module_keys["distro"].items[0].span,
                    did_you_mean(distro, DISTROS) or f"known: {', '.join(DISTROS)}")
            distro = None
    if distro is not None and DISTROS.get(distro) != ros:
        where = module_keys["distro"].items[0].span if "distro" in module_keys else None
        s.error("E208", f"distro `{distro}` is {DISTROS.get(distro)}, but this config uses {ros}",
                where, "ROS 1: noetic; ROS 2: humble, jazzy, kilted")
        distro = None
    ctx.ros = ros
    ctx.store = ctx.stores.get(ros, distro)
    ctx.distro = ctx.store.distro


def _output_via(ctx: Context) -> str | None:
    """`via` of [output]; without it, a port is YARP and a topic ROS 2."""
    keys = ctx.output_keys
    if "via" in keys:
        return choice(keys["via"], ctx.sink, CHOICES["via"])
    if "port" in keys:
        return "yarp"
    if "topic" in keys:
        return "ros2"
    return None
