"""Pass ``actions``: the [action <name>] sections of a config of actions.

Each section serves one ROS 2 action carried out on a robot's YARP ports
(docs/actions.md): today a ``control_msgs/FollowJointTrajectory`` from a
part's encoder port (``state``) and a port that takes its set points
(``command``).
Checks: the keys (E202, E204), the action's name (E402) and type (E380;
E381 for a type this section cannot carry out), the ports (E401) and the
state port's declaration (E213), the joints (E382: none, twice, or more than
the state port is declared to hold), the converters (E208, E313, E314,
E315; E383 for one with no inverse, which the set points need), the rates
and timeouts (E208) and the tolerances (E384: not a number, or negative),
and an action or a port given twice (E385).
Reads ``action_sections``, ``module``, ``store`` and ``distro``. Sets
``program`` to an :class:`~ybg.compiler.ir.Actions` when nothing is wrong.
"""

from __future__ import annotations

import math

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import closest
from ybg.compiler.msgtypes import ActionDef
from ybg.compiler.names import identifier_problem, port_problem, sanitize_identifier, topic_problem
from ybg.compiler.passes.context import Context
from ybg.compiler.passes.inputs import _layout
from ybg.compiler.passes.services import _converters, _endpoint
from ybg.compiler.values import check_keys, number

#: the keys of an [action] section
ACTION_KEYS = ("serve", "joints", "state", "command", "convert", "rate", "feedback_rate", "path_tolerance",
               "goal_tolerance", "goal_time_tolerance", "stale")
_EXAMPLE = ("e.g.\n  serve = /arm_controller/follow_joint_trajectory (control_msgs/FollowJointTrajectory)\n"
            "  joints = \"shoulder\", \"elbow\"\n  state = /robot/arm/state:o (float64 x2)\n"
            "  command = /robot/arm/setpoints:i\n  convert = deg_to_rad")


def run(ctx: Context) -> None:
    actions: list[ir.TrajectoryAction] = []
    for label, sec in ctx.action_sections.items():
        act = _action(ctx, label, sec)
        if act is not None:
            actions.append(act)
    _clashes(ctx, actions)
    if not ctx.sink.has_errors and len(actions) == len(ctx.action_sections):
        ctx.program = ir.Actions(ctx.module, ctx.source, tuple(actions), ctx.distro, "ros2")


def _action(ctx: Context, label: str, sec: ast.Section) -> ir.TrajectoryAction | None:
    s = ctx.sink
    errors = s.error_count
    keys = check_keys(sec, ACTION_KEYS, s)
    problem = identifier_problem(label)
    if problem:
        s.error("E214", f"action name `{label}` {problem}", sec.span, f"e.g. `[action {sanitize_identifier(label)}]`")
    missing = [k for k in ("serve", "joints", "state", "command") if k not in keys]
    if missing:
        s.error("E204", f"[action {label}] has no {', '.join(f'`{k}`' for k in missing)}", sec.span, _EXAMPLE)
        return None
    serve = _endpoint(ctx, keys["serve"])
    if serve is None:
        return None
    if serve.srv_type is None:
        s.error("E380", f"[action {label}]: `serve` names no action type", serve.span,
                "give the type in parentheses: `serve = /arm_controller/follow_joint_trajectory "
                "(control_msgs/FollowJointTrajectory)`")
        return None
    problem = topic_problem(serve.name)
    if problem:
        s.error("E402", f"invalid ROS 2 action name `{serve.name}`: {problem}", serve.span)
    definition = _action_type(ctx, serve.srv_type, serve.type_span)
    state = _endpoint(ctx, keys["state"])
    command = _endpoint(ctx, keys["command"])
    if state is None or command is None:
        return None
    for key, end in (("state", state), ("command", command)):
        problem = port_problem(end.name)
        if problem:
            s.error("E401", f"invalid YARP port name `{end.name}`: {problem}", end.span,
                    "a YARP port name starts with `/`, e.g. `/icub/right_arm/state:o`")
        if end.srv_type is not None:
            s.error("E213", f"`{key}` is a YARP port, not a ROS type", end.type_span,
                    "e.g. `state = /icub/right_arm/state:o (float64 x16)`" if key == "state"
                    else "e.g. `command = /icub/right_arm/setpoints:i`")
    if command.decl is not None:
        s.error("E213", "`command` takes no declaration: the set points are one float64 a joint",
                command.decl_span, "write `command = /robot/arm/setpoints:i`")
    layout = None
    if state.decl is not None and state.srv_type is None:
        layout = _layout(ctx, state.decl, state.decl_span)
    joints = _joints(ctx, keys["joints"], layout, state)
    convs = _converters(ctx, keys.get("convert"), "state", layout)
    if convs is not None:
        for c in convs:
            if c.scale == 0:
                s.error("E383", f"`{c.name}` has no inverse: the set points are the encoders' units, converted "
                                "back from the goal's", c.span, "a scale is not 0 here")
    rate = _number(ctx, keys, "rate", ir.TRAJECTORY_RATE)
    feedback_rate = _number(ctx, keys, "feedback_rate", ir.FEEDBACK_RATE)
    stale = _number(ctx, keys, "stale", ir.STALE_AFTER)
    path = _tolerance(ctx, keys.get("path_tolerance"))
    goal = _tolerance(ctx, keys.get("goal_tolerance"))
    goal_time = _tolerance(ctx, keys.get("goal_time_tolerance"))
    if s.error_count != errors or definition is None or joints is None or convs is None:
        return None
    return ir.TrajectoryAction(label, serve.name, definition.name, joints, state.name, command.name, layout,
                               tuple(convs), rate, feedback_rate, path, goal, goal_time or 0.0, stale,
                               span=sec.span, type_span=serve.type_span)


def _action_type(ctx: Context, name: str, span) -> ActionDef | None:
    s = ctx.sink
    store = ctx.store
    found = store.resolve_action(name) if store is not None else None
    if found is None:
        where = store.action_path(name) if store is not None else None
        if where is not None:
            s.error("E380", f"action type `{name}` cannot be read: its definition has problems", span, f"see {where}")
            return None
        known = store.action_names() if store is not None else []
        bare = name.split("/")[-1]
        guesses = [k for k in known if k.endswith("/" + bare)]
        guess = guesses[0] if guesses else closest(name, known)
        s.error("E380", f"unknown action type `{name}`", span,
                f"did you mean `{guess}`?" if guess else
                f"no `.action` defines it for {ctx.distro}: give the folder of your package with `--msg-path DIR`, "
                "where it is DIR/<pkg>/action/<Name>.action")
        return None
    if found.name not in ir.TRAJECTORY_TYPES:
        s.error("E381", f"[action] carries out {', '.join(ir.TRAJECTORY_TYPES)}; `{found.name}` is not one",
                span, "an action of another type is not yet carried out by a module (docs/actions.md)")
        return None
    return found


def _joints(ctx: Context, entry: ast.Entry, layout, state) -> tuple[str, ...] | None:
    s = ctx.sink
    names: list[str] = []
    for item in entry.items:
        text = item.value if isinstance(item, ast.Str) else item.text if isinstance(item, ast.Word) else None
        if not text:
            s.error("E382", "`joints` lists the joints' names, as the robot's URDF and MoveIt name them", item.span,
                    'e.g. `joints = "r_shoulder_pitch", "r_shoulder_roll", "r_elbow"`')
            return None
        if text in names:
            s.error("E382", f"joint `{text}` is listed twice", item.span,
                    "each joint is one element of the state port, listed once")
            return None
        names.append(text)
    if not names:
        s.error("E382", "`joints` lists no joint", entry.span, 'e.g. `joints = "shoulder", "elbow"`')
        return None
    width = None if layout is None else sum(g.count for g in layout)
    if width is not None and len(names) > width:
        s.error("E382", f"{len(names)} joints, but {state.name} is declared to hold {width} values", entry.span,
                f"the joints are the state port's first values, in order: list at most {width}, or declare the "
                f"port as it is, e.g. `({layout[0].type} x{len(names)})`")
        return None
    if layout is not None:
        kinds = [g.type for g in layout for _ in range(g.count)][:len(names)]
        bad = [k for k in kinds if k not in ir.NUMERIC_TYPES]
        if bad:
            s.error("E382", f"the joints' values on {state.name} are declared `{bad[0]}`, not numbers",
                    state.decl_span, "an encoder is a number, e.g. `(float64 x16)`")
            return None
    return tuple(names)


def _number(ctx: Context, keys: dict, key: str, default: float) -> float:
    if key not in keys:
        return default
    got = number(keys[key], ctx.sink)
    return default if got is None else got


def _tolerance(ctx: Context, entry: ast.Entry | None) -> float | None:
    """A tolerance: a number, 0 or more; None when not given."""
    if entry is None:
        return None
    item = entry.items[0] if len(entry.items) == 1 else None
    value = item.number() if isinstance(item, ast.Word) else None
    if value is None or isinstance(value, bool) or not math.isfinite(value) or value < 0:
        ctx.sink.error("E384", f"`{entry.key}` is a number, 0 or more (radians, or seconds for "
                               f"`goal_time_tolerance`)", item.span if item is not None else entry.span,
                       "a goal's own -1 lifts the config's tolerance for that goal; to check none, leave the key out")
        return None
    return float(value)


def _clashes(ctx: Context, actions: list[ir.TrajectoryAction]) -> None:
    seen_action: dict[str, ir.TrajectoryAction] = {}
    seen_command: dict[str, ir.TrajectoryAction] = {}
    for a in actions:
        if a.action in seen_action:
            ctx.sink.error("E385", f"action {a.action} is served twice", a.span,
                           f"first by [action {seen_action[a.action].name}]")
        seen_action.setdefault(a.action, a)
        if a.command in seen_command:
            ctx.sink.error("E385", f"{a.command} takes the set points of two actions", a.span,
                           f"[action {seen_command[a.command].name}] writes to it too: one joint, one commander")
        seen_command.setdefault(a.command, a)
