"""A generated Python module run with one more thread hand-over on its
message path, for the cost guard's own test (tests/test_cost.py): each
Bottle an input takes is handed to a thread of the bridge's before the
bridge gets it, as a change that queued work for another thread would.

    python handover_module.py MODULE.py [the module's arguments]
"""
import os
import queue
import runpy
import sys
import threading

module = os.path.abspath(sys.argv[1])
sys.argv = sys.argv[1:]
sys.path.insert(0, os.path.dirname(module))

from ybgc_runtime import core  # noqa: E402  (the module's own runtime, beside it)

taken = core.Bridge.on_bottle
handed = queue.SimpleQueue()


def hand_over():
    while True:
        bridge, args = handed.get()
        taken(bridge, *args)


threading.Thread(target=hand_over, name="hand-over", daemon=True).start()
core.Bridge.on_bottle = lambda bridge, *args: handed.put((bridge, args))
runpy.run_path(module, run_name="__main__")
