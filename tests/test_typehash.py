"""Type hashes (RIHS01, REP-2011) that ybgc computes from its own
definitions (ybg/compiler/typehash.py), against what ROS 2 itself says:

- every message type ybgc ships for Kilted, every ``.msg`` the venv's wheels
  install (``<venv>/share/<pkg>/msg``, found through AMENT_PREFIX_PATH) and the
  setup's message packages (``msgpkgs/``, found through ``--msg-path``): the
  hash equals the one the installed typesupport reports, read from the
  ``rosidl_message_type_support_t`` of the generated Python class (its
  ``get_type_hash_func``, which rcl calls when it advertises a publisher);
- every field type a ``.msg`` can spell (each primitive as a scalar, a fixed
  array, a bounded and an unbounded sequence, bounded strings, nested and
  empty messages): the description and the hash equal those of rosidl's own
  generator (rosidl_adapter, rosidl_parser, rosidl_generator_type_description,
  installed with the wheels);
- ``ybgc ir`` prints the hash of each ROS topic (null for ROS 1 and Humble);
- every service type ybgc ships for Kilted, and every ``.srv`` of the wheels
  and of ``msgpkgs/``: the hash equals the one the installed typesupport
  reports (``rosidl_service_type_support_t``'s ``get_type_hash_func``, which
  rcl calls when it creates a service or a client).

- the same for every message and service type ybgc ships for Jazzy, against
  the typesupport of Jazzy's wheels (``.venv-jazzy``, scripts/setup.sh; a
  test that does not find it fails saying how to install it).

Jazzy hashes are also checked to equal Kilted's where the two distros'
definitions are the same.
"""
from __future__ import annotations

import copy
import json
import subprocess
from pathlib import Path

import pytest

from harness.env import VENV, VENV_PYTHON, clean_environ
from harness.jazzy import JAZZY_VENV, jazzy_env, require_jazzy
from harness.generated import ybgc
from ybg.compiler.msgtypes import VENDORED_DIR, TypeStore, load_store
from ybg.compiler.typehash import (service_description, service_hash, service_hashes, type_description,
                                   type_hash, type_hashes)

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"

#: run by the venv's Python: reads a JSON list of ``pkg/Name``, prints
#: ``{pkg/Name: "RIHS01_..."}`` as the installed typesupport gives it, null for
#: a type whose package has no Python module installed
TYPESUPPORT_HASHES = r'''
import ctypes, importlib, json, sys

class TypeHash(ctypes.Structure):  # rosidl_type_hash_t
    _fields_ = [("version", ctypes.c_uint8), ("value", ctypes.c_uint8 * 32)]

GetTypeHash = ctypes.CFUNCTYPE(ctypes.POINTER(TypeHash), ctypes.c_void_p)

class MessageTypeSupport(ctypes.Structure):  # rosidl_message_type_support_t
    _fields_ = [("typesupport_identifier", ctypes.c_char_p), ("data", ctypes.c_void_p),
                ("func", ctypes.c_void_p), ("get_type_hash_func", GetTypeHash),
                ("get_type_description_func", ctypes.c_void_p),
                ("get_type_description_sources_func", ctypes.c_void_p)]

capsule_pointer = ctypes.pythonapi.PyCapsule_GetPointer
capsule_pointer.restype = ctypes.c_void_p
capsule_pointer.argtypes = [ctypes.py_object, ctypes.c_char_p]

out = {}
for name in json.load(sys.stdin):
    pkg, msg = name.split("/")
    try:
        module = importlib.import_module(pkg + ".msg")
    except ModuleNotFoundError as e:
        if e.name not in (pkg, pkg + ".msg"):
            raise
        out[name] = None
        continue
    cls = getattr(module, msg)
    cls.__class__.__import_type_support__()
    handle = capsule_pointer(cls._TYPE_SUPPORT, None)
    support = MessageTypeSupport.from_address(handle)
    assert support.typesupport_identifier == b"rosidl_typesupport_c", support.typesupport_identifier
    h = support.get_type_hash_func(handle).contents
    out[name] = "RIHS%02x_%s" % (h.version, bytes(h.value).hex())
json.dump(out, sys.stdout)
'''


#: the same for services: ``{pkg/Name: "RIHS01_..."}`` of ``pkg.srv.Name``
SERVICE_TYPESUPPORT_HASHES = r'''
import ctypes, importlib, json, sys

class TypeHash(ctypes.Structure):  # rosidl_type_hash_t
    _fields_ = [("version", ctypes.c_uint8), ("value", ctypes.c_uint8 * 32)]

GetTypeHash = ctypes.CFUNCTYPE(ctypes.POINTER(TypeHash), ctypes.c_void_p)

class ServiceTypeSupport(ctypes.Structure):  # rosidl_service_type_support_t
    _fields_ = [("typesupport_identifier", ctypes.c_char_p), ("data", ctypes.c_void_p),
                ("func", ctypes.c_void_p), ("request_typesupport", ctypes.c_void_p),
                ("response_typesupport", ctypes.c_void_p), ("event_typesupport", ctypes.c_void_p),
                ("event_message_create_handle_function", ctypes.c_void_p),
                ("event_message_destroy_handle_function", ctypes.c_void_p),
                ("get_type_hash_func", GetTypeHash), ("get_type_description_func", ctypes.c_void_p),
                ("get_type_description_sources_func", ctypes.c_void_p)]

capsule_pointer = ctypes.pythonapi.PyCapsule_GetPointer
capsule_pointer.restype = ctypes.c_void_p
capsule_pointer.argtypes = [ctypes.py_object, ctypes.c_char_p]

out = {}
for name in json.load(sys.stdin):
    pkg, srv = name.split("/")
    try:
        module = importlib.import_module(pkg + ".srv")
    except ModuleNotFoundError as e:
        if e.name not in (pkg, pkg + ".srv"):
            raise
        out[name] = None
        continue
    cls = getattr(module, srv)
    cls.__class__.__import_type_support__()
    handle = capsule_pointer(cls._TYPE_SUPPORT, None)
    support = ServiceTypeSupport.from_address(handle)
    assert support.typesupport_identifier == b"rosidl_typesupport_c", support.typesupport_identifier
    h = support.get_type_hash_func(handle).contents
    out[name] = "RIHS%02x_%s" % (h.version, bytes(h.value).hex())
json.dump(out, sys.stdout)
'''


def typesupport_hashes(names, script: str = TYPESUPPORT_HASHES, venv: Path = VENV) -> dict[str, str | None]:
    """The hash of each type as the typesupport installed in ``venv`` (the
    Kilted wheels', or the Jazzy ones' of JAZZY_VENV) reports it (with
    :data:`SERVICE_TYPESUPPORT_HASHES`, of each service)."""
    env = None if venv == VENV else jazzy_env(clean_environ())
    r = subprocess.run([str(venv / "bin" / "python"), "-c", script], input=json.dumps(sorted(names)),
                       capture_output=True, text=True, timeout=60, env=env)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def wheel_description(name: str, kind: str = "msg", venv: Path = VENV) -> dict | None:
    """The type description the wheel installed beside the type
    (``<venv>/share/<pkg>/msg/<Name>.json``; ``kind`` ``srv``: of a service),
    without default values."""
    pkg, msg = name.split("/")
    path = venv / "share" / pkg / kind / f"{msg}.json"
    if not path.is_file():
        return None
    description = json.loads(path.read_text())["type_description_msg"]
    return without_defaults(description)


def without_defaults(description: dict) -> dict:
    d = copy.deepcopy(description)
    for t in [d["type_description"], *d["referenced_type_descriptions"]]:
        for f in t["fields"]:
            f.pop("default_value", None)
    return d


def compare(store: TypeStore, names, venv: Path = VENV) -> tuple[list[str], list[str]]:
    """(types compared, types whose package ``venv`` has no module of);
    fails on a hash that differs, showing the descriptions."""
    ours = type_hashes(store, names)
    theirs = typesupport_hashes(names, venv=venv)
    compared = [n for n in names if theirs[n] is not None]
    missing = [n for n in names if theirs[n] is None]
    wrong = [n for n in compared if ours[n] != theirs[n]]
    if wrong:
        n = wrong[0]
        pytest.fail(f"{len(wrong)} of {len(compared)} hashes differ from the typesupport's: {wrong}\n"
                    f"{n}: ybgc {ours[n]}, typesupport {theirs[n]}\n"
                    f"ybgc's description:  {json.dumps(type_description(store, n))}\n"
                    f"the wheel's:         {json.dumps(wheel_description(n, venv=venv))}")
    return compared, missing


def test_every_kilted_type_ybgc_ships_hashes_as_the_installed_typesupport():
    store = load_store("ros2", "kilted", environ={})
    names = store.all_names()
    compared, missing = compare(store, names)
    # a package without a module here is one the setup does not install
    for n in missing:
        assert not (VENV / "share" / n.split("/")[0]).exists(), n
    packages = sorted({n.split("/")[0] for n in compared})
    not_installed = sorted({n.split("/")[0] for n in missing})
    print(f"\n{len(compared)} of {len(names)} shipped Kilted types compared ({', '.join(packages)}); "
          f"not installed: {', '.join(not_installed) or 'none'} ({len(missing)} types)")
    assert "std_msgs" in packages and "builtin_interfaces" in packages


def test_every_jazzy_type_ybgc_ships_hashes_as_jazzys_typesupport():
    # the Jazzy wheels of .venv-jazzy (scripts/setup.sh), with tf2_msgs built
    # from msgpkgs/ by Jazzy's rosidl: every shipped package is installed there
    require_jazzy(node_yarp=False)
    store = load_store("ros2", "jazzy", environ={})
    names = store.all_names()
    compared, missing = compare(store, names, JAZZY_VENV)
    assert not missing, missing
    packages = sorted({n.split("/")[0] for n in compared})
    print(f"\n{len(compared)} shipped Jazzy types compared ({', '.join(packages)})")
    assert {"std_msgs", "sensor_msgs", "tf2_msgs", "visualization_msgs"} <= set(packages)


def test_definitions_found_on_the_search_path_hash_as_the_installed_typesupport():
    # the wheels' own .msg files (AMENT_PREFIX_PATH), and the setup's message
    # packages from their sources (--msg-path msgpkgs), before the shipped ones
    store = load_store("ros2", "kilted", [ROOT / "msgpkgs"], environ={"AMENT_PREFIX_PATH": str(VENV)})
    vendored = Path(VENDORED_DIR)
    names = [n for n in store.all_names() if vendored not in Path(store.path_of(n)).parents]
    from_msgpkgs = [n for n in names if (ROOT / "msgpkgs") in Path(store.path_of(n)).parents]
    # (msgpkgs/jazzy/ holds the Jazzy builds of a package: not on a Kilted search path)
    assert {n.split("/")[0] for n in from_msgpkgs} == {p.name for p in (ROOT / "msgpkgs").iterdir()
                                                       if (p / "package.xml").exists()}
    compared, missing = compare(store, names)
    assert not missing, missing  # each of these is installed: found in the venv, or built into it
    print(f"\n{len(compared)} types of the search path compared ({len(from_msgpkgs)} from msgpkgs/: "
          f"{', '.join(from_msgpkgs)})")


# --------------------------------------------------------------------------
# Services


def compare_services(store: TypeStore, names, venv: Path = VENV) -> tuple[list[str], list[str]]:
    """:func:`compare` for services."""
    ours = service_hashes(store, names)
    theirs = typesupport_hashes(names, SERVICE_TYPESUPPORT_HASHES, venv)
    compared = [n for n in names if theirs[n] is not None]
    missing = [n for n in names if theirs[n] is None]
    wrong = [n for n in compared if ours[n] != theirs[n]]
    if wrong:
        n = wrong[0]
        pytest.fail(f"{len(wrong)} of {len(compared)} service hashes differ from the typesupport's: {wrong}\n"
                    f"{n}: ybgc {ours[n]}, typesupport {theirs[n]}\n"
                    f"ybgc's description:  {json.dumps(service_description(store, n))}\n"
                    f"the wheel's:         {json.dumps(wheel_description(n, 'srv', venv))}")
    return compared, missing


def test_every_kilted_service_ybgc_ships_hashes_as_the_installed_typesupport():
    store = load_store("ros2", "kilted", environ={})
    names = store.service_names()
    assert "std_srvs/Trigger" in names and "nav_msgs/GetMap" in names
    compared, missing = compare_services(store, names)
    # a package without services here is one the setup does not install, or
    # builds without them (tf2_msgs, msgpkgs/tf2_msgs: its messages only)
    for n in missing:
        assert not (VENV / "share" / n.split("/")[0] / "srv").exists(), n
    packages = sorted({n.split("/")[0] for n in compared})
    print(f"\n{len(compared)} of {len(names)} shipped Kilted services compared ({', '.join(packages)}); "
          f"not installed: {', '.join(missing) or 'none'}")
    assert {"std_srvs", "nav_msgs", "sensor_msgs", "diagnostic_msgs", "visualization_msgs"} <= set(packages)


def test_every_jazzy_service_ybgc_ships_hashes_as_jazzys_typesupport():
    require_jazzy(node_yarp=False)
    store = load_store("ros2", "jazzy", environ={})
    names = store.service_names()
    compared, missing = compare_services(store, names, JAZZY_VENV)
    # tf2_msgs is built with its messages only (msgpkgs/tf2_msgs), as for Kilted
    assert {n.split("/")[0] for n in missing} <= {"tf2_msgs"}, missing
    packages = sorted({n.split("/")[0] for n in compared})
    print(f"\n{len(compared)} of {len(names)} shipped Jazzy services compared ({', '.join(packages)}); "
          f"not installed: {', '.join(missing) or 'none'}")
    assert {"std_srvs", "nav_msgs", "sensor_msgs", "diagnostic_msgs", "visualization_msgs"} <= set(packages)


def test_services_found_on_the_search_path_hash_as_the_installed_typesupport():
    # the wheels' own .srv files (rcl_interfaces, lifecycle_msgs...) and the
    # setup's message packages (msgpkgs/ybg_demo_msgs/srv/LookAt.srv)
    store = load_store("ros2", "kilted", [ROOT / "msgpkgs"], environ={"AMENT_PREFIX_PATH": str(VENV)})
    vendored = Path(VENDORED_DIR)
    names = [n for n in store.service_names() if vendored not in Path(store.service_path(n)).parents]
    assert "ybg_demo_msgs/LookAt" in names
    assert (ROOT / "msgpkgs") in Path(store.service_path("ybg_demo_msgs/LookAt")).parents
    compared, missing = compare_services(store, names)
    assert not missing, missing
    print(f"\n{len(compared)} services of the search path compared: {', '.join(compared)}")


def test_service_description_is_rosidls():
    # the request, the response and the event of introspection, named in the
    # service's namespace; an empty request has rosidl's one member
    store = load_store("ros2", "kilted", environ={})
    d = service_description(store, "std_srvs/srv/Trigger")
    assert d == without_defaults(json.loads((VENV / "share/std_srvs/srv/Trigger.json").read_text())
                                 ["type_description_msg"])
    assert [f["name"] for f in d["type_description"]["fields"]] == \
        ["request_message", "response_message", "event_message"]
    assert [t["type_name"] for t in d["referenced_type_descriptions"]] == [
        "builtin_interfaces/msg/Time", "service_msgs/msg/ServiceEventInfo", "std_srvs/srv/Trigger_Event",
        "std_srvs/srv/Trigger_Request", "std_srvs/srv/Trigger_Response"]
    # pkg/Name and pkg/srv/Name; Jazzy's definitions are Kilted's; none before Iron nor in ROS 1
    assert service_hash(store, "std_srvs/Trigger") == service_hash(store, "std_srvs/srv/Trigger")
    jazzy = load_store("ros2", "jazzy", environ={})
    assert service_hashes(jazzy, ["std_srvs/SetBool", "nav_msgs/GetMap"]) == \
        service_hashes(store, ["std_srvs/SetBool", "nav_msgs/GetMap"])
    assert service_hash(load_store("ros2", "humble", environ={}), "std_srvs/Trigger") is None
    with pytest.raises(LookupError):
        service_hash(store, "std_srvs/Trigerr")


# --------------------------------------------------------------------------
# Every field type, against rosidl's own generator

PRIMITIVES = ["bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32",
              "int64", "uint64", "float32", "float64", "string", "wstring"]
ARRAYS = ["", "[3]", "[<=3]", "[]"]


def field_types_package() -> dict[str, str]:
    """``.msg`` texts of a package ``ybg_typehash`` using every field type."""
    lines = [f"{p}{a} f_{p}_{i}" for p in PRIMITIVES for i, a in enumerate(ARRAYS)]
    lines += [f"{s}<=5{a} b_{s}_{i}" for s in ("string", "wstring") for i, a in enumerate(ARRAYS)]
    lines += [f"Inner{a} inner_{i}" for i, a in enumerate(ARRAYS)]
    lines += ["std_msgs/Header header", "builtin_interfaces/Duration[2] durations",
              "int32 with_default 5", 'string<=8 text_default "ab"', "float64[] list_default [1.5, 2.0]",
              "int32 CONSTANT=7", "Empty nothing"]
    return {
        "AllTypes": "\n".join(lines) + "\n",
        "Inner": "geometry_msgs/Point32[<=2] points\nchar c\n",
        "Empty": "# no fields\nuint8 ONLY_A_CONSTANT=1\n",
    }


def rosidl_descriptions(root: Path, texts: dict[str, str]) -> dict[str, dict]:
    """What rosidl makes of the package: ``{pkg/Name: full type description}``
    (the .msg converted to .idl by rosidl_adapter, parsed by rosidl_parser,
    described by rosidl_generator_type_description; the types of other
    packages from the wheels' descriptions)."""
    from rosidl_adapter.msg import convert_msg_to_idl
    from rosidl_generator_type_description import (extract_full_type_description,
                                                   serialize_individual_type_description)
    from rosidl_parser.definition import IdlLocator, Message
    from rosidl_parser.parser import parse_idl_file

    pkg = root / "ybg_typehash"
    (pkg / "msg").mkdir(parents=True)
    type_map = {}
    for json_file in (VENV / "share").glob("*/msg/*.json"):
        d = json.loads(json_file.read_text())["type_description_msg"]
        for t in [d["type_description"], *d["referenced_type_descriptions"]]:
            type_map[t["type_name"]] = t
    for name, text in texts.items():
        (pkg / "msg" / f"{name}.msg").write_text(text)
        idl = convert_msg_to_idl(pkg, "ybg_typehash", Path("msg") / f"{name}.msg", pkg / "msg")
        locator = IdlLocator(pkg, idl.relative_to(pkg))
        for element in parse_idl_file(locator).content.elements:
            if isinstance(element, Message):
                s = element.structure
                type_map["/".join(s.namespaced_type.namespaced_name())] = \
                    serialize_individual_type_description(s.namespaced_type, s.members)
    return {f"ybg_typehash/{n}": extract_full_type_description(f"ybg_typehash/msg/{n}", type_map)
            for n in texts}


def test_every_field_type_is_described_and_hashed_as_rosidl_does(tmp_path):
    from rosidl_generator_type_description import calculate_type_hash

    texts = field_types_package()
    reference = rosidl_descriptions(tmp_path / "src", texts)
    user = tmp_path / "msgs" / "ybg_typehash"
    user.mkdir(parents=True)
    for name, text in texts.items():
        (user / f"{name}.msg").write_text(text)
    store = load_store("ros2", "kilted", [tmp_path / "msgs"], environ={})
    for name, full in reference.items():
        assert type_description(store, name) == without_defaults(full), name
        assert type_hash(store, name) == calculate_type_hash(full), name
    fields = reference["ybg_typehash/AllTypes"]["type_description"]["fields"]
    assert len({f["type"]["type_id"] for f in fields}) >= 60  # every kind of field is there


# --------------------------------------------------------------------------
# ybgc ir, and the distros without wheels here


def ends(ir: dict) -> list[dict]:
    """The output and the inputs of ``ybgc ir``'s JSON."""
    return [ir["output"], *(i for m in ir["muxes"] for i in m["inputs"])]


def ir_of(*args) -> dict:
    r = ybgc("ir", *args)
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def test_ir_prints_the_type_hash_of_each_ros_topic():
    ros2_output, ros2_input = EXAMPLES / "tf_frames_ros2.ini", EXAMPLES / "moveit_trajectory_to_yarp.ini"
    kilted = [e for cfg in (ros2_output, ros2_input) for e in ends(ir_of(cfg, "--distro", "kilted"))
              if e["kind"] == "ros2"]
    types = {e.get("msg_type") or e["ros_type"]: e["type_hash"] for e in kilted}
    assert len(types) == 2  # tf2_msgs/TFMessage out, trajectory_msgs/JointTrajectory in
    assert types == typesupport_hashes(types)
    # the default distro, Jazzy: the same definitions of these types, the same hashes
    jazzy = [e for cfg in (ros2_output, ros2_input) for e in ends(ir_of(cfg)) if e["kind"] == "ros2"]
    assert {e.get("msg_type") or e["ros_type"]: e["type_hash"] for e in jazzy} == types
    # no type hashes before Iron, nor in ROS 1
    for cfg, distro in ((ros2_output, "humble"), (ros2_input, "humble"),
                        (EXAMPLES / "rviz_joint_states_ros1.ini", "noetic")):
        found = [e for e in ends(ir_of(cfg, "--distro", distro)) if e["kind"] in ("ros1", "ros2")]
        assert found and all(e["type_hash"] is None for e in found), (cfg, found)
    # a YARP end has none
    assert "type_hash" not in ir_of(ros2_input)["output"]


def files_of(store: TypeStore, name: str) -> list[bytes]:
    """The definition files of ``name`` and of every type it references."""
    d = type_description(store, name)
    types = [d["type_description"], *d["referenced_type_descriptions"]]
    names = [t["type_name"].replace("/msg/", "/") for t in types]
    return [Path(store.path_of(n)).read_bytes() for n in names]


def test_jazzy_hashes_equal_kilted_ones_where_the_definitions_are_the_same():
    jazzy, kilted = (load_store("ros2", d, environ={}) for d in ("jazzy", "kilted"))
    on_jazzy = type_hashes(jazzy, jazzy.all_names())
    on_kilted = type_hashes(kilted, kilted.all_names())
    assert all(h and h.startswith("RIHS01_") for h in on_jazzy.values())
    differ = []
    for name, h in on_jazzy.items():
        if name in on_kilted and files_of(jazzy, name) == files_of(kilted, name):
            assert h == on_kilted[name], name
        elif name in on_kilted:
            differ.append(name)
    print(f"\n{len(on_jazzy)} Jazzy types hashed; defined otherwise than in Kilted: {differ or 'none'}; "
          f"Kilted only: {sorted(set(on_kilted) - set(on_jazzy))}")
    humble, noetic = load_store("ros2", "humble", environ={}), load_store("ros1", "noetic", environ={})
    assert set(type_hashes(humble, humble.all_names()).values()) == {None}
    assert type_hash(noetic, "std_msgs/Header") is None


def test_hashes_need_no_ros_and_check_computes_none():
    code = f"""
import sys
from ybg.cli import main
main(["check", {str(EXAMPLES / "tf_frames_ros2.ini")!r}])
assert "ybg.compiler.typehash" not in sys.modules, "ybgc check imports the type hashes"
before = set(sys.modules)
from ybg.compiler.msgtypes import load_store
from ybg.compiler.typehash import type_hashes
store = load_store("ros2", "kilted", environ={{}})
assert all(type_hashes(store, store.all_names()).values())
loaded = {{m.split(".")[0] for m in set(sys.modules) - before}}
print(sorted(loaded - set(sys.stdlib_module_names) - {{"ybg"}}))
"""
    r = subprocess.run([str(VENV_PYTHON), "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.strip() == "[]"  # the standard library and ybgc only
