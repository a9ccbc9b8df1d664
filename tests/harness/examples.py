"""The examples (examples/) and the command each documents for its check.

An example checks with ``ybgc check EXAMPLE``, run from the repository's
root, unless its header says otherwise on a line of its own::

    # check: ybgc check --msg-path msgpkgs examples/gaze_look_at.ini

(a config of a user's own ``.srv``, say). A folder of configs under
examples/ is a robot: ``ybgc check examples/FOLDER`` checks its configs
together, across configs too. scripts/demo.sh runs these commands, and
tests/test_corpus.py holds every example to its own.
"""
from __future__ import annotations

import re
import shlex
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = ROOT / "examples"
#: an example's own check command, in its header
CHECK_LINE = re.compile(r"^# check: (.*)$", re.M)


def _is_config(path: Path) -> bool:
    from ybg.cli import is_config_file

    return is_config_file(str(path))


def robots() -> list[Path]:
    """The folders of examples/ that hold configs: robots."""
    return sorted(d for d in EXAMPLES.iterdir() if d.is_dir() and any(map(_is_config, d.glob("*.ini"))))


def configs() -> list[Path]:
    """Every config of examples/: the single ones, then each robot's."""
    return sorted(EXAMPLES.glob("*.ini")) + [c for d in robots() for c in sorted(d.glob("*.ini")) if _is_config(c)]


def own_check(path: Path) -> list[str] | None:
    """The arguments after ``ybgc`` of the check command ``path``'s header
    gives (``# check: ybgc check ...``), or None."""
    m = CHECK_LINE.search(path.read_text(encoding="utf-8").split("\n[", 1)[0])
    if m is None:
        return None
    words = shlex.split(m.group(1))
    if words[:2] != ["ybgc", "check"]:
        raise ValueError(f"{path.relative_to(ROOT)}: `# check:` gives `{m.group(1)}`, not a `ybgc check` command")
    return words[1:]


def check_commands() -> list[list[str]]:
    """The check commands of every example, each as the arguments after
    ``ybgc``, to run from the repository's root: one ``check`` of every
    single example without a command of its own, each own command, and a
    ``check`` of each robot's folder."""
    plain, own = [], []
    for path in sorted(EXAMPLES.glob("*.ini")):
        args = own_check(path)
        if args is None:
            plain.append(str(path.relative_to(ROOT)))
        else:
            own.append(args)
    robot_checks = [["check", str(d.relative_to(ROOT))] for d in robots()]
    for d in robots():  # a robot's configs are checked with their folder: an own command there is a mistake
        for c in d.glob("*.ini"):
            if own_check(c) is not None:
                raise ValueError(f"{c.relative_to(ROOT)}: a config of a robot's folder is checked with the folder")
    return [["check", *plain]] + own + robot_checks
