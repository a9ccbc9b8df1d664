"""Hypothesis' profiles (tests/harness/properties.py): under ci, the default,
a property test draws the same examples on every run, its own @settings
included; fuzz draws more, at random."""
from __future__ import annotations

import sys

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from harness import properties


def draws(parent: settings) -> list:
    """What a property test with its own @settings (made under ``parent``)
    draws in one run."""
    drawn = []

    @settings(parent, max_examples=20)
    @given(st.floats(), st.text(max_size=8))
    def test(x, s):
        drawn.append((repr(x), s))

    test()
    return drawn


def test_ci_draws_the_same_examples_every_run():
    ci = settings.get_profile("ci")
    assert ci.derandomize and ci.database is None and ci.deadline is None
    assert HealthCheck.too_slow in ci.suppress_health_check
    first = draws(ci)
    assert len(first) == 20 and draws(ci) == first


def test_fuzz_draws_more_at_random():
    fuzz = settings.get_profile("fuzz")
    assert not fuzz.derandomize and fuzz.max_examples == 100 * properties.FUZZ_FACTOR
    assert fuzz.deadline is None
    assert draws(fuzz) != draws(fuzz)


def test_own_settings_inherit_the_profile():
    """A test's @settings made under the loaded profile keeps what it does
    not set; this run's profile is the one conftest loaded."""
    own = settings(max_examples=properties.examples(7), deadline=None)
    assert own.derandomize == settings.default.derandomize
    assert own.database == settings.default.database
    assert properties.deterministic(own) == (settings.get_current_profile_name() == "ci")
    assert own.max_examples == (7 if settings.get_current_profile_name() == "ci" else 7 * properties.FUZZ_FACTOR)


def test_ci_draws_do_not_depend_on_the_modules_loaded(tmp_path, monkeypatch):
    """Hypothesis draws some examples from the constants of the modules
    loaded in the process: under ci the pool is empty
    (``properties.without_local_constants``), so that a test draws the same
    examples whichever test files its pytest-xdist worker loaded before."""
    ci = settings.get_profile("ci")

    def many() -> list:
        drawn = []

        @settings(ci, max_examples=200)
        @given(st.text(max_size=12), st.integers())
        def test(s, n):
            drawn.append((s, n))

        test()
        return drawn

    before = many()
    (tmp_path / "ybg_constants_probe.py").write_text(
        "".join(f"WORD_{k} = {('probe-%d' % k)!r}\nNUMBER_{k} = {7919 * k + 13}\n" for k in range(300)),
        encoding="utf-8")
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.delitem(sys.modules, "ybg_constants_probe", raising=False)  # taken out again after the test
    __import__("ybg_constants_probe")
    assert many() == before
