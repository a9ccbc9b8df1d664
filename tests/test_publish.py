"""`publish` at a fixed rate (docs/runtime.md, "Timing"): `new` sends a
command once per new data, not at every cycle; `always` repeats the newest
values every cycle. The default, and what `ybgc check` says of it; then both
YARP backends against a real name server, on every YARP of the matrix."""

from __future__ import annotations

import re

import pytest

from harness.generated import generate, module_proc
from harness.module import stop_within, wait_log
from harness.yarp import YarpProducer, YarpReader
from ybg.compiler.pipeline import compile_text

# on YARP 3.5 and 4.0.0: 3.12.3 is the version tests' (docs/yarp-versions.md)
pytestmark = pytest.mark.yarp_ends

ROS_TO_YARP = """\
[output]
port = /gaze/xd:i
rate = 60

[mux goal]
topics = /goal (geometry_msgs/Point)
via = ros2

[message]
xd = goal
"""


def codes(result) -> list[str]:
    return [d.code for d in result.diagnostics]


def test_ros_to_yarp_defaults_to_new_data_and_says_so():
    r = compile_text(ROS_TO_YARP, "gaze.ini")
    assert r.program.timing.publish == "new" and codes(r) == ["N602"]
    note = r.diagnostics[0]
    assert (note.span.line, "publish = always" in note.hint) == (3, True)
    explicit = compile_text(ROS_TO_YARP.replace("rate = 60\n", "rate = 60\npublish = always\n"), "gaze.ini")
    assert explicit.program.timing.publish == "always" and codes(explicit) == []


def test_other_bridges_default_to_every_cycle():
    yarp_to_yarp = "[output]\nport = /o:o\nrate = 10\n\n[mux m]\nports = /a:o\n\n[message]\nv = m\n"
    r = compile_text(yarp_to_yarp, "y.ini")
    assert r.program.timing.publish == "always" and codes(r) == []
    r = compile_text(yarp_to_yarp.replace("rate = 10\n", "rate = 10\npublish = new\n"), "y.ini")
    assert r.program.timing.publish == "new" and codes(r) == []
    # without a rate it means nothing: said, not an error
    r = compile_text(yarp_to_yarp.replace("rate = 10\n", "publish = new\n"), "y.ini")
    assert r.program is not None and codes(r) == ["W510"] and r.diagnostics[0].span.line == 3
    r = compile_text(yarp_to_yarp.replace("rate = 10\n", "rate = 10\npublish = sometimes\n"), "y.ini")
    assert r.program is None and r.errors and "always" in (r.errors[0].hint or r.errors[0].message)


COMMAND = """\
[module]
name = {name}

[output]
port = /{name}/out:o
rate = 50
publish = {publish}

[mux cmd]
ports = /pub/src:o

[message]
verb = "set"
values = cmd
"""


@pytest.mark.parametrize("backend", ["py", "cpp"])
def test_a_command_goes_out_once_per_new_data(yarp, yarp_server, tmp_path, backend):
    """At 50 Hz with `publish = new`: two Bottles in, two commands out, the
    totals say so; with `always` the same single Bottle is repeated."""
    env = yarp_server.env
    name = f"pub_new_{backend}"
    out = generate(tmp_path, COMMAND.format(name=name, publish="new"), name, backend)
    module = module_proc(env, backend, out, name)
    with module, YarpReader(env, "/test/pub:i", source=f"/{name}/out:o") as reader, \
            YarpProducer(env, "/pub/src:o") as producer:
        wait_log(module, r"connected /pub/src:o")
        reader.wait_connected(timeout=30)
        producer.write([3, 45.0])
        reader.wait_for(1, timeout=30)
        producer.write([4, 46.0])
        reader.wait_for(2, timeout=30)
        rc, _ = stop_within(module)
    log = module.log_text()
    assert rc == 0, log[-3000:]
    assert re.search(r"published 2 messages", log), log[-2000:]  # whatever the cycles in between
    assert [b.data for b in reader.bottles] == [["set", 3, 45.0], ["set", 4, 46.0]]

    name = f"pub_always_{backend}"
    out = generate(tmp_path, COMMAND.format(name=name, publish="always"), name, backend)
    module = module_proc(env, backend, out, name)
    with module, YarpReader(env, "/test/pub2:i", source=f"/{name}/out:o") as reader, \
            YarpProducer(env, "/pub/src:o") as producer:
        wait_log(module, r"connected /pub/src:o")
        reader.wait_connected(timeout=30)
        producer.write([5, 47.0])
        got = reader.wait_for(5, timeout=30)  # the same command, cycle after cycle
        rc, _ = stop_within(module)
    assert rc == 0
    assert all(b.data == ["set", 5, 47.0] for b in got[:5])
