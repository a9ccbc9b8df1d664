"""Continuous integration runs the README's two commands as written: the
first block of README.md (set up and run the main job; set up and pass the
tests) holds the same two commands that .ci/run runs, in that order, and
.ci/run stops at the first that fails."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def readme_commands() -> list[str]:
    """The commands of the README's first shell block, comments left out."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    block = re.search(r"^```sh\n(.*?)^```", text, re.M | re.S)
    assert block, "README.md opens with a shell block of its two commands"
    lines = (line.split("#", 1)[0].strip() for line in block.group(1).splitlines())
    return [line for line in lines if line]


def ci_commands() -> list[str]:
    """The commands .ci/run runs: its lines that are neither comments nor
    shell settings."""
    lines = (line.strip() for line in (ROOT / ".ci" / "run").read_text(encoding="utf-8").splitlines())
    return [line for line in lines if line and not line.startswith(("#", "set ", "cd "))]


def test_ci_runs_the_readme_commands_as_written():
    readme = readme_commands()
    assert readme == ["scripts/setup.sh && scripts/demo.sh",
                      "scripts/setup.sh --yarp 3.12.3,4.0.0 && .venv/bin/python -m pytest -q -n 3 --dist loadfile"]
    assert ci_commands() == readme
    assert "set -euo pipefail" in (ROOT / ".ci" / "run").read_text(encoding="utf-8")

