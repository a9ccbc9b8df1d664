"""A Python runtime Bridge with no ports (ybg/runtime/core.py): the test
hands it what a port would, and reads what it logs."""
from __future__ import annotations

from ybg.runtime import core
from ybg.runtime.core import InputState


class HandInput(InputState):
    """An input with no port: the test calls the bridge as a port would."""

    def __init__(self, bridge, spec, local, timeout):
        self.init_state(bridge, spec, timeout)
        self.local = local


class HandBridge(core.Bridge):
    """A Bridge whose inputs are HandInputs and whose log lines are kept in ``logged``."""

    def make_input(self, mux, spec, local, timeout):
        return HandInput(self, spec, local, timeout)

    def log(self, text):
        self.logged.append(text)


def hand_bridge(spec, options, output, build) -> HandBridge:
    """The Bridge of ``spec`` publishing through ``output`` what ``build`` makes."""
    b = HandBridge.__new__(HandBridge)
    b.logged = []
    core.Bridge.__init__(b, spec, options, output, build, lambda v: None)
    return b
