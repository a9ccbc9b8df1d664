"""``ybgc check --backend B`` passes exactly when ``ybgc generate --backend B``
succeeds, for every config of the examples, the corpus (valid and invalid),
the canonical files and the legacy configs, and every backend: both commands
refuse from the backend's one declaration (``ybg.backends.registry``) and its
lowering, so they agree by construction; this test holds them to it.

Both commands run in this process, as a user runs them (``ybg.cli.main``),
the generation into a folder of its own. (``--package`` and
``--single-file`` render what the same lowering decided: ``Backend.lower``
makes the package's decisions too.)
"""

from __future__ import annotations

import contextlib
import io
from pathlib import Path

import pytest

from ybg.backends import backend_names
from ybg.cli import main

ROOT = Path(__file__).resolve().parent.parent
SOURCES = {
    "examples": sorted(ROOT.glob("examples/*.ini")),
    "canonical": sorted(ROOT.glob("tests/canonical/*.ini")),
    "invalid": sorted(ROOT.glob("tests/invalid/*.ini")),
    "legacy history": sorted(ROOT.glob("tests/legacy_history/**/*.ini")),
    "legacy": sorted((ROOT.parent / "shared" / "legacy").glob("**/*.ini")),
}
CONFIGS = [p for paths in SOURCES.values() for p in paths]


def run(*argv: str) -> tuple[int, str]:
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            code = main(list(argv))
        except SystemExit as e:
            code = e.code if isinstance(e.code, int) else 2
    return code, out.getvalue() + err.getvalue()


def test_every_source_of_configs_is_found():
    assert all(SOURCES.values()), {k: len(v) for k, v in SOURCES.items()}


@pytest.mark.parametrize("config", CONFIGS, ids=lambda p: str(p.relative_to(p.parents[1])))
def test_check_passes_exactly_when_generation_succeeds(config: Path, tmp_path: Path):
    # the examples of a user's own messages and services find them in msgpkgs/
    extra = ["--msg-path", str(ROOT / "msgpkgs")] if config in SOURCES["examples"] else []
    for backend in backend_names():
        checked, said = run("check", str(config), "--backend", backend, *extra)
        out = tmp_path / backend
        generated, told = run("generate", str(config), "--backend", backend, "-o", str(out), *extra)
        assert checked == generated, (
            f"{backend}: check {'passes' if checked == 0 else 'fails'} but generation "
            f"{'succeeds' if generated == 0 else 'fails'}\n--- check:\n{said}\n--- generate:\n{told}")
        assert (generated == 0) == out.is_dir(), told  # nothing written for a refused config
