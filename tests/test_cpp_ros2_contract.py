"""The runtime contract (docs/runtime.md) of a C++ module that publishes to
ROS 2 through rcl, with real peers: a YARP producer that stops (SIGSTOP, as a
crashed or overloaded robot part would) makes its input stale and nothing is
published until it returns; a ROS 2 subscriber that stops reading does not
hold the module up; a signal ends it with 0 within 2 s and its totals. The
module is the native one of `--backend cpp`; the same contract for YARP
outputs is the behaviour harness's (tests/harness/behaviour.py), for every backend.

Built against the newest YARP of the matrix: what differs between YARP
releases (reading Bottles) is covered on each of them by the harness.

And the other way to build it: the generated CMakeLists finds ROS 2 with
find_package, as in a sourced ROS 2 install. There is no such install here;
the wheels' ament CMake configs stand in for it, with what the wheels need
beyond an install given from outside (scripts/msgpkg_wheels.cmake, linker
flags for their bundled libraries and libpython), so that what is tested is
the CMakeLists' own find_package path."""

from __future__ import annotations

import collections
import glob
import os
import signal
import subprocess
import sysconfig
import time

import pytest

from harness.build import find_once_option
from harness.env import ROOT, VENV
from harness.generated import generate
from harness.module import EXIT_BOUND, Module, totals
from harness.ros2 import QosSubscriber, ros2_environment
from harness.yarp import YarpProducer

CONFIG = """\
[module]
name = contract_native

[output]
topic = /contract/joints
type = sensor_msgs/JointState
via = ros2
rate = 50
timeout = 0.5
depth = 100

[mux q]
ports = /contract/a:o (float64 x2), /contract/b:o (float64 x1)

[message]
header.stamp = timestamp
name = "a0", "a1", "b0"
position = q
"""

TIMEOUT = 0.5


@pytest.fixture(scope="module")
def native(yarp, tmp_path_factory):
    """The module of CONFIG, generated and built against ``yarp`` and the ROS 2 wheels."""
    tmp = tmp_path_factory.mktemp("contract_native")
    src = generate(tmp, CONFIG, "contract_native", "cpp")
    build = tmp / "build"
    for argv in (["cmake", "-S", str(src), "-B", str(build), f"-DCMAKE_PREFIX_PATH={yarp.cmake_prefix_path()}",
                  find_once_option(), f"-DYBGC_ROS2_PYTHON_ENV={VENV}"],
                 ["cmake", "--build", str(build), "-j2"]):
        r = subprocess.run(argv, capture_output=True, text=True, timeout=900)
        assert r.returncode == 0, (r.stdout + r.stderr)[-4000:]
    return build / "contract_native"


@pytest.fixture(scope="module")
def native_ament(yarp, tmp_path_factory):
    """The module of CONFIG built through its CMakeLists' find_package path
    (no -DYBGC_ROS2_PYTHON_ENV): rcl and the message packages found by their
    ament CMake configs, as in a sourced ROS 2 install."""
    tmp = tmp_path_factory.mktemp("contract_ament")
    src = generate(tmp, CONFIG, "contract_native", "cpp")
    build = tmp / "build"
    # the wheels' quirks, which a ROS 2 install has not: their bundled libraries, and libpython
    bundled = sorted(glob.glob(str(VENV / "lib" / "python3*" / "site-packages" / "ros_*.libs")))
    flags = [f"-Wl,-rpath-link,{d} -Wl,-rpath,{d}" for d in [str(VENV / "lib"), *bundled]]
    flags += ["-Wl,--disable-new-dtags -Wl,--no-as-needed",
              f"-L{sysconfig.get_config_var('LIBDIR')} -lpython{sysconfig.get_python_version()}"]
    env = dict(os.environ, AMENT_PREFIX_PATH=str(VENV))
    for argv in (["cmake", "-S", str(src), "-B", str(build),
                  f"-DCMAKE_PREFIX_PATH={yarp.cmake_prefix_path()};{VENV}", find_once_option(),
                  f"-DPython3_EXECUTABLE={VENV / 'bin' / 'python'}",
                  f"-DCMAKE_PROJECT_INCLUDE={ROOT / 'scripts' / 'msgpkg_wheels.cmake'}",
                  f"-DCMAKE_EXE_LINKER_FLAGS={' '.join(flags)}"],
                 ["cmake", "--build", str(build), "-j2"]):
        r = subprocess.run(argv, capture_output=True, text=True, timeout=900, env=env)
        assert r.returncode == 0, (r.stdout + r.stderr)[-4000:]
    cache = (build / "CMakeCache.txt").read_text()
    assert "YBGC_ROS2_PYTHON_ENV:PATH=\n" in cache  # the find_package branch, not the wheels' one
    assert f"rcl_DIR:PATH={VENV}/share/rcl/cmake" in cache
    return build / "contract_native"


def stamp(m) -> float:
    s = m.msg["header"]["stamp"]
    return s["sec"] + s["nanosec"] * 1e-9


@pytest.mark.yarp_min((4, 0))
def test_a_stopped_producer_makes_its_input_stale_and_nothing_is_published(native, yarp_server, ros2_domain):
    """At 50 Hz with on_stale = skip: the producer of /contract/b:o is
    SIGSTOPped; once its input is stale (0.5 s after its last Bottle) no
    message is published, said once; SIGCONT, and messages come again with
    its new values. Told by the messages themselves: each carries b's value
    (one a Bottle), so a value goes out in the cycles while it is the newest
    and fresh, TIMEOUT after it came at most, never in the stale stretch (a
    second more of cycles); and the node's clock at each publish (a stamp)
    says messages came after SIGCONT."""
    env = ros2_environment(yarp_server.env, ros2_domain)
    sub = QosSubscriber(env, "/contract/joints", "sensor_msgs/msg/JointState")
    module = Module([native], env=env, name="contract_native")
    a = YarpProducer(env, "/contract/a:o", bottles=[[1.0, 2.0]], rate=50)
    b = YarpProducer(env, "/contract/b:o", bottles=[[float(k)] for k in range(1, 3000)], rate=50)
    procs = [sub, module, a, b]
    try:
        for p in procs:
            p.start()
        module.wait_log("50 Hz")
        sub.wait_publishers(1)
        sub.wait_for(10)
        os.kill(b.pid, signal.SIGSTOP)
        module.wait_log("input /contract/b:o is stale", timeout=60)
        time.sleep(1.0)  # a stretch of stale input; the assertions are on the messages, not on this time
        resumed_at = time.time()
        held = len(sub.messages)
        os.kill(b.pid, signal.SIGCONT)
        sub.wait_for(held + 10)
        rc, elapsed = module.interrupt(signal.SIGINT)
    finally:
        if b.pid is not None:
            os.kill(b.pid, signal.SIGCONT)  # stopped or not: a stopped process takes no SIGTERM
        for p in reversed(procs):
            p.stop()
    log = module.log_text()
    assert rc == 0 and elapsed < EXIT_BOUND, log[-2000:]
    assert "Traceback" not in log
    stamps = [stamp(m) for m in sub.messages]
    assert any(t > resumed_at for t in stamps), "nothing published after the producer returned"
    assert log.count("input /contract/b:o is stale") == 1, log[-2000:]  # said once
    # every message has both inputs' values; b's are increasing: nothing stale went out again
    bs = [m.msg["position"][2] for m in sub.messages]
    assert all(m.msg["position"][:2] == [1.0, 2.0] for m in sub.messages)
    assert bs == sorted(bs)
    # the input is fresh until TIMEOUT after its last Bottle (the module's clock): its value
    # goes out in at most the cycles of that time (and the one that finds it stale), never
    # in the stale stretch's (a second of them: 50 more); cycles are only ever skipped
    value, most = collections.Counter(bs).most_common(1)[0]
    assert most <= TIMEOUT * 50 + 2, f"b's value {value} in {most} messages: published while stale"
    t = totals(log)
    assert t["/contract/b:o"][2] == 1, log[-1500:]  # one stale period
    assert t["published"] >= len(sub.messages)


@pytest.mark.yarp_min((4, 0))
def test_a_stalled_subscriber_does_not_hold_the_module_up(native, yarp_server, ros2_domain):
    """Two rclpy subscribers, one SIGSTOPped (reliable, as the config asks):
    the other keeps receiving every cycle's message, and SIGTERM ends the
    module with 0 within 2 s while the stalled one still holds its data."""
    env = ros2_environment(yarp_server.env, ros2_domain)
    stalled = QosSubscriber(env, "/contract/joints", "sensor_msgs/msg/JointState")
    live = QosSubscriber(env, "/contract/joints", "sensor_msgs/msg/JointState")
    module = Module([native], env=env, name="contract_native")
    a = YarpProducer(env, "/contract/a:o", bottles=[[1.0, 2.0]], rate=50)
    b = YarpProducer(env, "/contract/b:o", bottles=[[float(k)] for k in range(1, 3000)], rate=50)
    procs = [stalled, live, module, a, b]
    try:
        for p in procs:
            p.start()
        module.wait_log("50 Hz")
        stalled.wait_publishers(1)
        live.wait_publishers(1)
        stalled.wait_for(5)
        os.kill(stalled.pid, signal.SIGSTOP)
        try:
            n = len(live.messages)
            got = live.wait_for(n + 100, timeout=120)  # two seconds of cycles, however long they take here
            rc, elapsed = module.interrupt(signal.SIGTERM)
        finally:
            os.kill(stalled.pid, signal.SIGCONT)
    finally:
        for p in reversed(procs):
            p.stop()
    log = module.log_text()
    assert rc == 0 and elapsed < EXIT_BOUND, log[-2000:]
    assert "Traceback" not in log
    bs = [m.msg["position"][2] for m in got]
    assert bs == sorted(bs) and len(set(bs)) > 50  # new values kept coming
    assert totals(log)["published"] >= len(got)


@pytest.mark.yarp_min((4, 0))
def test_built_through_find_package_it_publishes_the_message(native_ament, yarp_server, ros2_domain):
    """The module built by find_package (above) publishes what the producers
    write: names, positions in input order, a stamp."""
    env = ros2_environment(yarp_server.env, ros2_domain)
    sub = QosSubscriber(env, "/contract/joints", "sensor_msgs/msg/JointState")
    module = Module([native_ament], env=env, name="contract_ament")
    a = YarpProducer(env, "/contract/a:o", bottles=[[0.25, -1.5]], rate=50)
    b = YarpProducer(env, "/contract/b:o", bottles=[[7.0]], rate=50)
    procs = [sub, module, a, b]
    try:
        for p in procs:
            p.start()
        module.wait_log("50 Hz")
        got = sub.wait_for(5)
        rc, elapsed = module.interrupt(signal.SIGINT)
    finally:
        for p in reversed(procs):
            p.stop()
    assert rc == 0 and elapsed < EXIT_BOUND, module.log_text()[-2000:]
    for m in got:
        assert m.msg["name"] == ["a0", "a1", "b0"] and m.msg["position"] == [0.25, -1.5, 7.0]
        assert stamp(m) > 1.7e9
