"""Several bridges in one process (``ybgc compose``, docs/compose.md): one
YARP network, one RPC port of the process (``/<name>/rpc:i``), and every
bridge as it runs alone, with its own ports, threads (inputs, loop, watcher
of connections), rate, freshness and totals, so that one that stalls or is
fed malformed Bottles delays no other. A bridge that cannot start is said
with its config and the others run; the process then exits 1 when stopped.

The composed module (``<name>.py``, or the ``ros2`` backend's
``<name>_node.py``) lists its bridges (:class:`Member`) and how to load each
one's generated module; :func:`run_bridges` runs YARP modules (the ``py``
backend's), ``ros2_io.run_composed`` rclpy nodes, both on the process shell
(shell.Process)."""

import argparse
import importlib.util
import os
import sys

from .core import parse_options  # ybgc:runtime-import
from .shell import SWITCH_INTERVAL, Member, Process, describe, load_failure  # ybgc:runtime-import
from .yarp_io import YarpBridge  # ybgc:runtime-import

# a composed module imports Member from here, with load_file and run_bridges


def load_file(path, name):
    """The generated module of a bridge, from its file ``path``, as module ``name``."""
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None:
        raise ImportError("no module at %s" % path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(name, None)
        raise
    return module


def run_bridges(name, members, argv, load):
    """Run the YARP bridges ``members`` (each loaded by ``load(member)``, a
    module of the ``py`` backend) in this process until SIGINT, SIGTERM or
    `quit` on ``/<name>/rpc:i``; the exit status. Each runs with its
    config's options (its own port prefix, rate, timeouts)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    sys.setswitchinterval(SWITCH_INTERVAL)
    parser = argparse.ArgumentParser(
        prog=os.path.basename(sys.argv[0]) if sys.argv and sys.argv[0] else name,
        description=describe(name, members),
        epilog="Each bridge runs with its config's options. `yarp rpc /%s/rpc:i` answers help, stats and quit."
               % name,
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.parse_args(argv)
    process = Process(name, members)
    process.handle_signals()
    if not process.connect() or not process.open_rpc("/%s/rpc:i" % name):
        return 1
    for member in members:
        if process.stop_event.is_set():
            break
        try:
            module = load(member)
            spec = module.SPEC
            options = parse_options(spec, [], "/" + spec.module)
            bridge = YarpBridge(spec, options, module.make_output(), module.build_message, module.compute)
        except (Exception, SystemExit) as e:
            process.refuse(member, load_failure(member, e))
            continue
        process.start(member, bridge)
    return process.serve()
