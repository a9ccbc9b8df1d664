"""A nested message filled from a port that declares no elements takes as
many values as it has fields; what a Bottle brings beyond them is dropped.
The cut is said at check time (W511, with the width assumed) and, by the
module, at the first Bottle wider than what the message reads (once).
pf3dTracker's `data:o` sends 7 values (x y z, likelihood, u v, seeing) and
the thesis' `ball_point_bridge.ini` fills a `geometry_msgs/Point` from it."""

from __future__ import annotations

import re

import pytest

from harness.env import LEGACY_DIR
from harness.generated import generate, module_proc
from harness.module import EXIT_BOUND, stop_within, wait_log
from harness.yarp import YarpProducer, YarpReader
from ybg.compiler.pipeline import compile_path, compile_text

# on YARP 3.5 and 4.0.0: 3.12.3 is the version tests' (docs/yarp-versions.md)
pytestmark = pytest.mark.yarp_ends

BALL = """\
[module]
name = {name}

[output]
port = /{name}/point:o
type = geometry_msgs/PointStamped

[mux ball]
ports = {ports}

[message]
header.frame_id = "l_camera_vision_link"
point = {point}
"""


def cut(text: str):
    r = compile_text(text, "ball.ini")
    return r, [d for d in r.diagnostics if d.code == "W511"]


def reads(program, mux: str = "ball"):
    m, = [m for m in program.muxes if m.name == mux]
    return [i.reads for i in m.inputs]


def test_the_thesis_ball_point_bridge_is_told_of_its_cut():
    r = compile_path(LEGACY_DIR / "ball_point_bridge.ini")
    w, = [d for d in r.diagnostics if d.code == "W511"]
    assert (w.span.line, w.span.column) == (20, 9)  # 2_mux = mux1
    assert "geometry_msgs/Point of 3 numbers (x, y, z)" in w.message
    assert "values 0 to 2 of mux `mux1`" in w.message and "`/pf3dTracker/data:o`" in w.message
    assert "point = mux1[0:3]" in w.hint and "/pf3dTracker/data:o (float64 x<N>)" in w.hint
    assert r.program is not None and reads(r.program, "mux1") == [3]


def test_a_range_says_the_cut_is_meant():
    r, w = cut(BALL.format(name="b", ports="/pf3dTracker/data:o", point="ball[0:3]"))
    assert r.program is not None and w == [] and reads(r.program) == [None]


def test_a_declared_port_of_another_width_is_an_error_not_a_cut():
    r, w = cut(BALL.format(name="b", ports="/pf3dTracker/data:o (float64 x7)", point="ball"))
    assert w == [] and [d.code for d in r.diagnostics] == ["E309"]


def test_the_values_read_start_after_the_declared_ports():
    r, w = cut(BALL.format(name="b", ports="/a:o (float64 x2), /pf3dTracker/data:o", point="ball"))
    assert len(w) == 1 and reads(r.program) == [None, 1]
    r, w = cut(BALL.format(name="b", ports="/a:o (float64 x2), /pf3dTracker/data:o", point="ball[1:]"))
    assert len(w) == 1 and "values 1 to 3" in w[0].message and reads(r.program) == [None, 2]


def test_a_use_of_the_whole_mux_leaves_nothing_to_say_at_run_time():
    text = """\
[output]
port = /imu:o
type = sensor_msgs/Imu
[mux m]
ports = /imu/data:o
[message]
linear_acceleration = m
linear_acceleration_covariance = m
"""
    r, w = cut(text)
    assert len(w) == 1 and (w[0].span.line, w[0].span.column) == (7, 23)
    assert reads(r.program, "m") == [None]  # the covariance reads all of it


def test_the_values_read_inside_an_array_of_messages_count():
    text = """\
[output]
port = /markers:o
type = visualization_msgs/MarkerArray
[mux ball]
ports = /pf3dTracker/data:o
[message]
markers[0].pose.position = ball
"""
    r, w = cut(text)
    assert len(w) == 1 and r.program is not None and reads(r.program) == [3]


@pytest.mark.parametrize("backend", ["py", "cpp"])
def test_the_module_says_the_first_wider_bottle_once(yarp, yarp_server, tmp_path, backend):
    env = yarp_server.env
    name = f"cut_{backend}"
    out = generate(tmp_path, BALL.format(name=name, ports="/cut/data:o", point="ball"), name, backend)
    module = module_proc(env, backend, out, name)
    with module, YarpReader(env, "/test/cut:i", source=f"/{name}/point:o") as reader, \
            YarpProducer(env, "/cut/data:o") as producer:
        wait_log(module, r"connected /cut/data:o")
        reader.wait_connected(timeout=30)
        producer.write([0.1, 0.2, 0.3])  # exactly what the Point takes
        got = reader.wait_for(1, timeout=30)
        assert "values, of which the message reads" not in module.log_text()
        for k in range(3):  # x y z, likelihood, u v, seeing
            producer.write([1.0 + k, 2.0, 3.0, 0.9, 320.0, 240.0, 1.0])
        got = reader.wait_for(4, timeout=30)
        rc, took = stop_within(module)
    assert [b.data[-1] for b in got] == [[0.1, 0.2, 0.3], [1.0, 2.0, 3.0], [2.0, 2.0, 3.0], [3.0, 2.0, 3.0]]
    said = re.findall(r".*values, of which the message reads.*", module.log_text())
    assert said == [f"{name}: input /cut/data:o: a Bottle of 7 values, of which the message reads the first 3; "
                    "the other 4 are dropped (declare the port's elements in the config to check its width); "
                    "said once"], module.log_text()[-3000:]
    assert rc == 0 and took < EXIT_BOUND, module.log_text()[-3000:]
