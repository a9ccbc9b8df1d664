"""The runtime of the rclpy node of commands (ybg/runtime/services.py, commands.py) and
the node's functions the ros2 backend writes, without a name server or a
ROS 2 peer: a reply Bottle's elements checked, converted and filled into a
response (the bool-from-word rule, a vocab as its word), the command Bottle
built from a request (a bool as 0/1, a converter as float64, an array one
item per element), the failure answers and reasons, `help`, `stats` and an
unknown command on a served port, and the texts held to ybg.lower.services.
The calls through real peers are tests/test_services*.py's."""
from __future__ import annotations

import types

import pytest
import yarp
from std_srvs.srv import SetBool, Trigger

from ybg.backends import RenderOptions, check_result, get_backend
from ybg.compiler import ir
from ybg.compiler.pipeline import compile_path
from ybg.lower import services as texts
from ybg.runtime import commands as rt
from ybg.runtime.commands import Conv, Elements, Unfit

from harness.env import EXAMPLES


def bottle(text: str) -> yarp.Bottle:
    return yarp.Bottle(text)


def items(b: yarp.Bottle) -> list:
    """The Bottle as (tag, value) pairs; a nested list as a list of them."""
    out = []
    for k in range(b.size()):
        v = b.get(k)
        if v.isList():
            out.append(items(v.asList()))
        elif v.isString():
            out.append(("string", v.asString()))
        elif v.isInt32():
            out.append(("int32", v.asInt32()))
        elif v.isInt64():
            out.append(("int64", v.asInt64()))
        elif v.isFloat64():
            out.append(("float64", v.asFloat64()))
        elif v.isVocab32():
            out.append(("vocab", yarp.decode(v.asVocab32())))
        else:
            out.append(("?", v.toString()))
    return out


# --------------------------------------------------------------------------
# the texts are the compiler's


def test_totals_and_stats_formats_are_the_compilers():
    assert rt.TOTALS_LINE == texts.TOTALS_LINE
    assert rt.STATS_KEYS == texts.STATS_KEYS


def test_totals_line_and_stats_list():
    s = types.SimpleNamespace(name="home")
    counts = rt.Counts()
    counts.calls = 5
    counts.count(None)
    counts.count("timed_out")
    counts.count("waited")
    counts.count("no_server")
    counts.count("unfit")
    assert rt.totals_lines([s], {"home": counts}) == [
        "service home: calls 5, answered 1, failed 4 (timed out 2, no server 1, did not fit 1)"]
    reply = rt.stats_reply(yarp.Bottle(), [s], {"home": counts})
    assert reply.toString() == "(service home calls 5 answered 1 failed 4 timed_out 2 no_server 1 unfit 1)"


# --------------------------------------------------------------------------
# a reply's elements


def test_bool_from_word_vocab_and_number():
    e = Elements(bottle("ok nack [ack] [fail] 1 0 2.5 0.0 \"done\""), true_words=ir.TRUE_WORDS)
    assert [e.bool(k) for k in range(9)] == [True, False, True, False, True, False, True, False, True]


def test_own_true_words():
    e = Elements(bottle("yes oui"), true_words=("oui",))
    assert (e.bool(0), e.bool(1)) == (False, True)


def test_vocab_is_a_word():
    b = yarp.Bottle()
    b.addVocab32("ok")
    e = Elements(b, types=("string",))
    assert e.str(0) == "ok"
    assert e.text() == "[ok]"


def test_numbers_words_and_whole_text():
    e = Elements(bottle('3 2.5 hello "two words"'))
    assert (e.int(0), e.float(0), e.float(1), e.str(2), e.str(3)) == (3, 3.0, 2.5, "hello", "two words")
    assert e.text() == 'hello'.join(["3 2.5 ", ' "two words"'])
    with pytest.raises(Unfit, match="element 2 is the word hello, not a number"):
        e.float(2)
    with pytest.raises(Unfit, match="element 1 is the number 2.5, not an integer"):
        e.int(1)
    with pytest.raises(Unfit, match="element 0 is the integer 3, not a word"):
        e.str(0)
    with pytest.raises(Unfit, match="no element 4"):
        e.str(4)


def test_a_nested_list_fills_nothing():
    e = Elements(bottle("(garbage 1.5) 42"))
    with pytest.raises(Unfit, match=r"element 0 is a list \(garbage 1.5\)"):
        e.bool(0)
    assert e.int(1) == 42


def test_declared_layout():
    assert Elements(bottle("1 2 3.5 ok"), types=("int32", "float64", "float64", "string")).values == [
        1, 2.0, 3.5, "ok"]
    with pytest.raises(Unfit, match="2 elements, expected 1"):
        Elements(bottle("ok ok"), types=("string",))
    with pytest.raises(Unfit, match="element 0 is the word on, expected int32"):
        Elements(bottle("on"), types=("int32",))
    with pytest.raises(Unfit, match=r"element 0 is a list \(garbage 1.5\), expected a string"):
        Elements(bottle("(garbage 1.5) 42"), types=("string", "int32"))
    assert Elements(bottle("1 0"), types=("bool", "bool")).values == [True, False]


def test_converters():
    deg = Conv("deg_to_rad", 3.141592653589793 / 180, 0.0, True, 0, 2)
    e = Elements(bottle("180 90 7"), types=("int32", "int32", "int32"), converters=(deg,))
    assert e.values == pytest.approx([3.141592653589793, 1.5707963267948966, 7])
    assert isinstance(e.values[2], int)
    with pytest.raises(Unfit, match=r"element 0 is the word ok, not a number \(deg_to_rad\)"):
        Elements(bottle("ok"), converters=(deg,))


def test_slices_into_arrays():
    e = Elements(bottle("1 2 3 4"))
    assert e.floats(1) == [2.0, 3.0, 4.0]
    assert e.ints(0, 2) == [1, 2]
    assert e.floats(1, fixed=3, field="v") == [2.0, 3.0, 4.0]
    with pytest.raises(Unfit, match="field v holds exactly 2 values, got 3"):
        e.floats(1, fixed=2, field="v")
    with pytest.raises(Unfit, match="field v holds at most 2 values, got 4"):
        e.ints(0, bound=2, field="v")
    with pytest.raises(Unfit, match=r"no elements \[2:6\]"):
        e.floats(2, 6)
    assert e.bytes(0, 2) == [b"\x01", b"\x02"]


def test_arguments_after_the_word():
    e = Elements(bottle("track 1 2.5"), 1, types=("int32", "float64"))
    assert (e.bool(0), e.float(1), e.text()) == (True, 2.5, "1 2.5")


# --------------------------------------------------------------------------
# Bottles from a message's fields


def test_values_on_the_wire():
    b = yarp.Bottle()
    rt.add_value(b, "int32", True)
    rt.add_value(b, "int64", 2**32)
    rt.add_value(b, "float64", 1)
    rt.add_value(b, "string", "a b")
    rt.add_value(b, "int32", b"\x07")
    rt.add_values(b.addList(), "float64", [1.0, 2.5])
    assert items(b) == [("int32", 1), ("int64", 2**32), ("float64", 1.0), ("string", "a b"), ("int32", 7),
                        [("float64", 1.0), ("float64", 2.5)]]


def test_converted_values_are_float64():
    b = yarp.Bottle()
    rt.add_converted(b, 90, 0.5, 1.0)
    rt.add_converted(b, [2, 4], 10.0, 0.0)
    assert items(b) == [("float64", 46.0), ("float64", 20.0), ("float64", 40.0)]


# --------------------------------------------------------------------------
# the node's functions, as the ros2 backend writes them


def node_namespace(program) -> dict:
    """The generated node (runtime inlined) executed as a module, not run."""
    files = get_backend("ros2").render(program, RenderOptions(single_file=True))
    (name,) = [k for k in files if k.endswith("_node.py")]
    namespace = {"__name__": "generated_node"}
    exec(compile(files[name], name, "exec"), namespace)
    return namespace


def example(stem: str) -> ir.Commands:
    result = check_result(compile_path(EXAMPLES / f"{stem}.ini"), "ros2")
    assert result.ok, [str(d) for d in result.diagnostics]
    assert isinstance(result.program, ir.Commands)
    return result.program


T = ir.TypeRef


def ref(*path, t="string", array=None, size=None) -> ir.FieldRef:
    return ir.FieldRef(tuple(path), T(t, array, size))


def test_trigger_served_the_command_the_response_and_the_failure():
    ns = node_namespace(example("home_arm_trigger"))
    (s,) = ns["SERVICES"]
    assert s.srv_class is Trigger and s.port == "/icub/left_arm/homing/rpc:i" and s.timeout == 5.0
    assert items(s.command(Trigger.Request())) == [("string", "home"), ("string", "all")]
    reply = bottle("ok")
    r = s.fill(reply, Elements(reply, 0, s.types, s.converters, s.true_words), Trigger.Response())
    assert (r.success, r.message) == (True, "ok")
    reply = bottle("busy")
    r = s.fill(reply, Elements(reply, 0, s.types, s.converters, s.true_words), Trigger.Response())
    assert (r.success, r.message) == (False, "busy")
    with pytest.raises(Unfit):
        Elements(bottle("ok ok"), 0, s.types)
    failed = s.failure(Trigger.Response(), s.reasons["timed_out"])
    assert (failed.success, failed.message) == (False, "/icub/left_arm/homing/rpc:i did not answer within 5 s")
    assert s.reasons == {k: v for k, v in texts.reasons(example("home_arm_trigger").services[0]).items()
                         if k != "bad_arguments"}


def test_setbool_request_sent_as_zero_or_one():
    ns = node_namespace(example("gaze_tracking_setbool"))
    (s,) = ns["SERVICES"]
    assert items(s.command(SetBool.Request(data=True))) == [("string", "set"), ("string", "track"), ("int32", 1)]
    assert items(s.command(SetBool.Request(data=False)))[-1] == ("int32", 0)


def module_rpc(ns, prefix):
    """A node of commands alone, its part (the inlined runtime's, whose
    classes the spec has) and the process that answers its RPC port, no
    port opened: (part, process); ``process.answer(command)`` is the reply."""
    spec = ns["SPEC"]
    part = ns["CommandsBridge"](spec, None, prefix)
    process = ns["Process"](spec.module, (ns["Member"](spec.module),), alone=True)
    process.parts[spec.module] = part
    process.rpc = types.SimpleNamespace(name=part.rpc_name, after_reply=None)
    return part, process


def test_served_port_commands_help_and_unknown():
    program = example("yarp_rpc_to_ros2")
    ns = node_namespace(program)
    spec = ns["SPEC"]
    node, process = module_rpc(ns, "/robot_gate")
    port = "/robot_gate/rpc:i"
    assert node.rpc_name == port  # the module's own RPC port is the one it serves: one port
    helped = process.answer(bottle("help"))
    assert items(helped) == [("vocab", "many")] + [("string", line) for line in texts.help_lines(program, port)]
    unknown = process.answer(bottle("jump 3"))
    assert items(unknown) == [("int32", 0), ("string", texts.unknown_command("jump"))]
    # arguments that do not fit: the failure reply, without a call
    bad = process.answer(bottle("track on"))
    (track,) = [s for s in program.services if s.name == "track"]
    assert items(bad)[0] == ("int32", 0)
    assert items(bad)[1][1].startswith("`track data:int32`: element 0 is the word on, expected int32")
    assert texts.usage(track) == "track data:int32"
    stats = process.answer(bottle("stats"))
    assert stats.toString() == ("(service home calls 0 answered 0 failed 0 timed_out 0 no_server 0 unfit 0) "
                                "(service track calls 1 answered 0 failed 1 timed_out 0 no_server 0 unfit 1)")
    # the same port among the bridges of a process: its commands, no stats or quit
    assert node._served(port, bottle("stats")).toString() == unknown.toString().replace("jump", "stats")
    # the reply of a response, and the failure reply
    track_spec = [s for s in spec.services if s.name == "track"][0]
    request = track_spec.request(Elements(bottle("track 1"), 1, track_spec.types), SetBool.Request())
    assert request.data is True
    reply = track_spec.reply(SetBool.Response(success=True, message="tracking on"))
    assert items(reply) == [("int32", 1), ("string", "tracking on")]
    assert items(track_spec.failure(SetBool.Response(), "why")) == [("int32", 0), ("string", "why")]


def test_module_rpc_port_alone():
    ns = node_namespace(example("home_arm_trigger"))
    node, process = module_rpc(ns, "/left_arm_homing")
    assert items(process.answer(bottle("help"))) == [("vocab", "many")] + [("string", t) for t in rt.COMMANDS_HELP]
    assert items(process.answer(bottle("jump"))) == [("vocab", "fail"),
                                                     ("string", texts.unknown_command("jump"))]
    assert items(process.answer(bottle("quit"))) == [("vocab", "bye")]
    assert process.quit_asked and process.rpc.after_reply == process.request_stop  # stops once `bye` is sent


def test_converter_array_list_and_literals_in_a_command():
    """send = "move", 3, 2.5, true, [request.v], deg_to_rad(request.v) of a
    float64[3] field, into a YARP port; its reply's elements into an array."""
    conv = ir.Converter("deg_to_rad", 0.5, 1.0, True)
    v = ref("v", t="float64", array="fixed", size=3)
    service = ir.Service(
        name="move", serves="ros2", service="/arm/move", srv_type="std_srvs/Trigger", port="/arm/rpc:i",
        bottle=(ir.BottleItem("literal", "move", "string"), ir.BottleItem("literal", 3, "int32"),
                ir.BottleItem("literal", 2.5, "float64"), ir.BottleItem("literal", True, "int32"),
                ir.BottleItem("list", items=(ir.BottleItem("field", ref=v),)),
                ir.BottleItem("field", ref=v, converter=conv)),
        fills=(ir.Fill(ref("success", t="bool"), "element", 0), ir.Fill(ref("message"), "element", 1)),
        failure_fills=(ir.Fill(ref("success", t="bool"), "literal", value=False),
                       ir.Fill(ref("message"), "error")))
    ns = node_namespace(ir.Commands("arm", "arm.ini", (service,)))
    (s,) = ns["SERVICES"]
    request = types.SimpleNamespace(v=[10.0, 20.0, 30.0])
    assert items(s.command(request)) == [
        ("string", "move"), ("int32", 3), ("float64", 2.5), ("int32", 1),
        [("float64", 10.0), ("float64", 20.0), ("float64", 30.0)],
        ("float64", 6.0), ("float64", 11.0), ("float64", 16.0)]
