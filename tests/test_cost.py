"""The cost guard: what one message of the benchmark's workload costs each
backend's module (and what a call costs the C++ module of commands),
counted in units that do not depend on the machine's load
(threads woken and context switches per tick; the Python modules' calls,
and of them the calls into YARP's bindings; the C++ module's system calls
and heap allocations), and held to the budgets of tests/cost_budget.json.
No timing: a driver writes a tick only once the module's message of the one
before has arrived, so that each tick is handled alone (tests/harness/cost.py).
A change that adds work to the message path fails here with the count before
(the budget's) and after; if the work is meant, the change raises the budget
and says why.

On PyPI's YARP 3.5 (the benchmark's) whatever ``--yarp`` says: the counts
depend on YARP's own work, and one release keeps one set of budgets.
A few seconds a backend (the C++ module is built first, once per run).
"""
from __future__ import annotations

import pytest

from harness import cost
from harness.env import ROOT, VENV_PYTHON
from harness.ros2 import ros2_environment

HANDOVER = ROOT / "tests" / "peers" / "handover_module.py"


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    return tmp_path_factory.mktemp("cost")


def measure(name, workdir, request, launch=None):
    subject = cost.SUBJECTS[name]
    env = None
    if subject.topic or subject.service:
        env = ros2_environment({}, request.getfixturevalue("ros2_domain"))
    return cost.measure(subject, workdir, ros2_env=env, launch=launch)


@pytest.mark.timeout(600)  # the C++ module is built first
@pytest.mark.parametrize("name", sorted(cost.SUBJECTS))
def test_a_message_costs_what_its_budget_says(name, workdir, request):
    measured = measure(name, workdir, request)
    found = cost.problems(measured, cost.load_budgets())
    assert not found, "\n".join(found) + f"\n(per tick: {measured.text()})"


def test_a_hand_over_added_to_the_message_path_is_caught(workdir, request):
    """The guard sees a change that hands each Bottle to one more thread:
    the Python module run with its runtime changed so
    (tests/peers/handover_module.py) wakes one more thread per tick, over
    the budget of the module as it is."""
    measured = measure("py", workdir, request,
                       launch=lambda argv: [VENV_PYTHON, HANDOVER, *argv[1:]])
    found = cost.problems(measured, cost.load_budgets())
    assert any("threads woken" in p for p in found), (found, measured.text())
    assert measured.per_tick["threads woken"] >= cost.load_budgets()["py"]["threads woken"]["measured"] + 0.9
