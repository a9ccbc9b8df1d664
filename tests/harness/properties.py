"""Hypothesis' profiles for the property tests.

    ci      the default: derandomized (each test draws the examples it drew
            on every run before, from a seed of its own source, whatever
            modules the tests before it loaded), no example
            database, no deadline and no health check on time (wall-clock
            limits that a busy machine trips). A run fails only on a bug,
            and fails again on the same example.
    fuzz    ``YBG_HYPOTHESIS_PROFILE=fuzz`` (scripts/fuzz.sh): random, and
            FUZZ_FACTOR times the examples, for a run outside CI. What it
            finds is kept in .hypothesis/ and printed with its
            ``@reproduce_failure`` blob; the example then goes into an
            explicit ``@example(...)`` of the test, which the ci profile runs
            every time.

A test that sets its own ``@settings`` inherits the loaded profile (a
``settings`` object takes what it does not set from the profile loaded when
it is made: tests/conftest.py loads it before any test module is imported),
and gives its budget as ``max_examples=examples(n)``. conftest refuses, at
collection, a property test that runs under the ci profile without
derandomize or with a database.
"""
from __future__ import annotations

import os

from hypothesis import HealthCheck, settings

#: the environment variable that chooses the profile
PROFILE_VARIABLE = "YBG_HYPOTHESIS_PROFILE"
#: how many times the ci profile's examples the fuzz profile draws
FUZZ_FACTOR = 20
#: the health checks that measure time
TIMED_CHECKS = (HealthCheck.too_slow,)

settings.register_profile("ci", derandomize=True, database=None, deadline=None,
                          suppress_health_check=TIMED_CHECKS, print_blob=True)
settings.register_profile("fuzz", derandomize=False, max_examples=100 * FUZZ_FACTOR, deadline=None,
                          suppress_health_check=TIMED_CHECKS, print_blob=True)


def load() -> str:
    """Load the profile ``YBG_HYPOTHESIS_PROFILE`` names, default ci
    (tests/conftest.py, before any test module; hypothesis'
    ``--hypothesis-profile`` option, when given, wins). In the ci profile,
    without the modules' constants (``without_local_constants``)."""
    name = os.environ.get(PROFILE_VARIABLE, "ci")
    settings.load_profile(name)
    if name == "ci":
        without_local_constants()
    return name


def without_local_constants() -> bool:
    """Hypothesis draws some examples from the constants of the project's
    modules loaded in the process (those it finds in sys.modules, at each
    draw): derandomized, a test's examples then depend on which modules the
    tests before it, in that pytest-xdist worker, happened to load, and
    change from run to run. With none (this empty pool), a test's examples
    depend on the test alone. False if this hypothesis keeps no such pool
    (another version): nothing to do."""
    try:
        from hypothesis.internal.conjecture import providers
    except ImportError:  # pragma: no cover - another hypothesis
        return False
    if not hasattr(providers, "_get_local_constants") or not hasattr(providers, "Constants"):
        return False  # pragma: no cover - another hypothesis
    none = providers.Constants()
    providers._get_local_constants = lambda: none
    return True


def examples(n: int) -> int:
    """A property test's ``max_examples``: ``n``, FUZZ_FACTOR times ``n`` in
    the fuzz profile."""
    return n * FUZZ_FACTOR if settings.get_current_profile_name() == "fuzz" else n


def deterministic(test_settings: settings) -> bool:
    """Whether a property test with these settings draws the same examples
    on every run: derandomized, and no database to replay from."""
    return test_settings.derandomize and test_settings.database is None
