"""An input takes Bottles only from the port its config names (docs/runtime.md,
"Reading"; docs/network.md, "A name that leads to another port").

A module's input port can receive Bottles from another port than its source:
a name server restarted without its registrations hands a late producer the
port number a running producer holds, and the source's name then leads to
that other port (tests/test_network.py reproduces it on the multi-host rig);
or a user connects a port by hand. YARP gives the name of the port that sent
each Bottle; the runtime refuses every Bottle of a port the input does not
accept: dropped, counted (`stats`, the exit totals, /diagnostics), said once
with both names, the connection closed and the source tried again. A port
the config (`accept`) or the command line (`--accept`) names is taken.

Here, without the rig: a port connected by hand with the real `yarp
connect`, on every backend and every YARP of the matrix, with the modules the
session already built (the behaviour harness's relay: one input, /t/src:o);
and the config's `accept` checked and carried into each backend's module.
"""
from __future__ import annotations

import contextlib
import re
import signal

import pytest

from harness.generated import generate
from harness.launchers import CppModules, PyModules, Ros2Modules
from harness.module import Module, assert_clean_exit
from harness.programs import relay_program
from harness.ros2 import QosSubscriber, statuses
from harness.yarp import YarpProducer, YarpReader, rpc
from ybg.backends import get_backend
from ybg.compiler.pipeline import compile_text
from ybg.runtime import core

# on YARP 3.5 and 4.0.0: 3.12.3 is the version tests' (docs/yarp-versions.md)
pytestmark = [pytest.mark.yarp_ends, pytest.mark.builds]

SRC = "/t/src:o"
OTHER = "/t/other:o"
IN = "/relay_bridge/data/in0:i"
OUT = "/relay_bridge/out:o"
RPC = "/relay_bridge/rpc:i"
#: the other port's values, none of which the source ever sends
FOREIGN = [[1000.0 + k] for k in range(10)]
#: what the module says, once, of a port it refuses
REFUSED = re.escape(f"input {SRC}: {OTHER} is connected to its port, not {SRC}")
STATS_INPUT = re.compile(r'^\s*input "?([^"\s]+)"? received (\d+) dropped (\d+) stale (\d+) unused (\d+) '
                         r'refused (\d+)$', re.M)


@pytest.fixture(params=["cpp", "py", "ros2"])
def modules(request, yarp, tmp_path):
    if request.param == "cpp":
        return CppModules(request.getfixturevalue("builds"), request)
    if request.param == "py":
        return PyModules(tmp_path)
    return Ros2Modules(tmp_path, request.getfixturevalue("ros2_domain"))


def relay(modules, env, accept=None) -> Module:
    """The relay module, not started; ``accept``: `--accept` (the ros2 node's
    parameter `accept`)."""
    if accept is None:
        return modules.module("relay_bridge", env)
    if modules.backend == "ros2":
        module = modules.module("relay_bridge", env)
        module.argv += ["--ros-args", "-p", f"accept:={accept}"]
        return module
    return modules.module("relay_bridge", env, "--accept", accept)


def refused_by_stats(server) -> int:
    """The input's `refused` in the module's `stats` answer."""
    text = rpc(server, RPC, "stats")
    got = {m[0]: int(m[5]) for m in STATS_INPUT.findall(text)}
    assert SRC in got, text
    return got[SRC]


def connect_by_hand(server) -> None:
    """`yarp connect OTHER IN`, as a user types it: it returns once the
    connection is made. The other port, writing at 100 Hz, may have its
    connection closed by the module before the test could count it, so
    nothing waits to see it open: the module's refusal is what is awaited."""
    r = server.yarp("connect", OTHER, IN)
    assert r.returncode == 0, r.stdout + r.stderr


def wait_closed(other: YarpProducer, timeout: float = 30.0) -> None:
    """The other port's connection to the module closed (by the module)."""
    other.wait(lambda: other.output_count() == 0, timeout, f"{OTHER} -> {IN} closed")


def refused_after_connecting(server, other: YarpProducer, before: int) -> int:
    """Connects the other port by hand until the module has refused more
    than ``before`` of its Bottles: the count then. The module closes the
    connection at its first Bottle or when its watcher lists it (every
    0.5 s), whichever comes first: on a busy machine the watcher may close
    it before the other port wrote on it, nothing came, and nothing is
    refused; it is connected again then, 10 times at most."""
    for _ in range(10):
        connect_by_hand(server)
        wait_closed(other)
        refused = refused_by_stats(server)
        if refused > before:
            return refused
    pytest.fail(f"{OTHER} connected by hand 10 times: no Bottle of it refused after the first {before}")


def refused_on_diagnostics(diag: QosSubscriber, at_least: int) -> None:
    """The node's /diagnostics status of the input counts ``at_least`` refused."""
    def refused(msg) -> int:
        st = [v for name, v in statuses(msg).items() if name.endswith(f": input {SRC}")]
        return int(st[0][2]["refused"]) if st else -1
    diag.wait(lambda: any(refused(m.msg) >= at_least for m in diag.messages), 30,
              f"refused {at_least} on /diagnostics")


def test_a_port_connected_by_hand_is_refused(modules, yarp_server):
    """A port connected by hand to the input's port: none of its Bottles
    comes out; they are counted (`stats`, the totals, the ros2 node's
    /diagnostics), said once with both names; the module closes the
    connection; the source, started later, is connected and relayed exactly;
    connected by hand again, the other port is refused again, counted, not
    said again, and the source flows on."""
    env = modules.environment(yarp_server.env)
    with contextlib.ExitStack() as stack:
        diag = None
        if modules.backend == "ros2":
            diag = stack.enter_context(QosSubscriber(env, "/diagnostics", "diagnostic_msgs/msg/DiagnosticArray"))
        module = stack.enter_context(relay(modules, env))
        reader = stack.enter_context(YarpReader(env, "/test/foreign:i", source=OUT))
        other = stack.enter_context(YarpProducer(env, OTHER, bottles=FOREIGN, rate=100, wait_connected=True))
        module.wait_log("publishing")
        reader.wait_connected()
        connect_by_hand(yarp_server)
        module.wait_match(REFUSED)
        wait_closed(other)
        first = refused_by_stats(yarp_server)
        if first == 0:  # closed before any of its Bottles came
            first = refused_after_connecting(yarp_server, other, 0)
        if diag is not None:
            refused_on_diagnostics(diag, first)
        src = stack.enter_context(YarpProducer(env, SRC))
        module.wait_log(f"connected {SRC} -> {IN}")
        src.wait_outputs(1)
        for k in range(3):
            src.write([float(k)])
            reader.wait_for(k + 1)
        refused_after_connecting(yarp_server, other, first)
        for k in range(3, 6):
            src.write([float(k)])
            reader.wait_for(k + 1)
        other.stop()
        refused = refused_by_stats(yarp_server)
        rc, elapsed = module.interrupt(signal.SIGINT)
    log = assert_clean_exit(yarp_server, module, rc, elapsed, [IN, OUT])
    assert [b.data for b in reader.bottles] == [[k, float(k)] for k in range(6)]
    assert len(re.findall(REFUSED, log)) == 1, log[-3000:]
    assert re.search(rf"input {re.escape(SRC)}: received 6, dropped 0, stale periods \d+, unused 0, "
                     rf"refused {refused} from {re.escape(OTHER)}\n", log), log[-3000:]
    assert module.count(re.escape(f"connected {SRC} -> {IN}")) == 1


def test_a_port_accepted_on_the_command_line_is_taken(modules, yarp_server):
    """`--accept SRC=OTHER` (the ros2 node's parameter `accept`): the other
    port, connected by hand, is relayed as the source would be; nothing is
    refused."""
    env = modules.environment(yarp_server.env)
    with contextlib.ExitStack() as stack:
        module = stack.enter_context(relay(modules, env, accept=f"{SRC}={OTHER}"))
        reader = stack.enter_context(YarpReader(env, "/test/replay:i", source=OUT))
        other = stack.enter_context(YarpProducer(env, OTHER))
        module.wait_log("publishing")
        reader.wait_connected()
        connect_by_hand(yarp_server)
        other.wait_outputs(1)
        for k in range(3):
            other.write([10.0 + k])
            reader.wait_for(k + 1)
        assert refused_by_stats(yarp_server) == 0
        assert other.output_count() == 1  # still connected
        rc, elapsed = module.interrupt(signal.SIGINT)
    log = assert_clean_exit(yarp_server, module, rc, elapsed, [IN, OUT])
    assert [b.data for b in reader.bottles] == [[k, 10.0 + k] for k in range(3)]
    assert "is connected to its port, not" not in log and "refused" not in log


# --------------------------------------------------------------------------
# the config's `accept` and the command line's `--accept` (no middleware)


ACCEPT = """\
[output]
port = /acc/out:o

[mux head]
ports = /icub/head/state:o (float64 x6)
accept = /replay/icub/head/state:o

[mux arm]
ports = /icub/torso/state:o, /icub/left_arm/state:o
accept = /icub/left_arm/state:o (/replay/left_arm:o, /other/left_arm:o)

[message]
head = [head]
arm = [arm]
"""


def _compiled(text):
    result = compile_text(text, "acc.ini")
    return result, [(d.code, d.span.line, d.span.column) for d in result.diagnostics]


def test_the_config_names_the_ports_an_input_accepts():
    """`accept = OTHER` (a mux of one port), `accept = PORT (OTHER, OTHER)`:
    in the IR, and in each backend's module spec."""
    result, diagnostics = _compiled(ACCEPT)
    assert result.ok and diagnostics == [], diagnostics
    accepts = {i.name: i.accepts for m in result.program.muxes for i in m.inputs}
    assert accepts == {"/icub/head/state:o": ("/replay/icub/head/state:o",), "/icub/torso/state:o": (),
                       "/icub/left_arm/state:o": ("/replay/left_arm:o", "/other/left_arm:o")}
    files = get_backend("py").render(result.program)
    module = next(t for n, t in files.items() if n == "acc.py")
    assert "accepts=('/replay/left_arm:o', '/other/left_arm:o')" in module
    node = next(t for n, t in get_backend("ros2").render(result.program).items() if n.endswith("acc_node.py"))
    assert "accepts=('/replay/icub/head/state:o',)" in node
    cpp = next(t for n, t in get_backend("cpp").render(result.program).items() if n == "acc.cpp")
    assert '-1, {"/replay/left_arm:o", "/other/left_arm:o"}}' in cpp
    assert '{"float64", 6}}, {}, -1, {"/replay/icub/head/state:o"}}' in cpp


@pytest.mark.parametrize("line, want", [
    ("accept = /x:o", ("E208", 6, 10)),                # two ports: which one?
    ("accept = /c:o (/x:o)", ("E208", 6, 10)),         # not a port of the mux
    ("accept = /a:o (x)", ("E401", 6, 16)),            # not a port name
    ("accept = /a:o (/x:o /y:o)", ("E208", 6, 10)),    # the ports are separated by commas
    ("accept =", ("E208", 6, 1)),
    ("accept = /a:o (/a:o)", ("W506", 6, 16)),         # the port itself
])
def test_accept_mistakes_are_caught(line, want):
    text = f"[output]\nport = /out:o\n\n[mux arm]\nports = /a:o, /b:o\n{line}\n\n[message]\na = [arm]\n"
    _, diagnostics = _compiled(text)
    assert diagnostics[:1] == [want], diagnostics


def test_accept_is_for_yarp_ports():
    text = ("[output]\nport = /out:o\n\n[mux goal]\ntopics = /goal (geometry_msgs/Point)\nvia = ros2\n"
            "accept = /x:o\n\n[message]\np = [goal]\n")
    _, diagnostics = _compiled(text)
    assert ("E208", 7, 1) in diagnostics, diagnostics


def test_the_command_line_accept():
    """`--accept PORT=OTHER`, or `OTHER` alone for a module of one YARP port
    input; a mistake is a usage error (status 2) saying what is wrong."""
    program = relay_program()
    spec = core.BridgeSpec("relay", "relay.ini", ("",), (core.MuxSpec("data", (
        core.InputSpec("data", 0, SRC, "yarp", types=None, timeout=1.0),), (), False, None),),
        ("data",), None, "all", 64, "skip", "pass")
    assert program.muxes[0].inputs[0].name == SRC
    assert core.parse_options(spec, ["--accept", OTHER], "/m").accept == {SRC: (OTHER,)}
    both = core.parse_options(spec, ["--accept", f"{SRC}={OTHER}", "--accept", "/r:o", "--accept", OTHER], "/m")
    assert both.accept == {SRC: (OTHER, "/r:o")}
    for bad in (["--accept", "/x:o=/y:o"], ["--accept", f"{SRC}=nope"], ["--accept", f"{SRC}="]):
        with pytest.raises(SystemExit) as stop:
            core.parse_options(spec, bad, "/m")
        assert stop.value.code == 2, bad


def test_a_generated_module_says_its_accept_option(tmp_path):
    """The py module's --help lists --accept."""
    import subprocess
    import sys

    out = generate(tmp_path, ACCEPT, "acc", "py")
    r = subprocess.run([sys.executable, str(out / "acc.py"), "--help"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and "--accept [PORT=]OTHER" in r.stdout, r.stdout + r.stderr
    r = subprocess.run([sys.executable, str(out / "acc.py"), "--accept", "/nope:o"], capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 2 and "say which input takes it" in r.stderr, r.stderr
