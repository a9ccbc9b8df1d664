"""An undeclared port's values go on as they came (docs/runtime.md, "Value
types on the wire"): a command such as `set pos 3 45.0`, read from a port
whose layout the config does not declare and written into an untyped Bottle,
keeps its integer (the original tool passed YARP values through; a module
that made it `set pos 3.0 45.0` would send a control board a wrong command).
Both YARP backends, on every YARP of the matrix, with a real name server."""

from __future__ import annotations

import pytest

from harness.generated import generate, module_proc
from harness.module import EXIT_BOUND, stop_within, wait_log
from harness.yarp import YarpProducer, YarpReader

# on YARP 3.5 and 4.0.0: 3.12.3 is the version tests' (docs/yarp-versions.md)
pytestmark = pytest.mark.yarp_ends

COMMAND = """\
[module]
name = {name}

[output]
port = /{name}/out:o

[mux cmd]
ports = /pt/src:o

[message]
verb = "set"
what = "pos"
values = cmd
"""


@pytest.mark.parametrize("backend", ["py", "cpp"])
def test_undeclared_integers_stay_integers(yarp, yarp_server, tmp_path, backend):
    env = yarp_server.env
    name = f"pass_{backend}"
    out = generate(tmp_path, COMMAND.format(name=name), name, backend)
    module = module_proc(env, backend, out, name)
    with module, YarpReader(env, "/test/pass:i", source=f"/{name}/out:o") as reader, \
            YarpProducer(env, "/pt/src:o") as producer:
        wait_log(module, r"connected /pt/src:o")
        reader.wait_connected(timeout=30)
        producer.write([3, 45.0])
        producer.write([{"int64": 2**40}, -7, 0.5])
        got = reader.wait_for(2, timeout=30)
        rc, took = stop_within(module)
    assert [b.data for b in got] == [["set", "pos", 3, 45.0], ["set", "pos", 2**40, -7, 0.5]]
    assert got[0].types == ["string", "string", "int32", "float64"]
    assert got[1].types == ["string", "string", "int64", "int32", "float64"]
    assert rc == 0 and took < EXIT_BOUND, module.log_text()[-3000:]
