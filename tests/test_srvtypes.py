"""ROS 2 service definitions (``.srv``) in the type store: the vendored ones
(``ybg/msgs/<distro>/<pkg>/<Name>.srv``, scripts/vendor_srvs.py), the user's
own (``--msg-path``, ``YBG_MSG_PATH``, ``AMENT_PREFIX_PATH``), and bad files,
which are problems, never exceptions."""

from __future__ import annotations

import os
import textwrap
import tomllib
from pathlib import Path

import pytest

from harness.env import VENV
from ybg.compiler.ir import TypeRef
from ybg.compiler.msgtypes import VENDORED_DIR, load_store, parse_srv

ROOT = Path(__file__).resolve().parent.parent
SERVICE_DISTROS = ("humble", "jazzy", "kilted")
NO_ENV: dict[str, str] = {}


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text).lstrip("\n"), encoding="utf-8")
    return path


def vendored_srvs(distro: str) -> list[Path]:
    return sorted((Path(VENDORED_DIR) / distro).glob("*/*.srv"))


# --------------------------------------------------------------------------
# The vendored services


@pytest.mark.parametrize("distro", SERVICE_DISTROS)
def test_every_vendored_service_parses_in_its_distro(distro):
    store = load_store("ros2", distro, environ=NO_ENV)
    files = vendored_srvs(distro)
    names = store.service_names()
    assert names == sorted(f"{p.parent.name}/{p.stem}" for p in files)
    for name in names:
        srv = store.resolve_service(name)
        assert srv is not None, (name, store.problems)
        assert srv.request.name == f"{name}_Request" and srv.response.name == f"{name}_Response"
    assert store.problems == []
    assert {"std_srvs/Empty", "std_srvs/SetBool", "std_srvs/Trigger", "sensor_msgs/SetCameraInfo",
            "nav_msgs/GetMap", "nav_msgs/GetPlan", "nav_msgs/SetMap", "nav_msgs/LoadMap",
            "diagnostic_msgs/AddDiagnostics", "diagnostic_msgs/SelfTest",
            "visualization_msgs/GetInteractiveMarkers"} <= set(names)


def test_vendored_kilted_services_are_the_wheels_files():
    # exact copies: byte for byte what the Kilted wheels installed here hold
    compared = 0
    for path in vendored_srvs("kilted"):
        installed = VENV / "share" / path.parent.name / "srv" / path.name
        if installed.is_file():
            assert path.read_bytes() == installed.read_bytes(), path
            compared += 1
    assert compared >= 11


def test_trigger_and_set_bool():
    store = load_store("ros2", "jazzy", environ=NO_ENV)
    trigger = store.resolve_service("std_srvs/Trigger")
    assert trigger is not None and trigger.name == "std_srvs/Trigger"
    assert trigger.request.fields == ()
    assert [(f.name, f.type) for f in trigger.response.fields] == \
        [("success", TypeRef("bool")), ("message", TypeRef("string"))]
    set_bool = store.resolve_service("std_srvs/srv/SetBool")
    assert set_bool is not None and set_bool.name == "std_srvs/SetBool"
    assert [(f.name, f.type) for f in set_bool.request.fields] == [("data", TypeRef("bool"))]
    assert [f.name for f in set_bool.response.fields] == ["success", "message"]
    assert store.service_path("std_srvs/srv/SetBool") == os.path.join(VENDORED_DIR, "jazzy", "std_srvs",
                                                                       "SetBool.srv")
    # once resolved, the request and the response are messages of the store
    assert store.resolve("std_srvs/Trigger_Response") == trigger.response
    # a message is no service, nor the other way round
    assert store.resolve_service("std_msgs/Header") is None and store.resolve("std_srvs/Trigger") is None
    assert store.service_candidates("Trigger") == ["std_srvs/Trigger"]
    empty = store.resolve_service("std_srvs/Empty")
    assert empty is not None and empty.request.fields == () == empty.response.fields
    # the fields of a service may be messages, of its own package or another
    get_plan = store.resolve_service("nav_msgs/GetPlan")
    assert [str(f.type) for f in get_plan.request.fields] == \
        ["geometry_msgs/PoseStamped", "geometry_msgs/PoseStamped", "float32"]
    assert get_plan.response.fields[0].type == TypeRef("nav_msgs/Path")
    load_map = store.resolve_service("nav_msgs/LoadMap")
    assert load_map.response.constant("RESULT_UNDEFINED_FAILURE").value == 255


# --------------------------------------------------------------------------
# The user's own services

LOOK_AT = """
    # A fixation point
    float64 x   # metres
    float64 y
    float64 z
    float64 timeout  # seconds
    ---
    bool success
    string message
    """


def test_a_user_service_is_found_through_the_msg_path(tmp_path):
    write(tmp_path / "my_gaze" / "srv" / "LookAt.srv", LOOK_AT)
    write(tmp_path / "my_gaze" / "msg" / "Target.msg", "geometry_msgs/Point point\n")
    write(tmp_path / "my_gaze" / "srv" / "Track.srv", "Target target\nbuiltin_interfaces/Duration during\n"
                                                      "---\nTarget[] reached\n")
    store = load_store("ros2", "kilted", [tmp_path], environ=NO_ENV)
    look_at = store.resolve_service("my_gaze/LookAt")
    assert look_at is not None
    assert [f.name for f in look_at.request.fields] == ["x", "y", "z", "timeout"]
    assert [f.name for f in look_at.response.fields] == ["success", "message"]
    assert store.service_path("my_gaze/srv/LookAt") == str(tmp_path / "my_gaze" / "srv" / "LookAt.srv")
    track = store.resolve_service("my_gaze/Track")
    assert track is not None, store.problems
    assert track.request.fields[0].type == TypeRef("my_gaze/Target")
    assert track.response.fields[0].type == TypeRef("my_gaze/Target", "sequence")
    assert {"my_gaze/LookAt", "my_gaze/Track", "std_srvs/Trigger"} <= set(store.service_names())
    # a user's definition comes before the shipped one
    write(tmp_path / "std_srvs" / "srv" / "Trigger.srv", "---\nbool done\n")
    store = load_store("ros2", "kilted", [tmp_path], environ=NO_ENV)
    assert [f.name for f in store.resolve_service("std_srvs/Trigger").response.fields] == ["done"]


def test_user_services_through_the_environment(tmp_path):
    write(tmp_path / "dirs" / "my_gaze" / "srv" / "LookAt.srv", LOOK_AT)
    write(tmp_path / "prefix" / "share" / "my_arm" / "srv" / "Home.srv", "string part\n---\nbool success\n")
    env = {"YBG_MSG_PATH": str(tmp_path / "dirs"), "AMENT_PREFIX_PATH": str(tmp_path / "prefix")}
    store = load_store("ros2", "jazzy", environ=env)
    assert store.resolve_service("my_gaze/LookAt") is not None
    assert store.resolve_service("my_arm/srv/Home") is not None
    # the project's own message package: msgpkgs/ybg_demo_msgs/srv/LookAt.srv
    store = load_store("ros2", "jazzy", [ROOT / "msgpkgs"], environ=NO_ENV)
    demo = store.resolve_service("ybg_demo_msgs/LookAt")
    assert demo is not None and [f.name for f in demo.request.fields] == ["x", "y", "z", "timeout"]


# --------------------------------------------------------------------------
# Bad files: problems, not exceptions


def test_a_service_without_separator_is_a_problem(tmp_path):
    srv, problems = parse_srv("bool data\nstring text\n", "my_pkg/NoCut", "ros2")
    assert [p.message for p in problems] == ["no '---' line between the request and the response"]
    assert problems[0].line == 2
    assert [f.name for f in srv.request.fields] == ["data", "text"] and srv.response.fields == ()
    write(tmp_path / "my_pkg" / "srv" / "NoCut.srv", "bool data\n")
    write(tmp_path / "my_pkg" / "srv" / "Twice.srv", "bool data\n---\nbool ok\n---\nbool again\n")
    write(tmp_path / "my_pkg" / "srv" / "Unknown.srv", "---\nmy_pkg/Nothing result\n")
    write(tmp_path / "my_pkg" / "srv" / "BadField.srv", "int33 x\n---\n")
    write(tmp_path / "my_pkg" / "srv" / "Empty.srv", "")
    store = load_store("ros2", "kilted", [tmp_path], environ=NO_ENV)
    for name in ("NoCut", "Twice", "Unknown", "BadField", "Empty"):
        assert store.resolve_service(f"my_pkg/{name}") is None, name
    text = "\n".join(str(p) for p in store.problems)
    assert "NoCut.srv:1:1: no '---' line" in text
    assert "Twice.srv:4:1: '---' separator in a message" in text
    assert "Unknown.srv:2:1: unknown message type 'my_pkg/Nothing'" in text
    assert "BadField.srv:1:1: unknown primitive type 'int33'" in text
    assert "Empty.srv:1:1: no '---' line" in text
    # an unreadable file, a name that is no service name
    (tmp_path / "my_pkg" / "srv" / "Binary.srv").write_bytes(b"\xff\xfe---\n")
    store = load_store("ros2", "kilted", [tmp_path], environ=NO_ENV)
    assert store.resolve_service("my_pkg/Binary") is None
    assert "cannot read" in str(store.problems[-1])
    assert store.resolve_service("not a name") is None and store.resolve_service("a/b/c/d") is None


# --------------------------------------------------------------------------
# Packaging


def test_the_distributions_hold_the_srv_files():
    """The sdist takes ``MANIFEST.in``'s files and the wheel the sdist's
    package data (``include-package-data``): every vendored ``.srv`` is in
    them. (tests/test_install.py builds both and checks every tracked file.)"""
    from setuptools.command.egg_info import FileList

    config = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert config["tool"]["setuptools"]["include-package-data"] is True
    ybg = ROOT / "ybg"
    files = FileList()
    files.set_allfiles([str(Path(d, f).relative_to(ROOT)) for d, _, fs in os.walk(ybg) for f in fs])
    for line in (ROOT / "MANIFEST.in").read_text().splitlines():
        if line.strip() and not line.lstrip().startswith("#"):
            files.process_template_line(line)
    srvs = [str(p.relative_to(ROOT)) for d in SERVICE_DISTROS for p in vendored_srvs(d)]
    assert len(srvs) >= 3 * 11
    assert set(srvs) <= set(files.files)
