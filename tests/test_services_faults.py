"""Commands under faults (docs/services.md, "Never hang, never lie"), with
both backends (the native module and the rclpy node) on YARP 3.5: the
config tests/services/service_faults.ini (a timeout of 0.5 s both ways;
each call identifiable by its x, caller x 1000 + call) on one name server
and ROS 2 domain a backend, its peers shared by the tests of the file:

- the YARP server SIGSTOPped mid-call: the ROS 2 caller gets the failure
  answer (success false, the reason) at the timeout (not before it; after
  it, within LIMIT at the caller), also for a call made while it is stopped; once it goes on, its late reply
  is never taken for the next call's;
- the YARP server SIGKILLed: the call fails within the timeout; restarted:
  the next call succeeds;
- 8 ROS 2 callers x 100 calls at once: every call answered with its own
  reply (none crossed, none lost: the server got each command once); 4 YARP
  callers x 25 at once the other way;
- the ROS 2 server gone (the module serving the YARP port): the YARP caller
  gets the failure reply within the timeout; the server back is used again;
- the exit totals (and `stats`) count the failures by kind.
"""
from __future__ import annotations

import collections
import os
import re
import signal
import time

import pytest

from harness.env import DEFAULT_YARP
from harness.module import stop_clean
from harness.ros2 import Ros2Domain
from harness.services import (RpcClient, RpcServer, ServiceClient, ServiceServer, Rig, compiled, counts, echo,
                              native, node, reply, require_services, service_builds, service_stats,
                              service_totals)
from harness.yarp import YarpServer
from ybg.lower import services as texts

#: the cpp modules come from the session's build (request.getfixturevalue)
pytestmark = pytest.mark.builds

KEY = "service_faults"
LOOK_AT = "ybg_demo_msgs/srv/LookAt"
ROS_SERVED = "/faults/look_at"          # served by the module, calls the YARP port
GAZE = "/faults/gaze/rpc:i"             # the YARP RPC server it calls
YARP_SERVED = "/faults/rpc:i"           # served by the module, calls the ROS 2 service
ROS_CALLED = "/faults/ros/look_at"
TIMEOUT = 0.5
#: a failure answer comes within the call's timeout (the module's own deadline,
#: docs/services.md), timed here at the caller: the rest is the transport and
#: the processes' scheduling, which a loaded machine stretches. A module that
#: let a call wait past its deadline for good would still fail; this bound is
#: its hang detector, not a figure (bench/ has the figures)
LIMIT = TIMEOUT + 1.0
ECHO = re.compile(r'^ok look "?3D"? \((\S+) (\S+) (\S+)\) (\S+)$')


def request(caller: int, k: int) -> dict:
    return {"x": float(caller * 1000 + k), "y": float(caller), "z": float(k), "timeout": TIMEOUT}


def echoed(message: str) -> tuple:
    """(x, y, z, timeout) of the echo of a `look 3D (x y z) t` command."""
    m = ECHO.match(message)
    assert m, f"not the echo of a look command: {message!r}"
    return tuple(float(v) for v in m.groups())


class FaultRig:
    """A backend's module of service_faults.ini with its peers: the YARP RPC
    server it calls (echoing each command after `ok`), the rclpy server it
    calls (saying the x, y, z it got), 8 rclpy callers and 4 YARP callers."""

    def __init__(self, backend: str, request, tmp_path):
        self.backend = backend
        self.server = YarpServer(install=DEFAULT_YARP).start()
        self.domain = Ros2Domain().start()
        self.rig = Rig(self.server, self.domain)
        env = self.rig.env
        self.program = compiled(KEY, backend)
        self.reasons = {s.name: texts.reasons(s) for s in self.program.services}
        self.gaze = RpcServer(env, GAZE, [echo()])
        self.ros = ServiceServer(env, {ROS_CALLED: {"type": LOOK_AT, "response": {
            "success": True, "message": "x {x} y {y} z {z}"}}})
        # callers of the module's service; and of the one it calls, to see it come and go
        self.caller = ServiceClient(env, {ROS_SERVED: LOOK_AT, ROS_CALLED: LOOK_AT}, callers=8)
        self.yarp_caller = RpcClient(env, YARP_SERVED, clients=4)
        if backend == "cpp":
            builds = request.getfixturevalue("builds")
            builds.build()
            self.module = native(builds, KEY, env)
        else:
            self.module = node(self.program, tmp_path, env)
        self.rig.start(self.module, self.gaze, self.ros, self.caller, self.yarp_caller)
        self.fresh = True  # started: ready() before a test uses it

    def ready(self) -> None:
        """The module serves its ROS 2 service and YARP port, and sees the
        ROS 2 server it calls (a call until one is answered: until the
        module has discovered the server, it answers that there is none, or,
        seeing it before its responses reach the module, that it did not
        answer)."""
        self.caller.wait_service(ROS_SERVED, timeout=60)
        self.caller.wait_service(ROS_CALLED, timeout=60)
        self.yarp_caller.connect()
        end = time.monotonic() + 30
        while True:
            r = self.yarp_caller.call(["look", 0.0, 0.0, 0.0, TIMEOUT])
            if r.data[0] == 1:
                return
            assert r.data in ([0, self.reasons["look"]["no_server"]], [0, self.reasons["look"]["timed_out"]]), r
            assert time.monotonic() < end, "the module does not see the ROS 2 server within 30 s"

    def ros_gone(self) -> None:
        """The ROS 2 server the module calls ends as a server ends (its node
        destroyed), and is seen gone."""
        self.ros.quit()
        self.caller.wait_no_service(ROS_CALLED)

    def call_once_gone(self, args: list) -> tuple:
        """The module's answer to a call of ``look`` made once it sees the
        ROS 2 server gone (after ``ros_gone``), and how many calls before it
        were answered at their timeout: the module sees the server gone when
        its own participant's discovery does, which may be after the test's
        client sees it, and until then a call goes to the server that is no
        more. Each answer within the bound."""
        reasons = self.reasons["look"]
        late = 0
        end = time.monotonic() + 30
        while True:
            r = self.yarp_caller.call(args)
            assert r.seconds <= LIMIT, f"answered after {r.seconds:.3f} s"
            if r.data == [0, reasons["no_server"]] or time.monotonic() > end:
                return r, late
            assert r.data == [0, reasons["timed_out"]], r
            late += 1

    def ros_back(self) -> None:
        self.ros.start()
        self.caller.wait_service(ROS_CALLED)

    def call(self, caller: int, k: int, timeout: float = 10.0):
        return self.caller.call(ROS_SERVED, request(caller, k), timeout=timeout)

    def close(self) -> None:
        for p in (self.gaze, self.ros):
            if p.pid and p.alive:
                os.kill(p.pid, signal.SIGCONT)
        self.rig.close()
        self.server.stop()
        self.domain.stop()


@pytest.fixture(scope="module")
def builds(tmp_path_factory):
    return service_builds(tmp_path_factory, DEFAULT_YARP)


@pytest.fixture(scope="module", params=("cpp", "ros2"))
def faults(request, tmp_path_factory):
    require_services()
    r = FaultRig(request.param, request, tmp_path_factory.mktemp(f"faults_{request.param}"))
    yield r
    r.close()


@pytest.fixture(autouse=True)
def _ready(request):
    """The module (started anew) ready before a test; its log shown when the test fails."""
    if "faults" not in request.fixturenames:
        yield
        return
    rig = request.getfixturevalue("faults")
    if rig.fresh:
        rig.ready()
        rig.fresh = False
    yield
    print(f"---- log of {rig.module.name}:\n{rig.module.log_text()[-4000:]}")


def assert_failure(r, reason: str) -> None:
    """A failure answer: within LIMIT of the call (not before the timeout,
    for a timeout), success false and the reason."""
    assert r.response == {"success": False, "message": reason}, r
    assert r.seconds <= LIMIT, f"answered {r.seconds:.3f} s after the call (limit {LIMIT:.3f} s)"


@pytest.mark.timeout(900)  # the build may fall to this test
def test_yarp_server_stopped_mid_call(faults):
    timed_out = faults.reasons["look_at"]["timed_out"]
    assert timed_out == "/faults/gaze/rpc:i did not answer within 0.5 s"
    faults.gaze.set_rules([echo(delay=0.2)])  # a call is held by the server when it stops
    seen = len(faults.gaze.commands)
    ident = faults.caller.start_call(ROS_SERVED, request(1, 0), timeout=5)
    faults.gaze.wait_commands(seen + 1)
    os.kill(faults.gaze.pid, signal.SIGSTOP)
    try:
        first = faults.caller.result(ident)
        assert_failure(first, timed_out)
        assert first.seconds >= TIMEOUT, f"a timeout said after {first.seconds:.3f} s"
        # a call made while it is stopped: the same
        assert_failure(faults.call(1, 1), timed_out)
    finally:
        os.kill(faults.gaze.pid, signal.SIGCONT)
    faults.gaze.set_rules([echo()])
    # its late replies went to connections the module closed: the next call
    # gets its own
    r = faults.call(1, 2)
    assert r.response["success"] is True, r
    assert echoed(r.response["message"]) == (1002.0, 1.0, 2.0, TIMEOUT)


def test_yarp_server_killed_and_restarted(faults):
    r = faults.call(2, 0)
    assert r.response["success"] is True and echoed(r.response["message"])[0] == 2000.0, r
    faults.gaze.kill()
    gone = faults.call(2, 1)
    reasons = faults.reasons["look_at"]
    assert gone.response["message"] in (reasons["no_server"], reasons["timed_out"]), gone
    assert_failure(gone, gone.response["message"])
    faults.gaze.start()
    r = faults.call(2, 2)
    assert r.response["success"] is True, r
    assert echoed(r.response["message"]) == (2002.0, 2.0, 2.0, TIMEOUT)


def test_concurrent_ros2_callers_each_get_their_own_reply(faults):
    # callers 10 to 17: x values no other test sends, so that the server's
    # events of an earlier test's last calls, which may come after their
    # responses, are not taken for these
    callers = range(10, 18)
    requests = [[request(i, k) for k in range(100)] for i in callers]
    got = faults.caller.batch(ROS_SERVED, requests, timeout=5)
    for i, mine in zip(callers, got):
        for k, r in enumerate(mine):
            assert r is not None and not r.timed_out, (i, k, r)
            assert r.response["success"] is True, (i, k, r)
            assert echoed(r.response["message"]) == (i * 1000.0 + k, float(i), float(k), TIMEOUT), (i, k, r)
    # the server's events of the last calls may come after the responses
    want = collections.Counter(i * 1000.0 + k for i in callers for k in range(100))
    def received() -> collections.Counter:
        return collections.Counter(x for x in (c["data"][2][0] for c in faults.gaze.commands) if x in want)
    try:
        faults.gaze.wait(lambda: sum(received().values()) >= len(want), 30, "the commands of 8 callers")
    except TimeoutError:
        pass  # said below: which were lost
    seen = received()
    lost, twice = sorted(want - seen), sorted(x for x, n in seen.items() if n > 1)
    assert not lost and not twice, f"commands lost: {lost[:10]}; sent more than once: {twice[:10]}"


def test_concurrent_yarp_callers_each_get_their_own_reply(faults):
    calls = [[["look", i * 1000.0 + k, float(i), float(k), TIMEOUT] for k in range(25)] for i in range(4)]
    got = faults.yarp_caller.batch(calls)
    for i, mine in enumerate(got):
        for k, r in enumerate(mine):
            x = i * 1000.0 + k
            assert r is not None and r.ok, (i, k, r)
            assert (r.data, r.types) == ([1, f"x {x} y {float(i)} z {float(k)}"], ["int32", "string"]), (i, k, r)


def test_ros2_server_gone_and_back(faults):
    r = faults.yarp_caller.call(["look", 1.0, 2.0, 3.0, TIMEOUT])
    assert r.data == [1, "x 1.0 y 2.0 z 3.0"], r
    faults.ros_gone()
    r, _ = faults.call_once_gone(["look", 4.0, 5.0, 6.0, TIMEOUT])
    reasons = faults.reasons["look"]
    assert r.data == [0, reasons["no_server"]] == [0, "/faults/ros/look_at: no server"], r
    faults.ros_back()
    # once the module sees it again, it is used again (no restart); until
    # then a failure answer within the timeout: no server, or no answer
    # (discovery is not symmetric in time: a client may see the server
    # before the server's responses reach it)
    end = time.monotonic() + 30
    while True:
        r = faults.yarp_caller.call(["look", 7.0, 8.0, 9.0, TIMEOUT])
        if r.data[0] == 1 or time.monotonic() > end:
            break
        assert r.data in ([0, reasons["no_server"]], [0, reasons["timed_out"]]), r
        assert r.seconds <= LIMIT, f"answered after {r.seconds:.3f} s"
        time.sleep(0.1)
    assert r.data == [1, "x 7.0 y 8.0 z 9.0"], f"the server back was not used again within 30 s: {r}"


def test_totals_count_failures_by_kind(faults):
    """Failures of each kind both ways: `stats` and the exit totals count
    them (from what they said before this test)."""
    port = "/service_faults/rpc:i"
    before = service_stats(faults.server, port)
    reasons = faults.reasons
    # ROS 2 -> YARP: answered; a reply that lacks reply[0]; no answer; no server
    assert faults.call(3, 0).response["success"] is True
    faults.gaze.set_rules([reply("")])
    unfit = faults.call(3, 1)
    assert unfit.response["success"] is False
    assert unfit.response["message"].startswith(f"{GAZE} replied "), unfit
    faults.gaze.set_rules([echo(delay=TIMEOUT + 0.3)])
    assert_failure(faults.call(3, 2), reasons["look_at"]["timed_out"])
    faults.gaze.quit()
    assert_failure(faults.call(3, 3), reasons["look_at"]["no_server"])
    faults.gaze.start()
    faults.gaze.set_rules([echo()])
    # YARP -> ROS 2: answered; arguments that do not fit; no answer; no server
    assert faults.yarp_caller.call(["look", 1.0, 2.0, 3.0, TIMEOUT]).data[0] == 1
    bad = faults.yarp_caller.call(["look", "a", "b", "c", "d"])
    assert bad.data[0] == 0 and bad.data[1].startswith(
        "`look x:float64 y:float64 z:float64 timeout:float64`: "), bad
    faults.ros.respond(ROS_CALLED, delay=TIMEOUT + 0.3)
    late = faults.yarp_caller.call(["look", 1.0, 2.0, 3.0, TIMEOUT])
    assert late.data == [0, reasons["look"]["timed_out"]] and late.seconds <= LIMIT, late
    faults.ros.respond(ROS_CALLED, delay=0)
    faults.ros_gone()
    gone, late = faults.call_once_gone(["look", 1.0, 2.0, 3.0, TIMEOUT])
    assert gone.data == [0, reasons["look"]["no_server"]], gone
    faults.ros_back()

    each = counts(calls=4, answered=1, unfit=1, timed_out=1, no_server=1)
    # the calls the module answered at their timeout before it saw the server gone, counted as such
    extra = {"look_at": counts(), "look": counts(calls=late, timed_out=late)}
    want = {k: {key: before[k][key] + each[key] + extra[k][key] for key in each} for k in ("look_at", "look")}
    stats = service_stats(faults.server, port)
    assert {k: stats.get(k) for k in want} == want, stats["text"]
    log = stop_clean(faults.module)
    assert service_totals(log.split("==== start")[-1]) == want
    faults.module.start()  # for a test after this one (_ready waits for it)
    faults.fresh = True
