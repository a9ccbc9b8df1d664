"""What every backend of actions says and computes alike (docs/actions.md):
each joint's encoder conversion as one scale and offset (the set points are
converted back by its inverse), and the texts of what an action does."""

from __future__ import annotations

from ybg.compiler import ir
from ybg.lower.errors import LoweringError
from ybg.lower.rosnames import action_type_name


def joint_conversions(action: ir.TrajectoryAction) -> tuple[tuple[float, float], ...]:
    """(scale, offset) of each joint: its encoder value ``x`` is
    ``x * scale + offset`` in the goal's units, the converters applied in
    their order to the joint's element of the state Bottle."""
    out = []
    for k in range(len(action.joints)):
        scale, offset = 1.0, 0.0
        for c in action.converters:
            stop = c.stop if c.stop is not None else k + 1
            if c.start <= k < stop:
                scale, offset = scale * c.scale, offset * c.scale + c.offset
        if scale == 0:
            raise LoweringError(f"joint {action.joints[k]!r}: its converters scale by 0, which set points cannot "
                                f"be converted back from", action.span)
        out.append((scale, offset))
    return tuple(out)


def describe(action: ir.TrajectoryAction) -> str:
    """One line: what the action serves and what it drives."""
    return (f"action {action.name}: {action.action} ({action_type_name(action.action_type)}) for "
            f"{len(action.joints)} joints, encoders from {action.state}, set points to {action.command} "
            f"at {action.rate:g} Hz")


def summary(actions: ir.Actions) -> str:
    """A line of what the module is."""
    return f"ROS 2 node {actions.module}: {len(actions.actions)} action(s) carried out on YARP ports"


__all__ = ["joint_conversions", "describe", "summary"]
