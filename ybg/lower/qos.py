"""The ROS 2 QoS of the IR (an output's, a topic input's), checked once for
every backend that builds it: the policies each runtime can make."""

from __future__ import annotations

from ybg.compiler import ir
from ybg.compiler.diagnostics import Span
from ybg.lower.errors import LoweringError


def checked_qos(qos: ir.QoS, span: Span | None = None) -> ir.QoS:
    """``qos``, or a LoweringError at ``span`` when a runtime cannot make it
    (the checker refuses such a config first: this guards the IR a program
    builds by hand)."""
    if qos.reliability not in ir.RELIABILITIES or qos.durability not in ir.DURABILITIES or int(qos.depth) < 1:
        raise LoweringError(f"unsupported QoS {qos}", span)
    return qos


__all__ = ["checked_qos"]
