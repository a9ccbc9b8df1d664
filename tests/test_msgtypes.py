"""The ROS message type model: vendored definitions, parsing, search paths."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from ybg.compiler.ir import TypeRef
from ybg.compiler.msgtypes import (
    DEFAULT_DISTRO, DISTROS, PRIMITIVES, VENDORED_DIR, MsgConstant, MsgField, MsgProblem,
    field_positions, load_store, normalize_name, numeric_leaves, parse_msg,
)

ROOT = Path(__file__).resolve().parent.parent
NO_ENV: dict[str, str] = {}


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
    return path


# --------------------------------------------------------------------------
# Vendored definitions against rosbags

def _vendor_script():
    spec = importlib.util.spec_from_file_location("vendor_msgs", ROOT / "scripts" / "vendor_msgs.py")
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def _expected_type(desc, ros: str, nodetype) -> tuple[TypeRef, int | None]:
    """rosbags field description -> (TypeRef, string bound)."""
    kind, rest = desc
    if kind == nodetype.BASE:
        base, bound = rest
        return TypeRef(base), bound or None
    if kind == nodetype.NAME:
        pkg, _, name = rest.split("/")
        base = f"{pkg}/{name}"
        if ros == "ros1" and base == "builtin_interfaces/Time":
            base = "time"
        elif ros == "ros1" and base == "builtin_interfaces/Duration":
            base = "duration"
        return TypeRef(base), None
    elem, size = rest
    inner, bound = _expected_type(elem, ros, nodetype)
    assert inner.array is None
    if kind == nodetype.ARRAY:
        return TypeRef(inner.base, "fixed", size), bound
    return TypeRef(inner.base, "sequence", size or None), bound


@pytest.mark.parametrize("distro", sorted(DISTROS))
def test_vendored_equals_rosbags(distro):
    pytest.importorskip("rosbags")
    from rosbags.interfaces import Nodetype
    from rosbags.typesys import get_typestore

    vendor = _vendor_script()
    ros, store_id = vendor.DISTRO_STORES[distro]
    assert DISTROS[distro] == ros
    fielddefs = get_typestore(store_id).fielddefs
    expected_names = {
        f"{n.split('/')[0]}/{n.split('/')[2]}" for n in fielddefs
        if n.split("/")[0] in vendor.PACKAGES
        and not (ros == "ros1" and n.startswith("builtin_interfaces/"))
    }
    extra = set(vendor.ROS1_EXTRA) if ros == "ros1" else set()
    store = load_store(ros, distro, environ=NO_ENV)
    # and the messages of the packages copied from upstream with their actions (tests/test_actiontypes.py)
    copied = {n for n in store.all_names() if n.split("/")[0] in vendor.COPIED}
    assert set(store.all_names()) - copied == expected_names | extra
    for name in sorted(expected_names):
        pkg, typ = name.split("/")
        constants, fields = fielddefs[f"{pkg}/msg/{typ}"]
        if [f[0] for f in fields] == [vendor.PLACEHOLDER]:
            fields = []
        msgdef = store.resolve(name)
        assert msgdef is not None, name
        assert msgdef.name == name
        assert Path(msgdef.path) == Path(VENDORED_DIR, distro, pkg, f"{typ}.msg")
        got = [(f.name, f.type, f.string_bound) for f in msgdef.fields]
        want = [(fname, *_expected_type(desc, ros, Nodetype)) for fname, desc in fields]
        assert got == want, name
        assert [(c.name, c.type, c.value) for c in msgdef.constants] == \
            [tuple(c) for c in constants], name
        assert all(f.default is None for f in msgdef.fields)
        # every nested type resolves
        for f in msgdef.fields:
            if f.type.is_message:
                assert store.resolve(f.type.base) is not None, (name, f.type.base)
    assert store.problems == []


def test_ros1_extra_as_debian_defines_them():
    """tf2_msgs/TFMessage and tf/tfMessage, which rosbags lacks, read as
    Debian's ros-tf2-msgs defines the first (scripts/setup.sh installs it)."""
    debian = Path("/usr/share/tf2_msgs/msg/TFMessage.msg")
    if not debian.exists():
        pytest.skip("Debian's ros-tf2-msgs is not installed")
    store = load_store("ros1", "noetic", environ=NO_ENV)
    want = [line.split() for line in debian.read_text().splitlines() if line.strip()]
    for name in ("tf2_msgs/TFMessage", "tf/tfMessage"):
        msgdef = store.resolve(name)
        assert [[str(f.type), f.name] for f in msgdef.fields] == want, name
    assert store.problems == []


def test_vendored_files_up_to_date():
    pytest.importorskip("rosbags")
    assert _vendor_script().main(["--check"]) == 0


def test_ros1_and_ros2_spelling_in_files():
    ros1 = Path(VENDORED_DIR, "noetic", "std_msgs", "Header.msg").read_text()
    ros2 = Path(VENDORED_DIR, "jazzy", "std_msgs", "Header.msg").read_text()
    assert ros1 == "uint32 seq\ntime stamp\nstring frame_id\n"
    assert ros2 == "builtin_interfaces/Time stamp\nstring frame_id\n"
    assert Path(VENDORED_DIR, "noetic", "sensor_msgs", "Imu.msg").read_text().startswith("Header header\n")
    cam = Path(VENDORED_DIR, "jazzy", "sensor_msgs", "CameraInfo.msg").read_text()
    assert "float64[9] k\n" in cam and "float64[] d\n" in cam
    assert "float64[<=3] dimensions" in Path(VENDORED_DIR, "jazzy", "shape_msgs", "SolidPrimitive.msg").read_text()
    assert not Path(VENDORED_DIR, "noetic", "builtin_interfaces").exists()


# --------------------------------------------------------------------------
# The store on the vendored definitions


def test_defaults_and_primitives():
    assert DEFAULT_DISTRO == {"ros1": "noetic", "ros2": "jazzy"}
    assert {"noetic", "humble", "jazzy"} <= DISTROS.keys()
    assert {"time", "duration"} <= PRIMITIVES["ros1"]
    assert "time" not in PRIMITIVES["ros2"] and "wstring" in PRIMITIVES["ros2"]
    assert load_store("ros1", environ=NO_ENV).distro == "noetic"
    assert load_store("ros2", environ=NO_ENV).distro == "jazzy"


@pytest.mark.parametrize("ros,distro", [("ros1", "jazzy"), ("ros2", "noetic"), ("ros2", "foo"),
                                        ("ros3", None)])
def test_bad_dialect_or_distro(ros, distro):
    with pytest.raises(ValueError):
        load_store(ros, distro, environ=NO_ENV)


def test_header_differs():
    h1 = load_store("ros1", environ=NO_ENV).resolve("std_msgs/Header")
    h2 = load_store("ros2", environ=NO_ENV).resolve("std_msgs/msg/Header")
    assert [(f.name, f.type) for f in h1.fields] == [
        ("seq", TypeRef("uint32")), ("stamp", TypeRef("time")), ("frame_id", TypeRef("string"))]
    assert [(f.name, f.type) for f in h2.fields] == [
        ("stamp", TypeRef("builtin_interfaces/Time")), ("frame_id", TypeRef("string"))]
    t = load_store("ros2", environ=NO_ENV).resolve("builtin_interfaces/Time")
    assert [(f.name, f.type.base) for f in t.fields] == [("sec", "int32"), ("nanosec", "uint32")]
    assert load_store("ros1", environ=NO_ENV).resolve("builtin_interfaces/Time") is None


def test_resolve_names():
    store = load_store("ros2", "humble", environ=NO_ENV)
    a = store.resolve("geometry_msgs/Point")
    assert a is store.resolve("geometry_msgs/msg/Point")  # cached
    assert store.resolve("Point") is None
    assert store.resolve("geometry_msgs/srv/Point") is None
    assert store.resolve("nope_msgs/Point") is None
    assert store.resolve("") is None
    assert normalize_name(" std_msgs/msg/Header ") == "std_msgs/Header"
    assert normalize_name("a/b/c") is None
    js = store.resolve("sensor_msgs/JointState")
    assert [f.name for f in js.fields] == ["header", "name", "position", "velocity", "effort"]
    assert js.field("position").type == TypeRef("float64", "sequence")
    assert js.field("name").type == TypeRef("string", "sequence")
    assert js.field("header").type == TypeRef("std_msgs/Header")
    status = store.resolve("diagnostic_msgs/DiagnosticStatus")
    assert status.constant("WARN") == MsgConstant("WARN", "byte", 1)
    assert status.field("values").type == TypeRef("diagnostic_msgs/KeyValue", "sequence")


def test_candidates():
    for ros in ("ros1", "ros2"):
        store = load_store(ros, environ=NO_ENV)
        assert store.candidates("JointState") == ["sensor_msgs/JointState"]
        assert store.candidates("Header") == ["std_msgs/Header"]
        assert store.candidates("NoSuchThing") == []
        assert "geometry_msgs/PoseStamped" in store.all_names()
        assert store.all_names() == sorted(store.all_names())


def test_numeric_leaves():
    store = load_store("ros2", environ=NO_ENV)
    xyz = [("x", "float64"), ("y", "float64"), ("z", "float64")]
    assert numeric_leaves(store, store.resolve("geometry_msgs/Point")) == xyz
    assert numeric_leaves(store, "geometry_msgs/Quaternion") == xyz + [("w", "float64")]
    assert numeric_leaves(store, "geometry_msgs/Pose") == \
        [(f"position.{n}", t) for n, t in xyz] + \
        [(f"orientation.{n}", "float64") for n in "xyzw"]
    assert numeric_leaves(store, "geometry_msgs/Point32") == [(n, "float32") for n in "xyz"]
    assert numeric_leaves(store, "builtin_interfaces/Time") == [("sec", "int32"), ("nanosec", "uint32")]
    assert numeric_leaves(store, "std_msgs/ColorRGBA") == [(n, "float32") for n in "rgba"]
    assert numeric_leaves(store, "std_msgs/Empty") == []
    for name in ("std_msgs/Header", "sensor_msgs/JointState", "std_msgs/Float64MultiArray",
                 "geometry_msgs/PoseStamped", "std_msgs/Bool", "no_msgs/Nothing"):
        assert numeric_leaves(store, name) is None, name
    cov = numeric_leaves(store, "geometry_msgs/PoseWithCovariance")
    assert len(cov) == 7 + 36 and cov[7] == ("covariance[0]", "float64")
    assert cov[-1] == ("covariance[35]", "float64")
    ros1 = load_store("ros1", environ=NO_ENV)
    assert numeric_leaves(ros1, "std_msgs/Time") is None  # time is a primitive


def test_field_positions():
    """Index paths in the definition: a nested message's index, then its field's; an
    array element's index after the array's."""
    ros1 = load_store("ros1", environ=NO_ENV)
    assert field_positions(ros1, "geometry_msgs/PointStamped", ("point.x", "point.z", "header")) == \
        ((1, 0), (1, 2), (0,))
    assert field_positions(ros1, "geometry_msgs/PoseWithCovariance",
                           ("pose.orientation.w", "covariance[35]")) == ((0, 1, 3), (1, 35))
    assert field_positions(ros1, "sensor_msgs/JointState", ("position",)) == ((2,),)


# --------------------------------------------------------------------------
# User definitions


def test_user_dir_adds_and_overrides(tmp_path):
    write(tmp_path / "my_msgs" / "msg" / "MotorsInertial.msg", """
        # motor readings
        Header header
        float64[4] current   # A
        float64[4] velocity
        MotorState state
        """)
    write(tmp_path / "my_msgs" / "msg" / "MotorState.msg", "uint8 IDLE=0\nuint8 mode\nfloat32 temp\n")
    write(tmp_path / "sensor_msgs" / "msg" / "JointState.msg", "Header header\nfloat64[2] position\n")
    write(tmp_path / "flat_msgs" / "Flat.msg", "int16 a\n")
    store = load_store("ros1", msg_path=[str(tmp_path)], environ=NO_ENV)
    assert store.search_paths[0] == str(tmp_path)
    assert store.search_paths[-1] == os.path.join(VENDORED_DIR, "noetic")
    mi = store.resolve("my_msgs/MotorsInertial")
    assert mi.path == str(tmp_path / "my_msgs" / "msg" / "MotorsInertial.msg")
    assert [(f.name, f.type) for f in mi.fields] == [
        ("header", TypeRef("std_msgs/Header")),
        ("current", TypeRef("float64", "fixed", 4)),
        ("velocity", TypeRef("float64", "fixed", 4)),
        ("state", TypeRef("my_msgs/MotorState")),
    ]
    assert mi.fields[1].line == 3
    assert store.candidates("MotorsInertial") == ["my_msgs/MotorsInertial"]
    assert store.resolve("my_msgs/msg/MotorState").constant("IDLE").value == 0
    js = store.resolve("sensor_msgs/JointState")
    assert [f.name for f in js.fields] == ["header", "position"]
    assert js.path.startswith(str(tmp_path))
    assert store.resolve("flat_msgs/Flat").fields == (MsgField("a", TypeRef("int16")),)
    assert store.resolve("geometry_msgs/Point") is not None  # vendored still there
    assert store.problems == []
    state = store.resolve("my_msgs/MotorState")
    assert numeric_leaves(store, state) is not None
    # a package folder itself (with package.xml)
    pkg = tmp_path / "ws" / "solo_msgs"
    write(pkg / "package.xml", "<package/>")
    write(pkg / "msg" / "Solo.msg", "float64[2] v\n")
    solo = load_store("ros2", msg_path=pkg, environ=NO_ENV)
    assert numeric_leaves(solo, "solo_msgs/Solo") == [("v[0]", "float64"), ("v[1]", "float64")]


def test_msg_path_before_env(tmp_path):
    write(tmp_path / "a" / "p_msgs" / "msg" / "M.msg", "int32 first\n")
    write(tmp_path / "b" / "p_msgs" / "msg" / "M.msg", "int32 second\n")
    env = {"YBG_MSG_PATH": str(tmp_path / "b")}
    store = load_store("ros2", msg_path=[tmp_path / "a"], environ=env)
    assert store.resolve("p_msgs/M").fields[0].name == "first"
    assert load_store("ros2", environ=env).resolve("p_msgs/M").fields[0].name == "second"


def test_env_ybg_msg_path(tmp_path):
    write(tmp_path / "one" / "x_msgs" / "msg" / "X.msg", "float64 x\n")
    write(tmp_path / "two" / "y_msgs" / "msg" / "Y.msg", "float64 y\n")
    env = {"YBG_MSG_PATH": os.pathsep.join([str(tmp_path / "one"), "", str(tmp_path / "two")])}
    for ros in ("ros1", "ros2"):
        store = load_store(ros, environ=env)
        assert store.resolve("x_msgs/X") is not None
        assert store.resolve("y_msgs/Y") is not None
        assert store.search_paths[:2] == [str(tmp_path / "one"), str(tmp_path / "two")]


def test_env_ros_package_path(tmp_path):
    src = tmp_path / "catkin_ws" / "src"
    write(src / "group" / "robot_msgs" / "package.xml", "<package/>")
    write(src / "group" / "robot_msgs" / "msg" / "Wheels.msg", "float64 left\nfloat64 right\n")
    # a package inside a package is not one, nor below CATKIN_IGNORE
    write(src / "group" / "robot_msgs" / "inner" / "package.xml", "<package/>")
    write(src / "group" / "robot_msgs" / "inner" / "msg" / "Inner.msg", "int8 a\n")
    write(src / "ignored" / "CATKIN_IGNORE", "")
    write(src / "ignored" / "hidden_msgs" / "package.xml", "<package/>")
    write(src / "ignored" / "hidden_msgs" / "msg" / "H.msg", "int8 a\n")
    env = {"ROS_PACKAGE_PATH": str(src), "AMENT_PREFIX_PATH": str(src)}
    store = load_store("ros1", environ=env)
    assert numeric_leaves(store, "robot_msgs/Wheels") == [("left", "float64"), ("right", "float64")]
    assert store.candidates("Inner") == [] and store.candidates("H") == []
    # ROS_PACKAGE_PATH is for ROS 1 only
    assert load_store("ros2", environ=env).resolve("robot_msgs/Wheels") is None


def test_env_ament_prefix_path(tmp_path):
    prefix = tmp_path / "install"
    write(prefix / "share" / "robot_msgs" / "msg" / "Wheels.msg", "float64 left 1.5\nfloat64 right\n")
    write(prefix / "share" / "std_msgs" / "msg" / "Header.msg",
          "builtin_interfaces/Time stamp\nstring frame_id\nuint8 extra\n")
    env = {"AMENT_PREFIX_PATH": os.pathsep.join([str(prefix), str(tmp_path / "missing")]),
           "ROS_PACKAGE_PATH": str(prefix)}
    store = load_store("ros2", "humble", environ=env)
    wheels = store.resolve("robot_msgs/Wheels")
    assert wheels.fields[0].default == 1.5 and wheels.fields[1].default is None
    assert [f.name for f in store.resolve("std_msgs/Header").fields] == ["stamp", "frame_id", "extra"]
    assert load_store("ros1", environ=env).resolve("robot_msgs/Wheels") is None


def test_malformed_user_msg(tmp_path):
    path = write(tmp_path / "bad_msgs" / "msg" / "Broken.msg", """
        # a comment
        float64 ok

        float64[3 position
        """)
    store = load_store("ros2", msg_path=[tmp_path], environ=NO_ENV)
    assert store.problems == []  # lazy: nothing parsed yet
    assert store.candidates("Broken") == ["bad_msgs/Broken"]
    assert store.resolve("bad_msgs/Broken") is None
    assert store.problems == [MsgProblem(str(path), 4, 1, "invalid type 'float64[3'")]
    assert store.resolve("bad_msgs/Broken") is None
    assert len(store.problems) == 1  # reported once
    assert str(store.problems[0]) == f"{path}:4:1: invalid type 'float64[3'"


def test_unknown_nested_type_is_a_problem(tmp_path):
    path = write(tmp_path / "m_msgs" / "msg" / "Outer.msg", "float64 a\n  Inner inner\n")
    store = load_store("ros2", msg_path=[tmp_path], environ=NO_ENV)
    outer = store.resolve("m_msgs/Outer")
    assert outer is not None and outer.field("inner").type == TypeRef("m_msgs/Inner")
    assert store.problems == [MsgProblem(str(path), 2, 3, "unknown message type 'm_msgs/Inner' (field 'inner')")]
    assert numeric_leaves(store, outer) is None


def test_recursive_user_types_do_not_loop(tmp_path):
    write(tmp_path / "r_msgs" / "msg" / "A.msg", "B b\n")
    write(tmp_path / "r_msgs" / "msg" / "B.msg", "A a\n")
    store = load_store("ros1", msg_path=[tmp_path], environ=NO_ENV)
    assert numeric_leaves(store, "r_msgs/A") is None


def test_unreadable_file(tmp_path):
    path = tmp_path / "u_msgs" / "msg" / "U.msg"
    path.parent.mkdir(parents=True)
    path.write_bytes(b"float64 \xff\n")
    store = load_store("ros2", msg_path=[tmp_path], environ=NO_ENV)
    assert store.resolve("u_msgs/U") is None
    assert store.problems[0].path == str(path) and store.problems[0].line == 0


# --------------------------------------------------------------------------
# The parser

PROBLEMS = [
    # (dialect, line text, column, message start)
    ("ros2", "float64[3 position", 1, "invalid type"),
    ("ros2", "float64", 8, "expected a field name"),
    ("ros2", "float64   # no name", 11, "expected a field name"),
    ("ros2", "int32 9x", 7, "invalid field name"),
    ("ros2", "int32 Big", 7, "invalid field name 'Big'"),
    ("ros2", "int32 a__b", 7, "invalid field name"),
    ("ros2", "int32 x[3]", 8, "unexpected '['"),
    ("ros2", "uint8 z 300", 9, "uint8 value 300 out of range"),
    ("ros2", "float32 y 1.0.0", 11, "invalid float32 value"),
    ("ros2", "bool b maybe", 8, "invalid bool value"),
    ("ros2", "int32 FooBar=1", 7, "invalid constant name"),
    ("ros2", "int32 FOO=abc", 11, "invalid int32 value"),
    ("ros2", "int32[] FOO=1", 1, "a constant must have a primitive type"),
    ("ros2", "time t", 1, "unknown primitive type 'time' (ROS 2 uses builtin_interfaces/Time)"),
    ("ros2", "float64[] v [1, , 2]", 16, "empty list item"),
    ("ros2", "float64[2] v [1, 2, 3]", 14, "default has 3 items"),
    ("ros2", "int8[<=1] v [1, 2]", 13, "default has 2 items, more than the bound 1"),
    ("ros2", "string<=2 s \"abc\"", 13, "string longer than its bound 2"),
    ("ros2", "string s \"abc", 10, "unterminated string"),
    ("ros2", "float64<=3 x", 8, "only strings can have a bound"),
    ("ros2", "int8[<=x] v", 8, "invalid array bound"),
    ("ros2", "int8[x] v", 6, "invalid array size"),
    ("ros2", "Point p 1", 9, "a field of type"),
    ("ros2", "a/b/C c", 1, "invalid type"),
    ("ros2", "foo x", 1, "unknown primitive type 'foo'"),
    ("ros1", "float64 x 1.0", 11, "unexpected text after the field name"),
    ("ros1", "string<=3 s", 7, "ROS 1 has no bounded strings"),
    ("ros1", "int8[<=3] s", 6, "ROS 1 has no bounded arrays"),
    ("ros1", "wstring w", 1, "unknown primitive type 'wstring'"),
    ("ros1", "time T=1", 1, "a constant must have a primitive type"),
    ("ros1", "---", 1, "'---' separator"),
]


@pytest.mark.parametrize("ros,text,column,message", PROBLEMS)
def test_parse_problem(ros, text, column, message):
    msgdef, problems = parse_msg(f"int32 before\n{text}\nint32 after\n", "p_msgs/M", ros, "M.msg")
    assert len(problems) == 1, problems
    p = problems[0]
    assert (p.path, p.line, p.column) == ("M.msg", 2, column), p
    assert p.message.startswith(message), p.message
    assert msgdef.fields[0].name == "before"
    if text != "---":
        assert msgdef.fields[-1].name == "after"


def test_parse_duplicate_name():
    _, problems = parse_msg("int32 a\nfloat64   a\nint32 B=1\nint32 B=2\n", "p/M", "ros1")
    assert [(p.line, p.column, p.message) for p in problems] == [
        (2, 11, "'a' already defined on line 1"), (4, 7, "'B' already defined on line 3")]
    assert problems[0].path == "<p/M>"


def test_parse_ros2_syntax():
    text = textwrap.dedent("""
        # comment with = and "quotes"
        int32 FOO=1  # trailing
        int32 NEG = -2
        int64 HEX=0x10
        float64 PI=3.14159
        bool YES=true
        string NAME="x # y"
        string BARE=hello world  # comment
        float64 x 0.0
        float64[3] v [1, 2, 3.5]
        string<=5 s "ab"  # bounded with default
        string<=5[<=2] ss ["a", 'b,c']
        wstring w "wide"
        int32[] e []
        bool b true
        Point p
        geometry_msgs/Pose q
        other_msgs/msg/Thing t
        byte raw
        char c
        uint8[<=4] u
        """)
    msgdef, problems = parse_msg(text, "geometry_msgs/Foo", "ros2")
    assert problems == []
    assert [(c.name, c.type, c.value) for c in msgdef.constants] == [
        ("FOO", "int32", 1), ("NEG", "int32", -2), ("HEX", "int64", 16), ("PI", "float64", 3.14159),
        ("YES", "bool", True), ("NAME", "string", "x # y"), ("BARE", "string", "hello world")]
    f = {x.name: x for x in msgdef.fields}
    assert list(f) == ["x", "v", "s", "ss", "w", "e", "b", "p", "q", "t", "raw", "c", "u"]
    assert f["x"] == MsgField("x", TypeRef("float64"), 0.0)
    assert f["v"].type == TypeRef("float64", "fixed", 3) and f["v"].default == (1.0, 2.0, 3.5)
    assert f["s"] == MsgField("s", TypeRef("string"), "ab", 5)
    assert f["ss"] == MsgField("ss", TypeRef("string", "sequence", 2), ("a", "b,c"), 5)
    assert f["w"].type == TypeRef("wstring") and f["w"].default == "wide"
    assert f["e"].default == () and f["b"].default is True
    assert f["p"].type == TypeRef("geometry_msgs/Point")
    assert f["q"].type == TypeRef("geometry_msgs/Pose")
    assert f["t"].type == TypeRef("other_msgs/Thing")
    assert f["raw"].type == TypeRef("byte") and f["c"].type == TypeRef("char")
    assert f["u"].type == TypeRef("uint8", "sequence", 4)
    assert str(f["u"].type) == "uint8[<=4]"
    assert (f["v"].line, f["v"].column) == (11, 1)


def test_parse_ros1_syntax():
    text = "string S= a # b \"c\"\nbool B=1\nHeader header\ntime t\nduration[] ds\n" \
           "geometry_msgs/Point[2] pts\nfloat64 CamelCase\r\n"
    msgdef, problems = parse_msg(text, "foo/Bar", "ros1")
    assert problems == []
    assert [(c.name, c.value) for c in msgdef.constants] == [("S", 'a # b "c"'), ("B", True)]
    assert [(f.name, f.type) for f in msgdef.fields] == [
        ("header", TypeRef("std_msgs/Header")), ("t", TypeRef("time")),
        ("ds", TypeRef("duration", "sequence")), ("pts", TypeRef("geometry_msgs/Point", "fixed", 2)),
        ("CamelCase", TypeRef("float64"))]
    # in ROS 2, a bare Header is a message of the same package
    msgdef, _ = parse_msg("Header header\n", "foo/Bar", "ros2")
    assert msgdef.fields[0].type == TypeRef("foo/Header")


# --------------------------------------------------------------------------
# Start-up cost


def test_import_is_light():
    """Importing and using the store loads only the standard library (no numpy,
    no rosbags): it is on the start-up path of every command."""
    code = ("import sys\n"
            "before = set(sys.modules)\n"
            "import ybg.compiler.msgtypes as m\n"
            "s = m.load_store('ros2', environ={}); s.resolve('sensor_msgs/JointState'); s.all_names()\n"
            "mods = set(sys.modules)\n"
            "print('numpy' in mods, 'rosbags' in mods)\n"
            "std = set(sys.stdlib_module_names)\n"
            "print(sorted(x for x in mods - before if x.split('.')[0] not in std and x.split('.')[0] != 'ybg'))\n")
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True,
                         cwd=ROOT, env=env).stdout.splitlines()
    assert out == ["False False", "[]"]


def test_a_ros2_input_is_read_in_the_distro_the_config_names():
    """`[module] distro = kilted` holds for the topics a mux reads as for the
    output: nav_msgs/Goals is Kilted's only (Jazzy has no such type)."""
    from ybg.compiler.options import Options
    from ybg.compiler.pipeline import compile_text

    text = ("[module]\nname = goals_bridge\ndistro = kilted\n\n[output]\nport = /goals:o\n\n"
            "[mux g]\ntopics = /goals (nav_msgs/Goals header.stamp)\nvia = ros2\n\n[message]\nstamp = g[0]\n")
    assert [d.code for d in compile_text(text, "goals.ini").diagnostics] == []
    jazzy = compile_text(text, "goals.ini", Options(distro="jazzy")).diagnostics  # the command line wins
    assert [(d.code, d.span.line, d.span.column) for d in jazzy] == [("E301", 9, 18)]
