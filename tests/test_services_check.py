"""The checker of a config of commands ([service] sections, docs/services.md):
the IR it builds from the examples, the failure answers it derives, and the
mistakes it reports (the invalid corpus holds one file per code; these are
the other cases of each code)."""

from __future__ import annotations

import math
from pathlib import Path

import pytest

from ybg.compiler import ir
from ybg.compiler.options import Options
from ybg.compiler.pipeline import compile_path, compile_text
from ybg.lower import services as texts

ROOT = Path(__file__).resolve().parent.parent
MSGPKGS = Options(msg_path=(str(ROOT / "msgpkgs"),))


def program(name: str) -> ir.Commands:
    result = compile_path(ROOT / "examples" / name, MSGPKGS)
    assert not result.errors, result.errors
    assert isinstance(result.program, ir.Commands)
    return result.program


def codes(text: str, options: Options = MSGPKGS) -> list[tuple[str, int, int]]:
    result = compile_text(text, "c.ini", options)
    return [(d.code, d.span.line, d.span.column) for d in result.errors]


def test_trigger_served_sends_its_command_and_fills_the_response_from_the_reply():
    (home,) = program("home_arm_trigger.ini").services
    assert (home.serves, home.service, home.srv_type, home.port) == (
        "ros2", "/icub/left_arm/home", "std_srvs/Trigger", "/icub/left_arm/homing/rpc:i")
    assert home.timeout == 5.0 and home.layout == (ir.ElementGroup("string", 1),)
    assert [(i.kind, i.value, i.type) for i in home.bottle] == [("literal", "home", "string"),
                                                               ("literal", "all", "string")]
    assert [(f.ref.dotted, f.ref.type.base, f.source, f.start) for f in home.fills] == [
        ("success", "bool", "element", 0), ("message", "string", "text", 0)]
    # a failed call: success false and the reason in message; nothing else to say
    assert [(f.ref.dotted, f.source, f.value) for f in home.failure_fills] == [
        ("success", "literal", False), ("message", "error", None)]
    assert home.true_words == ir.TRUE_WORDS


def test_a_users_own_service_sends_its_numbers_in_a_nested_list():
    (look,) = program("gaze_look_at.ini").services
    assert look.srv_type == "ybg_demo_msgs/LookAt"
    cmd, three_d, point, timeout = look.bottle
    assert (cmd.value, three_d.value) == ("look", "3D")
    assert point.kind == "list" and [i.ref.dotted for i in point.items] == ["x", "y", "z"]
    assert all(i.ref.type == ir.TypeRef("float64") for i in point.items)
    assert timeout.kind == "field" and timeout.ref.dotted == "timeout" and timeout.converter is None


def test_yarp_port_served_fills_the_request_from_the_arguments_and_replies_the_response():
    commands = program("yarp_rpc_to_ros2.ini")
    home, track = commands.services
    assert commands.served_ports == ("/robot_gate/rpc:i",)
    assert commands.on_port("/robot_gate/rpc:i") == (home, track)
    # `home` reads no argument and declares none: it takes none
    assert home.serves == "yarp" and home.layout == () and home.fills == ()
    assert track.layout == (ir.ElementGroup("int32", 1),)
    assert [(f.ref.dotted, f.source, f.start) for f in track.fills] == [("data", "element", 0)]
    assert [i.ref.dotted for i in track.bottle] == ["success", "message"]
    # the failure reply: success 0 and the reason where the message goes
    assert [(i.kind, i.value, i.type) for i in track.failure_bottle] == [("literal", 0, "int32"),
                                                                        ("error", None, None)]


def test_help_and_reasons_are_made_once_from_the_ir():
    commands = program("yarp_rpc_to_ros2.ini")
    assert texts.help_lines(commands, "/robot_gate/rpc:i") == [
        "home: calls the ROS 2 service /robot/home (std_srvs/Trigger)",
        "track data:int32: calls the ROS 2 service /tracker/enable (std_srvs/SetBool)",
        "help: this list",
    ]
    (home,) = program("home_arm_trigger.ini").services
    reasons = texts.reasons(home)
    assert reasons["timed_out"] == "/icub/left_arm/homing/rpc:i did not answer within 5 s"
    assert reasons["no_server"].startswith("/icub/left_arm/homing/rpc:i: no server")


def test_converters_on_a_request_field_and_on_the_reply():
    text = """
[service aim]
serve = /aim (ybg_demo_msgs/LookAt)
call = /gaze/rpc (string x1, float64 x1)
send = "aim", deg_to_rad(request.x), scale(0.001)(request.y), [request.z]
convert = rad_to_deg[1:2]
true_words = done, "ok"
response.success = reply[0]
response.message = reply
"""
    result = compile_text(text, "aim.ini", MSGPKGS)
    assert not result.errors, result.errors
    (aim,) = result.program.services
    x, y = aim.bottle[1], aim.bottle[2]
    assert x.converter.name == "deg_to_rad" and x.converter.scale == math.pi / 180.0
    assert y.converter.name == "scale" and y.converter.scale == 0.001
    assert aim.bottle[3].kind == "list"
    (conv,) = aim.converters
    assert (conv.name, conv.start, conv.stop) == ("rad_to_deg", 1, 2)
    assert aim.true_words == ("done", "ok")


def test_ir_of_commands_round_trips_through_json():
    for name in ("home_arm_trigger.ini", "gaze_look_at.ini", "yarp_rpc_to_ros2.ini", "gaze_tracking_setbool.ini"):
        p = program(name)
        assert ir.from_json(ir.to_json(p)) == p


@pytest.mark.parametrize("text, expected", [
    # a key of the other direction: `reply` on a served ROS 2 service
    ('[service a]\nserve = /a (std_srvs/Trigger)\ncall = /a/rpc\nsend = "a"\nreply = response.message\n'
     'response.success = reply[0]\n', [("E202", 5, 1)]),
    # no `send`
    ("[service a]\nserve = /a (std_srvs/Trigger)\ncall = /a/rpc\nresponse.success = reply[0]\n", [("E204", 1, 1)]),
    # a bare word in `send` (a word is sent quoted; a field is request.<field>)
    ("[service a]\nserve = /a (std_srvs/SetBool)\ncall = /a/rpc\nsend = home, request.data\n"
     "response.success = reply[0]\n", [("E208", 4, 8)]),
    # a converter on a bool
    ("[service a]\nserve = /a (std_srvs/SetBool)\ncall = /a/rpc\nsend = deg_to_rad(request.data)\n"
     "response.success = reply[0]\n", [("E314", 4, 8)]),
    # one ROS 2 service served twice
    ("[service a]\nserve = /a (std_srvs/Trigger)\ncall = /a/rpc\nsend = \"a\"\nresponse.success = reply[0]\n\n"
     "[service b]\nserve = /a (std_srvs/Trigger)\ncall = /b/rpc\nsend = \"b\"\nresponse.success = reply[0]\n",
     [("E353", 7, 1)]),
    # the reply as text into a bool
    ("[service a]\nserve = /a (std_srvs/Trigger)\ncall = /a/rpc\nsend = \"a\"\nresponse.success = reply\n",
     [("E305", 5, 20)]),
    # a failure answer that is not a constant
    ("[service a]\nserve = /a (std_srvs/Trigger)\ncall = /a/rpc\nsend = \"a\"\nresponse.message = reply\n"
     "failure.success = reply[0]\n", [("E208", 6, 19)]),
    # neither side a ROS 2 service
    ("[service a]\nserve = /a/rpc:i\ncall = /b/rpc\n", [("E352", 1, 1)]),
])
def test_mistakes(text, expected):
    assert codes(text) == expected


def test_a_service_section_needs_its_name():
    assert codes("[service]\nserve = /a (std_srvs/Trigger)\n")[0] == ("E104", 1, 1)


def test_failure_constants_answer_a_service_without_success():
    text = """
[service a]
serve = /a (std_srvs/Trigger)
call = /a/rpc
send = "a"
response.message = reply
failure.message = error
"""
    result = compile_text(text, "a.ini", MSGPKGS)
    assert not result.errors, result.errors
    (a,) = result.program.services
    assert [(f.ref.dotted, f.source) for f in a.failure_fills] == [("message", "error")]


def test_on_failure_replies_what_the_config_says():
    text = """
[service home]
serve = /gate/rpc:i
call = /robot/home (std_srvs/Trigger)
reply = response.message
on_failure = "fail", error
"""
    result = compile_text(text, "a.ini", MSGPKGS)
    assert not result.errors, result.errors
    (home,) = result.program.services
    assert [(i.kind, i.value) for i in home.failure_bottle] == [("literal", "fail"), ("error", None)]
