"""Lowering of a checked config of actions (:class:`~ybg.compiler.ir.Actions`)
to the view-model that ``templates/actions_node.py.j2`` prints: an rclpy
node on the runtime's ``actions`` module (docs/actions.md). The node holds
only data: one ``TrajectorySpec`` a FollowJointTrajectory; what a goal does
is the runtime's (trajectory.py, actions.py). Every value of the config
reaches the source through :func:`~ybg.lower.python.py_literal`."""

from __future__ import annotations

from dataclasses import dataclass

from ybg.compiler import ir
from ybg.lower import actions as texts
from ybg.lower.compose import config_file
from ybg.lower.errors import LoweringError
from ybg.lower.package import PackageView, node_package
from ybg.lower.python import py_literal
from ybg.lower.rosnames import action_type_name, identifier, node_name, split_action
from ybg.backends.ros2.services import SrvImport as ActionImport
from ybg.backends.ros2.services import class_imports

#: names the node's module takes (an action class must not)
_TAKEN = frozenset({"os", "signal", "sys", "yarp", "RUNTIME", "SPEC", "ACTIONS", "ActionsSpec", "TrajectorySpec",
                    "run_actions", "main", "ybgc_runtime"})


@dataclass(frozen=True)
class ActionView:
    """One action: a comment, and its ``TrajectorySpec``'s keyword arguments (name, code)."""

    comment: str
    fields: tuple[tuple[str, str], ...]


@dataclass(frozen=True)
class ActionsView:
    """Everything the node template prints."""

    filename: str
    config: str
    module: str
    node_name: str
    default_prefix: str
    summary: tuple[str, ...]
    imports: tuple[ActionImport, ...]
    actions: tuple[ActionView, ...]
    uses: tuple[str, ...]


def _imports(actions: ir.Actions) -> tuple[dict[str, str], tuple[ActionImport, ...]]:
    types = {}
    for a in actions.actions:
        try:
            types[a.action_type] = split_action(a.action_type)
        except LoweringError as e:
            raise e.at(a.type_span or a.span)
    return class_imports(types, "action", _TAKEN)


def _action(a: ir.TrajectoryAction, cls: str) -> ActionView:
    conversions = texts.joint_conversions(a)
    fields = (
        ("name", py_literal(a.name)),
        ("action", py_literal(a.action)),
        ("action_class", cls),
        ("type_name", py_literal(action_type_name(a.action_type))),
        ("joints", py_literal(a.joints)),
        ("state", py_literal(a.state)),
        ("command", py_literal(a.command)),
        ("width", py_literal(a.width)),
        ("scales", py_literal(tuple(s for s, _ in conversions))),
        ("offsets", py_literal(tuple(o for _, o in conversions))),
        ("rate", py_literal(float(a.rate))),
        ("feedback_rate", py_literal(float(a.feedback_rate))),
        ("path_tolerance", py_literal(a.path_tolerance)),
        ("goal_tolerance", py_literal(a.goal_tolerance)),
        ("goal_time_tolerance", py_literal(float(a.goal_time_tolerance))),
        ("stale", py_literal(float(a.stale))),
        ("description", py_literal(texts.describe(a))),
    )
    return ActionView(texts.describe(a), fields)


def lower(actions: ir.Actions) -> ActionsView:
    """The view-model of the node generated for ``actions``."""
    if not actions.actions:
        raise LoweringError("a config of actions with no action")
    filename = f"{identifier(actions.module, 'module name')}_node.py"
    classes, imports = _imports(actions)
    views = []
    for a in actions.actions:
        try:
            views.append(_action(a, classes[a.action_type]))
        except LoweringError as e:
            raise e.at(a.span)
    uses = tuple(f"{a.action} ({action_type_name(a.action_type)}): the joints {', '.join(a.joints)}, encoders "
                 f"from the YARP port {a.state}, set points to {a.command}" for a in actions.actions)
    return ActionsView(
        filename=filename,
        config=py_literal(config_file(actions)),
        module=py_literal(actions.module),
        node_name=py_literal(node_name(actions)),
        default_prefix=py_literal("/" + actions.module),
        summary=tuple(py_literal(line) for line in [texts.summary(actions)] + [v.comment for v in views]),
        imports=imports,
        actions=tuple(views),
        uses=uses,
    )


def lower_package(actions: ir.Actions, view: ActionsView) -> PackageView:
    """The view-model of the ament_python package around the node."""
    return node_package(actions, view.filename, texts.summary(actions))


__all__ = ["ActionsView", "ActionView", "ActionImport", "lower", "lower_package"]
