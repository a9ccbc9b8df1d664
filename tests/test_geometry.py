"""The orientation and geometry converters and the element-wise expressions.

- Python (ybg/runtime/geometry.py) against an independent reference,
  scipy's Rotation (tests/harness/geometry_reference.py), to 1e-12, on what
  hypothesis draws; round trips away from singularities.
- C++ (ybgc_convert.cpp, built with -ffp-contract=off as a module is) against
  Python bit for bit, on what hypothesis draws (finite or not): a small
  program (tests/runtime/geometry_check.cpp) reads the inputs on its stdin.
- Expressions: the code each backend compiles from the checked tree, C++ and
  Python bit for bit, and numpy's float64 arithmetic to 1e-12.
- The checker's widths are the runtime's; `ybgc fmt` keeps an expression's
  tree.
"""
from __future__ import annotations

import math
import struct
import subprocess
import warnings
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, example, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from harness import geometry_reference
from harness.build import cmake_build
from harness.env import yarp_install
from harness.properties import TIMED_CHECKS, examples
from ybg.backends.cpp.lower import cpp_expression
from ybg.backends.runtime import CPP_SOURCES
from ybg.lower.python import py_expression
from ybg.compiler import ir
from ybg.compiler.diagnostics import Sink
from ybg.compiler.fmt import format_document
from ybg.compiler.parser import parse_text
from ybg.compiler.passes.converters import _node
from ybg.runtime import geometry

RUNTIME = Path(__file__).resolve().parents[1] / "ybg" / "runtime" / "cpp"
HELPER = Path(__file__).resolve().parent / "runtime" / "geometry_check.cpp"
TOL = 1e-12
SETTINGS = settings(max_examples=examples(300), deadline=None,
                    suppress_health_check=[HealthCheck.function_scoped_fixture, *TIMED_CHECKS])

angle = st.floats(-math.pi, math.pi)
#: the middle Euler angle away from the gimbal lock (+-pi/2)
middle = st.floats(-math.pi / 2 + 0.05, math.pi / 2 - 0.05)
unit = st.floats(-1.0, 1.0)
quaternion = st.tuples(unit, unit, unit, unit).filter(lambda q: math.sqrt(sum(v * v for v in q)) > 0.1)
axis = st.tuples(unit, unit, unit).filter(lambda a: math.sqrt(sum(v * v for v in a)) > 0.1)
anything = st.floats(allow_nan=True, allow_infinity=True)


def py(name: str, values, axes: str | None = None, degrees: bool = False) -> list[float]:
    args = (axes, degrees) if axes is not None else ()
    return geometry.GEOMETRY[name](list(values), *args)


def close(got, want, tol=TOL) -> bool:
    return len(got) == len(want) and all(abs(a - b) <= tol for a, b in zip(got, want))


def close_angles(got, want, tol, turn=2 * math.pi) -> bool:
    """Angles equal to ``tol``, pi and -pi being the same angle."""
    return len(got) == len(want) and all(
        abs(math.remainder(a - b, turn)) <= tol for a, b in zip(got, want))


def same_bits(a: list[float], b: list[float]) -> bool:
    return len(a) == len(b) and all(
        (math.isnan(x) and math.isnan(y)) or struct.pack("<d", x) == struct.pack("<d", y) for x, y in zip(a, b))


def matrix_of(q) -> list[float]:
    return [float(v) for v in Rotation.from_quat(q).as_matrix().ravel()]


# --------------------------------------------------------------------------
# Python against scipy


@SETTINGS
@given(st.sampled_from(ir.EULER_AXES), angle, middle, angle, st.booleans())
def test_euler_to_quat_and_back(axes, a1, a2, a3, degrees):
    angles = [a1, a2, a3]
    if degrees:
        angles = [math.degrees(a) for a in angles]
    q = py("euler_to_quat", angles, axes, degrees)
    assert close(q, geometry_reference.geometry("euler_to_quat", angles, axes, degrees))
    assert q[3] >= 0.0
    back = py("quat_to_euler", q, axes, degrees)
    turn = 360.0 if degrees else 2 * math.pi
    tol = 1e-10 if degrees else 1e-12
    assert close_angles(back, geometry_reference.geometry("quat_to_euler", q, axes, degrees), tol, turn)
    assert close_angles(back, angles, 10 * tol, turn)


@SETTINGS
@given(st.sampled_from(ir.EULER_AXES), quaternion, st.booleans())
def test_quat_to_euler_is_the_same_rotation(axes, q, degrees):
    """Any quaternion: the angles make the same rotation, to 1e-12 away from
    the gimbal lock, and near it to what the lock's threshold allows."""
    angles = py("quat_to_euler", q, axes, degrees)
    mid = angles[1] if not degrees else math.radians(angles[1])
    assert -math.pi / 2 <= mid <= math.pi / 2
    near = abs(abs(mid) - math.pi / 2) < 1e-3
    got = Rotation.from_euler(axes, angles, degrees=degrees)
    assert got.approx_equal(Rotation.from_quat(q), atol=1e-7 if near else 1e-12)


@pytest.mark.parametrize("axes", ir.EULER_AXES)
@pytest.mark.parametrize("sign", [1, -1])
def test_quat_to_euler_at_the_gimbal_lock(axes, sign):
    """The middle angle exactly +-90 degrees: the last angle is 0 and the
    first one makes the rotation."""
    for first, last in ((0.3, -1.1), (2.5, 0.7), (-3.0, 3.0)):
        q = py("euler_to_quat", [first, sign * math.pi / 2, last], axes)
        angles = py("quat_to_euler", q, axes)
        assert angles[2] == 0.0 and abs(abs(angles[1]) - math.pi / 2) < 1e-7
        assert Rotation.from_euler(axes, angles).approx_equal(Rotation.from_quat(q), atol=1e-8)


def test_rpy_is_ros_convention():
    """rpy = xyz about fixed axes: R = Rz(yaw) Ry(pitch) Rx(roll), as tf2's setRPY."""
    roll, pitch, yaw = 0.1, -0.4, 2.0
    q = py("euler_to_quat", [roll, pitch, yaw], "xyz")
    rz = Rotation.from_rotvec([0, 0, yaw])
    ry = Rotation.from_rotvec([0, pitch, 0])
    rx = Rotation.from_rotvec([roll, 0, 0])
    assert (rz * ry * rx).approx_equal(Rotation.from_quat(q), atol=1e-15)
    # tf2's closed form of setRPY
    cr, sr, cp, sp, cy, sy = (math.cos(roll / 2), math.sin(roll / 2), math.cos(pitch / 2), math.sin(pitch / 2),
                              math.cos(yaw / 2), math.sin(yaw / 2))
    want = [sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy]
    assert close(q, want if want[3] >= 0 else [-v for v in want])


@SETTINGS
@given(axis, st.floats(1e-3, math.pi - 1e-3), st.floats(0.5, 2.0))
def test_axis_angle_to_quat_and_back(a, theta, length):
    """iCub's 4-value form: the axis (of any length) and the angle in radians."""
    values = [v * length for v in a] + [theta]
    q = py("axis_angle_to_quat", values)
    assert close(q, geometry_reference.geometry("axis_angle_to_quat", values))
    back = py("quat_to_axis_angle", q)
    assert close(back, geometry_reference.geometry("quat_to_axis_angle", q), 1e-11)
    n = math.sqrt(sum(v * v for v in a))
    assert close(back, [v / n for v in a] + [theta], 1e-11)


@SETTINGS
@given(quaternion)
def test_quat_to_axis_angle(q):
    got = py("quat_to_axis_angle", q)
    assert 0.0 <= got[3] <= math.pi
    assume(1e-6 < got[3] < math.pi - 1e-6)  # at pi, the axis and its opposite are the same rotation
    assert close(got, geometry_reference.geometry("quat_to_axis_angle", q), 1e-10)


@SETTINGS
@given(quaternion, st.tuples(*[st.floats(-10, 10)] * 3))
@example((0.0, 1.0, -1.0, 0.0), (0.0, 0.0, 0.0))  # 180 degrees: w = 0, the sign from y
def test_matrix_and_transform_to_quat(q, t):
    m = matrix_of(q)
    got = py("matrix_to_quat", m)
    assert close(got, geometry_reference.geometry("matrix_to_quat", m))
    transform = m[0:3] + [t[0]] + m[3:6] + [t[1]] + m[6:9] + [t[2], 0.0, 0.0, 0.0, 1.0]
    pose = py("transform_to_pose", transform)
    assert close(pose, geometry_reference.geometry("transform_to_pose", transform))
    assert pose[:3] == list(t)


@SETTINGS
@given(quaternion)
def test_quat_normalize(q):
    got = py("quat_normalize", q)
    assert close(got, geometry_reference.geometry("quat_normalize", q))
    assert all(math.copysign(1, a) == math.copysign(1, b) for a, b in zip(got, q) if b != 0)


# --------------------------------------------------------------------------
# rotations of 180 degrees: w = 0, the sign of the quaternion from x, y, z

#: the axes of the rotations of 180 degrees tried: each axis, both ways, and oblique ones
HALF_TURN_AXES = [(1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1), (1, 1, 0), (1, -1, 0),
                  (-1, 1, 0), (0, -1, 1), (-1, 0, -1), (1, 2, 3), (-3, 1, -2), (0, 0.6, -0.8)]


def half_turn(a) -> list[float]:
    """The canonical quaternion of the rotation of 180 degrees about ``a``
    (docs/config.md): the unit axis, its first non-zero element positive, w 0."""
    n = math.sqrt(sum(v * v for v in a))
    unit_axis = [v / n for v in a]
    sign = 1.0 if next(v for v in unit_axis if v != 0) > 0 else -1.0
    return [sign * v for v in unit_axis] + [0.0]


def half_turn_cases(a) -> list[tuple]:
    """(converter, values, axes, degrees) of every converter that gives a
    quaternion, each making the rotation of 180 degrees about ``a``: the
    axis-angle both ways round, the exact matrix 2 a a^T - I and scipy's
    (whose w rounds to some 1e-16), the transforms of both, and the Euler
    angles of every axis order, in radians and in degrees."""
    n = math.sqrt(sum(v * v for v in a))
    u = np.array(a, dtype=float) / n
    rotation = Rotation.from_rotvec(u * math.pi)
    cases = [("axis_angle_to_quat", [*a, math.pi], None, False),
             ("axis_angle_to_quat", [*a, -math.pi], None, False),
             ("axis_angle_to_quat", [2 * v for v in a] + [3 * math.pi], None, False)]
    for m in (2 * np.outer(u, u) - np.eye(3), rotation.as_matrix()):
        flat = [float(v) for v in m.ravel()]
        cases.append(("matrix_to_quat", flat, None, False))
        cases.append(("transform_to_pose", flat[0:3] + [0.5] + flat[3:6] + [-1.0] + flat[6:9] + [2.0, 0, 0, 0, 1],
                      None, False))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy's gimbal-lock warning: the angles still make the rotation
        for axes in ir.EULER_AXES:
            for degrees in (False, True):
                angles = [float(v) for v in rotation.as_euler(axes, degrees=degrees)]
                cases.append(("euler_to_quat", angles, axes, degrees))
    return cases


@pytest.mark.parametrize("a", HALF_TURN_AXES, ids=str)
def test_half_turns_give_the_canonical_quaternion(a):
    """A rotation of 180 degrees through every converter that gives a
    quaternion: w exactly 0 and the first non-zero of x, y, z positive,
    whatever sign the arithmetic left on w; as the reference says."""
    want = half_turn(a)
    for name, values, axes, degrees in half_turn_cases(a):
        got = py(name, values, axes, degrees) if axes else py(name, values)
        q = got[3:] if name == "transform_to_pose" else got
        assert close(q, want), (name, values, axes, degrees, got)
        assert q[3] == 0.0 and math.copysign(1.0, q[3]) == 1.0, (name, values, got)
        assert close(got, geometry_reference.geometry(name, values, axes, degrees)), (name, values, got)


@pytest.mark.parametrize("axes", ir.EULER_AXES)
def test_half_turns_about_each_euler_axis(axes):
    """One Euler angle of +-pi (+-180 degrees), the others 0: the quaternion
    of the axis it turns about, positive."""
    for k, axis in enumerate(geometry.AXES[axes]):
        for degrees, turn in ((False, math.pi), (True, 180.0)):
            for sign in (1, -1):
                angles = [0.0, 0.0, 0.0]
                angles[k] = sign * turn
                want = [0.0, 0.0, 0.0, 0.0]
                want[axis] = 1.0
                got = py("euler_to_quat", angles, axes, degrees)
                assert close(got, want) and got[3] == 0.0, (angles, degrees, got)
                assert close(got, geometry_reference.geometry("euler_to_quat", angles, axes, degrees))


@pytest.mark.parametrize("a", HALF_TURN_AXES, ids=str)
def test_quat_to_axis_angle_at_a_half_turn(a):
    """A quaternion of w 0 (or within 1e-12 of it, of either sign) and its
    opposite give one axis, the canonical quaternion's, and the angle pi."""
    want = half_turn(a)
    for sign in (1.0, -1.0):
        for w in (0.0, -0.0, 1e-17, -1e-17, 5e-13, -5e-13):
            q = [sign * v for v in a] + [w]
            got = py("quat_to_axis_angle", q)
            assert close(got[:3], want[:3]) and got[3] == math.pi, (q, got)
            assert close(got, geometry_reference.geometry("quat_to_axis_angle", q)), (q, got)


def test_zero_w_is_within_1e_12():
    """|w| <= 1e-12 is w = 0 (the rounding of a half turn's); beyond it, the
    sign of w decides, as the reference's does."""
    for w in (5e-13, -5e-13, 1e-12, -1e-12):
        got = py("quat_to_axis_angle", [-0.6, 0.8, 0.0, w])
        assert got == [0.6, -0.8, -0.0, math.pi], (w, got)
    for w in (5e-13, -5e-13):  # w = cos(pi / 2 - w), to 1e-16
        assert py("axis_angle_to_quat", [-0.6, 0.8, 0.0, math.pi - 2 * w]) == [0.6, -0.8, -0.0, 0.0], w
    for w, axis in ((2e-12, [-0.6, 0.8, 0.0]), (-2e-12, [0.6, -0.8, -0.0])):
        got = py("quat_to_axis_angle", [-0.6, 0.8, 0.0, w])
        assert close(got[:3], axis) and got[3] < math.pi, (w, got)
        assert close(got, geometry_reference.geometry("quat_to_axis_angle", [-0.6, 0.8, 0.0, w])), (w, got)
        q = py("axis_angle_to_quat", [-0.6, 0.8, 0.0, math.pi - 2 * w])
        assert close(q, geometry_reference.geometry("axis_angle_to_quat", [-0.6, 0.8, 0.0, math.pi - 2 * w]))
        assert math.copysign(1.0, q[3]) == 1.0 and q[3] > 1e-12, (w, q)


def test_degenerate_inputs():
    """No rotation and results that cannot be: stated values, or all NaN."""
    assert py("axis_angle_to_quat", [0, 0, 0, 1.0]) == [0.0, 0.0, 0.0, 1.0]
    assert py("quat_to_axis_angle", [0, 0, 0, 2.0]) == [0.0, 0.0, 1.0, 0.0]
    for name, width in ir.GEOMETRY_WIDTHS.items():
        if name not in ("transform_to_pose",):
            args = ("xyz", False) if "euler" in name else ()
            assert all(math.isnan(v) for v in geometry.GEOMETRY[name]([float("nan")] * width[0], *args)), name
    assert all(math.isnan(v) for v in py("quat_normalize", [0, 0, 0, 0]))
    assert all(math.isnan(v) for v in py("quat_to_euler", [0, 0, 0, 0], "xyz"))


def test_checker_widths_are_the_runtime_ones():
    assert ir.GEOMETRY_WIDTHS == geometry.GEOMETRY_WIDTHS
    assert set(ir.EULER_AXES) == set(geometry.AXES)


# --------------------------------------------------------------------------
# C++ against Python, bit for bit

#: expressions the C++ helper is built with (every operator and function)
EXPRESSIONS = [
    "clamp(x, -1, 1) * 0.5", "x * pi / 180", "-x + 1e-3 - (2 - x)", "abs(x) / (x - 1)",
    "min(x, 0.25) + max(x, -0.25)", "sqrt(x) * sqrt(2)", "sin(x) * cos(x / 3)", "atan2(x, 1 - x)",
    "-(x * x) / 7 + --x", "atan2(sin(x), cos(x)) - x", "x / 0", "1 / x", "sqrt(x - 1e300 * 1e10)",
]


def checked(text: str) -> ir.ExprNode:
    sink = Sink()
    doc = parse_text(f"[mux m]\nconvert = expr({text})\n", sink)
    node = _node(type("Ctx", (), {"sink": sink})(), doc.sections[0].entries[0].items[0].body)
    assert node is not None and not sink.items, sink.items
    return node


@pytest.fixture(scope="module")
def cpp(tmp_path_factory):
    """The helper, running: a request in, a line of results out."""
    install = yarp_install("3.5")
    if install.missing():
        pytest.fail(f"YARP 3.5 is not installed: {install.missing()}")
    src = tmp_path_factory.mktemp("geometry_check")
    lambdas = ",\n".join(f"    []([[maybe_unused]] double x) {{ return {cpp_expression(checked(t))}; }}"
                         for t in EXPRESSIONS)
    (src / "expressions.inc").write_text(f"double (*const kExpressions[])(double) = {{\n{lambdas}\n}};\n")
    (src / "CMakeLists.txt").write_text(f"""cmake_minimum_required(VERSION 3.16)
project(geometry_check CXX)
find_package(YARP REQUIRED COMPONENTS os)
find_package(Threads REQUIRED)
add_executable(geometry_check {HELPER} {' '.join(str(RUNTIME / s) for s in CPP_SOURCES)})
# the runtime's sources as one translation unit, as a module's CMakeLists compiles them
set_target_properties(geometry_check PROPERTIES UNITY_BUILD ON UNITY_BUILD_BATCH_SIZE 0)
set_source_files_properties({HELPER} PROPERTIES SKIP_UNITY_BUILD_INCLUSION ON)
target_include_directories(geometry_check PRIVATE {RUNTIME} {src})
target_compile_features(geometry_check PRIVATE cxx_std_17)
set_target_properties(geometry_check PROPERTIES CXX_EXTENSIONS OFF)
target_compile_options(geometry_check PRIVATE -O2 -Wall -Wextra -Werror -ffp-contract=off)
target_link_libraries(geometry_check PRIVATE YARP::YARP_os YARP::YARP_init Threads::Threads)
""")
    built = cmake_build(src, src / "build", install)
    assert built.returncode == 0, built.stdout[-3000:] + built.stderr[-3000:]
    proc = subprocess.Popen([str(src / "build" / "geometry_check")], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                            text=True, bufsize=1)

    def ask(request: str) -> list[float]:
        proc.stdin.write(request + "\n")
        proc.stdin.flush()
        return [float.fromhex(w) for w in proc.stdout.readline().split()]

    yield ask
    proc.stdin.close()
    proc.wait(timeout=10)


def cpp_geometry(cpp, name, values, axes=None, degrees=False) -> list[float]:
    return cpp(f"g {name} {axes or 'xyz'} {int(degrees)} " + " ".join(float(v).hex() for v in values))


@SETTINGS
@given(st.sampled_from(ir.EULER_AXES), st.booleans(),
       st.one_of(st.tuples(angle, angle, angle), st.tuples(anything, anything, anything)),
       st.one_of(quaternion, st.tuples(anything, anything, anything, anything)))
def test_cpp_euler_bit_for_bit(cpp, axes, degrees, angles, q):
    assert same_bits(cpp_geometry(cpp, "euler_to_quat", angles, axes, degrees),
                     py("euler_to_quat", angles, axes, degrees))
    assert same_bits(cpp_geometry(cpp, "quat_to_euler", q, axes, degrees), py("quat_to_euler", q, axes, degrees))


@SETTINGS
@given(st.one_of(st.tuples(unit, unit, unit, st.floats(-10, 10)), st.tuples(anything, anything, anything, anything)),
       st.one_of(quaternion, st.tuples(anything, anything, anything, anything)))
def test_cpp_axis_angle_and_normalize_bit_for_bit(cpp, aa, q):
    assert same_bits(cpp_geometry(cpp, "axis_angle_to_quat", aa), py("axis_angle_to_quat", aa))
    assert same_bits(cpp_geometry(cpp, "quat_to_axis_angle", q), py("quat_to_axis_angle", q))
    assert same_bits(cpp_geometry(cpp, "quat_normalize", q), py("quat_normalize", q))


@SETTINGS
@given(quaternion, st.lists(st.floats(-2, 2), min_size=9, max_size=9), st.tuples(*[st.floats(-10, 10)] * 3),
       st.lists(anything, min_size=16, max_size=16))
def test_cpp_matrix_and_transform_bit_for_bit(cpp, q, noisy, t, wild):
    for m in (matrix_of(q), noisy):
        assert same_bits(cpp_geometry(cpp, "matrix_to_quat", m), py("matrix_to_quat", m))
        transform = m[0:3] + [t[0]] + m[3:6] + [t[1]] + m[6:9] + [t[2], 0.0, 0.0, 0.0, 1.0]
        assert same_bits(cpp_geometry(cpp, "transform_to_pose", transform), py("transform_to_pose", transform))
    assert same_bits(cpp_geometry(cpp, "transform_to_pose", wild), py("transform_to_pose", wild))


@pytest.mark.parametrize("a", HALF_TURN_AXES, ids=str)
def test_cpp_half_turns_bit_for_bit(cpp, a):
    """The rotations of 180 degrees of the Python tests above, and the
    quaternions of w within 1e-12 of 0: C++ gives Python's bits."""
    for name, values, axes, degrees in half_turn_cases(a):
        assert same_bits(cpp_geometry(cpp, name, values, axes, degrees),
                         py(name, values, axes, degrees) if axes else py(name, values)), (name, values)
    for sign in (1.0, -1.0):
        for w in (0.0, -0.0, 1e-17, -1e-17, 5e-13, -5e-13, 1e-12, -1e-12, 2e-12, -2e-12):
            q = [sign * v for v in a] + [w]
            assert same_bits(cpp_geometry(cpp, "quat_to_axis_angle", q), py("quat_to_axis_angle", q)), q
            aa = [sign * v for v in a] + [math.pi - 2 * w]
            assert same_bits(cpp_geometry(cpp, "axis_angle_to_quat", aa), py("axis_angle_to_quat", aa)), aa


@SETTINGS
@given(st.one_of(st.floats(-10, 10), anything))
def test_expressions_cpp_python_and_numpy(cpp, x):
    """Each expression as the C++ and the Python backends compile it: the same
    bits; and numpy's float64 evaluation of the checked tree to 1e-12."""
    names = {n: getattr(geometry, n) for n in ("div", "sqrt", "sin", "cos", "atan2", "fabs", "min_of", "max_of",
                                               "clamp")}
    for k, text in enumerate(EXPRESSIONS):
        node = checked(text)
        used: set[str] = set()
        f = eval(f"lambda x: {py_expression(node, used)}", names)  # the generated module's lambda
        got = float(f(float(x)))
        assert same_bits(cpp(f"e {k} {float(x).hex()}"), [got]), (text, x)
        want = geometry_reference.evaluate(node, x)
        assert (math.isnan(got) and math.isnan(want)) or got == want or abs(got - want) <= TOL * max(1, abs(want)), \
            (text, x, got, want)


# --------------------------------------------------------------------------
# the syntax

_leaf = st.one_of(st.just("x"), st.just("pi"), st.floats(0, 1e6).map(repr))


def _expressions(children):
    return st.one_of(
        st.tuples(children, st.sampled_from("+-*/"), children).map(lambda t: f"({t[0]}) {t[1]} ({t[2]})"),
        children.map(lambda c: f"-({c})"),
        st.tuples(st.sampled_from(sorted(ir.EXPR_FUNCTIONS)), st.lists(children, min_size=1, max_size=3)).map(
            lambda t: f"{t[0]}({', '.join(t[1])})"))


@settings(max_examples=examples(200), deadline=None)
@given(st.recursive(_leaf, _expressions, max_leaves=12))
def test_fmt_keeps_the_tree_with_fewest_parentheses(text):
    """fmt writes an expression with only the parentheses its tree needs;
    read back, it is the same tree, and fmt of that is the same text."""
    sink = Sink()
    doc = parse_text(f"[mux m]\nconvert = expr({text})\n", sink)
    assert not sink.items, (text, sink.items)
    out = format_document(doc)
    again = parse_text(out, Sink())
    assert again == doc and format_document(again) == out


def test_numpy_reference_is_not_the_runtime():
    """The reference shares no code with the runtime it checks."""
    src = Path(geometry_reference.__file__).read_text()
    assert "ybg.runtime" not in src and "ybgc_runtime" not in src
    assert np.float64(1.0) / np.float64(3.0) == 1.0 / 3.0


LEGACY = """[general]
num_mux = 1
output_name = /icub/right_hand/pose
to_ros = false
rate = 50

[mux1]
num_ports = 1
ports = /icub/cartesianController/right_arm/state:o
function = expr(clamp(x, -0.6, 0.6) * 2 - -1)[0:3], scale(2)
verbose = false

[message]
num_fields = 2
1_type = single_value
1_msg = "hand"
2_type = mux
2_mux = mux1
"""


def test_fmt_to_named_keeps_an_expression(tmp_path):
    """A legacy `function` with an expression: `ybgc fmt --to named` writes
    a named config that checks clean and is the same program."""
    from harness.generated import ybgc
    from ybg.compiler.pipeline import compile_path

    old = tmp_path / "pose.ini"
    old.write_text(LEGACY)
    new = tmp_path / "pose_named.ini"
    r = ybgc("fmt", "--to", "named", old, "-o", new)
    assert r.returncode == 0, r.stderr
    assert "convert = expr(clamp(x, -0.6, 0.6) * 2 - -1)[0:3], scale(2)" in new.read_text()
    before, after = compile_path(old), compile_path(new)
    assert not after.diagnostics and after.program is not None
    assert after.program.muxes == before.program.muxes
    (conv, _), = [m.converters for m in after.program.muxes]
    assert isinstance(conv, ir.ExprConverter) and (conv.start, conv.stop) == (0, 3)


def test_runtime_geometry_names_do_not_clash():
    """--single-file inlines geometry.py before core.py and the I/O modules
    in one namespace: none of them redefines its names (core takes the two
    it imports from it)."""
    import ast as pyast

    def names(module: str) -> set[str]:
        tree = pyast.parse((RUNTIME.parent / f"{module}.py").read_text())
        out = set()
        for node in tree.body:
            if isinstance(node, (pyast.FunctionDef, pyast.ClassDef)):
                out.add(node.name)
            elif isinstance(node, pyast.Assign):
                out.update(t.id for t in node.targets if isinstance(t, pyast.Name))
        return out

    ours = names("geometry")
    assert {"GEOMETRY", "clamp", "div"} <= ours
    for other in ("core", "yarp_io", "ros2_io"):
        assert not ours & names(other), (other, ours & names(other))
