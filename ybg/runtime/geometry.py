"""Orientation and geometry converters, and the functions of element-wise
expressions (docs/config.md, "Converters"), with no middleware.

Each converter takes the elements of a range of a mux and gives the elements
that replace them: Euler angles (3) <-> quaternion (4), axis-angle (4) <->
quaternion, a 3x3 rotation matrix (9, row-major) -> quaternion, a 4x4
homogeneous transform (16, row-major) -> translation and quaternion (7), a
quaternion normalised. Quaternions are ``x y z w``, as ROS orders them; a
converter that gives one gives the canonical one of q and -q (``_positive``:
w > 0, or w = 0 and the first non-zero of x, y, z positive, with 1e-12 for 0).

The C++ runtime (``ybgc_convert.cpp``) does the same operations in the same
order with the same libm, so that both give the same bits; a result that is
not finite (a NaN input, a zero quaternion, a matrix that is no rotation) is
all NaN in both. Python raises where C gives an infinity or a NaN (a division
by zero, ``sqrt`` of a negative number, ``sin`` of an infinity): those are
caught and give NaN, as C would."""

import math

NAN = float("nan")
#: degrees -> radians and back, the same doubles as deg_to_rad and rad_to_deg
DEG = math.pi / 180.0
RAD = 180.0 / math.pi

#: |cos| of the middle Euler angle under which quat_to_euler takes it for +-pi/2
GIMBAL_LOCK = 1e-8

#: |w| up to which a quaternion's w is 0 (the rounding of a 180-degree
#: rotation's, some 1e-16), for the sign of the quaternion a converter gives
ZERO_W = 1e-12

#: Euler axis orders: fixed (extrinsic) axes, the first rotation first.
#: "xyz" is ROS's rpy: R = Rz(yaw) Ry(pitch) Rx(roll).
AXES = {"xyz": (0, 1, 2), "xzy": (0, 2, 1), "yxz": (1, 0, 2),
        "yzx": (1, 2, 0), "zxy": (2, 0, 1), "zyx": (2, 1, 0)}


def _parity(i, j, k):
    """+1.0 for an even permutation of (0, 1, 2), -1.0 for an odd one."""
    return 1.0 if (i, j, k) in ((0, 1, 2), (1, 2, 0), (2, 0, 1)) else -1.0


def _finite(values):
    """``values``, or all NaN when one of them is not finite."""
    for v in values:
        if not math.isfinite(v):
            return [NAN] * len(values)
    return list(values)


def _guarded(function):
    def run(values, *args):
        try:
            return _finite(function(*values, *args))
        except (ZeroDivisionError, ValueError, OverflowError):
            return [NAN] * GEOMETRY_WIDTHS[function.__name__][1]
    run.__name__ = function.__name__
    run.__doc__ = function.__doc__
    return run


def _qmul(p, q):
    """The quaternion product p q (x y z w): q first, then p."""
    px, py, pz, pw = p
    qx, qy, qz, qw = q
    return (pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx,
            pw * qz + px * qy - py * qx + pz * qw,
            pw * qw - px * qx - py * qy - pz * qz)


def _unit(x, y, z, w):
    n = math.sqrt(x * x + y * y + z * z + w * w)
    return x / n, y / n, z / n, w / n


def _positive(q):
    """The canonical one of q and -q (the same rotation): w > 0; or, when
    |w| <= ZERO_W (a rotation of 180 degrees, whose w the arithmetic leaves
    at some 1e-16 of either sign), w = 0.0 and the first of x, y, z beyond
    ZERO_W positive. A NaN stays (the result is then all NaN)."""
    x, y, z, w = q
    if abs(w) <= ZERO_W:
        for v in (x, y, z):
            if abs(v) > ZERO_W:
                if v < 0.0:
                    return -x, -y, -z, 0.0
                break
        return x, y, z, 0.0
    if w < 0.0:
        return -x, -y, -z, -w
    return q


def _rot(q, r, c):
    """Element (r, c) of the rotation matrix of the unit quaternion q."""
    w = q[3]
    if r == c:
        a, b = [k for k in (0, 1, 2) if k != r]
        return 1.0 - 2.0 * (q[a] * q[a] + q[b] * q[b])
    m = 3 - r - c
    return 2.0 * (q[r] * q[c] - _parity(r, c, m) * q[m] * w)


def euler_to_quat(a1, a2, a3, axes, degrees):
    """Euler angles about the fixed axes ``axes`` (``a1`` about the first
    axis first) -> quaternion x y z w."""
    if degrees:
        a1, a2, a3 = a1 * DEG, a2 * DEG, a3 * DEG
    q = (0.0, 0.0, 0.0, 1.0)
    for axis, angle in zip(AXES[axes], (a1, a2, a3)):
        h = angle * 0.5
        e = [0.0, 0.0, 0.0, math.cos(h)]
        e[axis] = math.sin(h)
        q = _qmul(e, q)
    return _positive(q)


def quat_to_euler(x, y, z, w, axes, degrees):
    """Quaternion x y z w (normalised first) -> Euler angles about the fixed
    axes ``axes``; the middle angle in [-pi/2, pi/2]. At the gimbal lock
    (the middle angle +-pi/2) the last angle is 0 and the first one makes
    the rotation."""
    q = _unit(x, y, z, w)
    i, j, k = AXES[axes]
    s = _parity(i, j, k)
    rkj, rkk = _rot(q, k, j), _rot(q, k, k)
    c = math.sqrt(rkj * rkj + rkk * rkk)  # |cos(a2)|
    a2 = math.atan2(-s * _rot(q, k, i), c)
    if c < GIMBAL_LOCK:
        # the middle angle is +-pi/2: only a1 + a3 (or a1 - a3) is defined; a3 = 0
        a1 = math.atan2(-s * _rot(q, j, k), _rot(q, j, j))
        a3 = 0.0
    else:
        a1 = math.atan2(s * rkj, rkk)
        a3 = math.atan2(s * _rot(q, j, i), _rot(q, i, i))
    if degrees:
        return a1 * RAD, a2 * RAD, a3 * RAD
    return a1, a2, a3


def axis_angle_to_quat(ax, ay, az, theta):
    """Axis-angle (iCub's ax ay az theta, the angle in radians; the axis is
    normalised, a zero axis is no rotation) -> quaternion x y z w."""
    n = math.sqrt(ax * ax + ay * ay + az * az)
    if n == 0.0:
        return 0.0, 0.0, 0.0, 1.0
    h = theta * 0.5
    s = math.sin(h) / n
    return _positive((ax * s, ay * s, az * s, math.cos(h)))


def quat_to_axis_angle(x, y, z, w):
    """Quaternion x y z w (normalised first) -> unit axis and angle in
    [0, pi]; no rotation is the axis 0 0 1 with angle 0."""
    x, y, z, w = _positive(_unit(x, y, z, w))
    v = math.sqrt(x * x + y * y + z * z)
    if v == 0.0:
        return 0.0, 0.0, 1.0, 0.0
    return x / v, y / v, z / v, 2.0 * math.atan2(v, w)


def matrix_to_quat(*m):
    """A 3x3 rotation matrix, row-major -> quaternion x y z w, normalised,
    canonical (_positive; Shepperd's method: the largest of w, x, y, z first)."""
    m00, m01, m02, m10, m11, m12, m20, m21, m22 = m
    tr = m00 + m11 + m22
    if tr > 0.0:
        s = math.sqrt(tr + 1.0) * 2.0
        q = ((m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s, 0.25 * s)
    elif m00 > m11 and m00 > m22:
        s = math.sqrt(1.0 + m00 - m11 - m22) * 2.0
        q = (0.25 * s, (m01 + m10) / s, (m02 + m20) / s, (m21 - m12) / s)
    elif m11 > m22:
        s = math.sqrt(1.0 + m11 - m00 - m22) * 2.0
        q = ((m01 + m10) / s, 0.25 * s, (m12 + m21) / s, (m02 - m20) / s)
    else:
        s = math.sqrt(1.0 + m22 - m00 - m11) * 2.0
        q = ((m02 + m20) / s, (m12 + m21) / s, 0.25 * s, (m10 - m01) / s)
    return _positive(_unit(*q))


def transform_to_pose(*m):
    """A 4x4 homogeneous transform, row-major -> translation x y z, then
    the quaternion x y z w of its rotation (the layout of
    geometry_msgs/Pose and Transform)."""
    return (m[3], m[7], m[11]) + matrix_to_quat(m[0], m[1], m[2], m[4], m[5], m[6], m[8], m[9], m[10])


def quat_normalize(x, y, z, w):
    """A quaternion x y z w divided by its norm."""
    return _unit(x, y, z, w)


#: converter -> (elements it takes, elements it gives)
GEOMETRY_WIDTHS = {
    "euler_to_quat": (3, 4),
    "quat_to_euler": (4, 3),
    "axis_angle_to_quat": (4, 4),
    "quat_to_axis_angle": (4, 4),
    "matrix_to_quat": (9, 4),
    "transform_to_pose": (16, 7),
    "quat_normalize": (4, 4),
}

#: the converters as the runtime applies them: a list of floats in, a list out
GEOMETRY = {f.__name__: _guarded(f) for f in (
    euler_to_quat, quat_to_euler, axis_angle_to_quat, quat_to_axis_angle, matrix_to_quat,
    transform_to_pose, quat_normalize)}


# --- the functions of element-wise expressions ------------------------------
# C's results where Python would raise; min and max as std::min and std::max.

def div(a, b):
    """a / b, an infinity or NaN for b == 0 as in IEEE arithmetic."""
    if b == 0.0:
        if a == 0.0 or a != a:
            return NAN
        return math.copysign(math.inf, a) * math.copysign(1.0, b)
    return a / b


def sqrt(x):
    return NAN if x < 0.0 else math.sqrt(x)


def sin(x):
    return NAN if math.isinf(x) else math.sin(x)


def cos(x):
    return NAN if math.isinf(x) else math.cos(x)


atan2 = math.atan2
fabs = math.fabs


def min_of(a, b):
    """b if b < a else a (std::min)."""
    return b if b < a else a


def max_of(a, b):
    """b if a < b else a (std::max)."""
    return b if a < b else a


def clamp(x, lo, hi):
    """x bounded to [lo, hi]: min_of(max_of(x, lo), hi)."""
    return min_of(max_of(x, lo), hi)
