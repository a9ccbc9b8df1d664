"""Independent references for the geometry converters and the element-wise
expressions, for the tests: scipy's Rotation (a well-kept rotation library,
installed for the tests only) and numpy's float64 arithmetic. Nothing here
uses ybgc's runtime."""
from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

from ybg.compiler import ir


#: |w| up to which w is 0 (docs/config.md, "Orientation and geometry converters")
ZERO_W = 1e-12


def _canonical(q) -> list[float]:
    """The one of q and -q the converters give (docs/config.md): w > 0; or,
    for |w| <= ZERO_W, w = 0.0 and the first of x, y, z beyond ZERO_W
    positive."""
    q = np.asarray(q, dtype=float)
    if abs(q[3]) <= ZERO_W:
        xyz = q[:3]
        leading = xyz[np.abs(xyz) > ZERO_W]
        sign = -1.0 if leading.size and leading[0] < 0 else 1.0
        return [float(v) for v in sign * xyz] + [0.0]
    return [float(v) for v in (-q if q[3] < 0 else q)]


def geometry(name: str, values: list[float], axes: str | None = None, degrees: bool = False) -> list[float]:
    """What converter ``name`` gives for ``values``, by scipy."""
    v = np.asarray(values, dtype=float)
    if name == "euler_to_quat":
        return _canonical(Rotation.from_euler(axes, v, degrees=degrees).as_quat())
    if name == "quat_to_euler":
        return [float(a) for a in Rotation.from_quat(v).as_euler(axes, degrees=degrees)]
    if name == "axis_angle_to_quat":
        n = np.linalg.norm(v[:3])
        if n == 0:
            return [0.0, 0.0, 0.0, 1.0]
        return _canonical(Rotation.from_rotvec(v[:3] / n * v[3]).as_quat())
    if name == "quat_to_axis_angle":
        # the rotation vector of the canonical quaternion (angle in [0, pi]): at pi,
        # of the two opposite axes (the same rotation), the one of the quaternion
        rotvec = Rotation.from_quat(_canonical(Rotation.from_quat(v).as_quat())).as_rotvec()
        angle = float(np.linalg.norm(rotvec))
        if angle == 0.0:
            return [0.0, 0.0, 1.0, 0.0]
        return [float(a) for a in rotvec / angle] + [angle]
    if name == "matrix_to_quat":
        return _canonical(Rotation.from_matrix(v.reshape(3, 3)).as_quat())
    if name == "transform_to_pose":
        m = v.reshape(4, 4)
        return [float(m[0, 3]), float(m[1, 3]), float(m[2, 3])] + _canonical(
            Rotation.from_matrix(m[:3, :3]).as_quat())
    if name == "quat_normalize":
        return [float(a) for a in v / np.sqrt(np.sum(v * v))]
    raise KeyError(name)


_NUMPY = {"abs": np.fabs, "sqrt": np.sqrt, "sin": np.sin, "cos": np.cos, "atan2": np.arctan2,
          "min": lambda a, b: b if b < a else a, "max": lambda a, b: b if a < b else a,
          "clamp": lambda x, lo, hi: min_(max_(x, lo), hi)}


def min_(a, b):
    return b if b < a else a


def max_(a, b):
    return b if a < b else a


def evaluate(node: ir.ExprNode, x: float) -> float:
    """A checked expression at ``x``, in numpy float64 (IEEE: no exceptions)."""
    with np.errstate(all="ignore"):
        return float(_eval(node, np.float64(x)))


def _eval(node: ir.ExprNode, x):
    op = node.op
    if op == "number":
        return np.float64(node.value)
    if op == "x":
        return x
    if op == "pi":
        return np.float64(math.pi)
    args = [_eval(a, x) for a in node.args]
    if op == "neg":
        return -args[0]
    if op == "+":
        return args[0] + args[1]
    if op == "-":
        return args[0] - args[1]
    if op == "*":
        return args[0] * args[1]
    if op == "/":
        return args[0] / args[1]
    return np.float64(_NUMPY[op](*args))
