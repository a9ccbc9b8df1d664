"""docs/benchmarks.md says the commit each of its runs measured (a table row
`| measured | commit X; ... |`, which bench/run.py and the other benches
write), and its figures are those of the code: no file of the runtime
library (ybg/runtime/, both languages) or of the templates of the generated
modules changed in a commit after the one a run measured, unless the page
says why it was not run again, in that run's table:

    | not rerun for | the changes up to commit Y: why |

(the commits after Y are again unaccounted for). The next run of that bench
rewrites its table, and the row goes with it.

It reads the history with git: in a shallow clone that lacks a measured
commit it fails saying so (fetch the whole history), never passes unread.
"""
from __future__ import annotations

import re
import subprocess

import pytest

from harness.env import ROOT

PAGE = ROOT / "docs" / "benchmarks.md"
#: what a benchmark's figures depend on: the runtime library and the templates
HOT_PATH = ("ybg/runtime", "ybg/backends/cpp/templates", "ybg/backends/py/templates",
            "ybg/backends/ros2/templates")
MEASURED = re.compile(r"^\| measured \| commit ([0-9a-f]{7,40})\b", re.M)
NOTED = re.compile(r"^\| not rerun for \| the changes up to commit ([0-9a-f]{7,40})\b[^|]*\S[^|]*\|", re.M)


def git(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["git", *args], cwd=ROOT, capture_output=True, text=True, timeout=60)


def runs(page: str) -> list[tuple[str, str, str | None]]:
    """(the section's title, the commit it measured, the commit its note runs
    up to or None) of each run the page reports."""
    out = []
    starts = [0] + [m.start() for m in re.finditer(r"^## ", page, re.M)] + [len(page)]
    for a, b in zip(starts, starts[1:]):
        text = page[a:b]
        measured = MEASURED.search(text)
        if measured:
            noted = NOTED.search(text)
            title = text.splitlines()[0].lstrip("# ").strip()
            out.append((title, measured.group(1), noted.group(1) if noted else None))
    return out


def commit_known(commit: str) -> None:
    """Fail, saying why, unless ``commit`` is in the history of HEAD."""
    shallow = git("rev-parse", "--is-shallow-repository").stdout.strip() == "true"
    known = git("cat-file", "-e", f"{commit}^{{commit}}").returncode == 0
    if known and git("merge-base", "--is-ancestor", commit, "HEAD").returncode == 0:
        return
    if shallow:
        pytest.fail(f"this clone is shallow and its history does not reach commit {commit}, which "
                    f"{PAGE.name} names: the test cannot tell what changed since; fetch the whole "
                    f"history (git fetch --unshallow; a CI checkout with fetch-depth 0)", pytrace=False)
    pytest.fail(f"commit {commit}, which {PAGE.name} names, is not in the history of HEAD", pytrace=False)


def test_the_page_names_the_commit_of_its_main_run():
    found = runs(PAGE.read_text(encoding="utf-8"))
    assert found and found[0][0] == "Benchmarks of the generated bridge modules", found


def test_no_runtime_change_since_a_run_is_left_unsaid():
    if git("rev-parse", "--git-dir").returncode != 0:
        pytest.fail(f"{ROOT} is not a git repository: the test reads which commits changed the runtime "
                    f"since the runs of {PAGE.name}", pytrace=False)
    problems = []
    for title, measured, noted in runs(PAGE.read_text(encoding="utf-8")):
        commit_known(measured)
        since = measured
        if noted is not None:
            commit_known(noted)
            if git("merge-base", "--is-ancestor", measured, noted).returncode != 0:
                problems.append(f"{title}: its note names commit {noted}, which is not after {measured}")
                continue
            since = noted
        log = git("log", "--format=%h %s", f"{since}..HEAD", "--", *HOT_PATH)
        assert log.returncode == 0, log.stderr
        changes = log.stdout.splitlines()
        if changes:
            problems.append(
                f"{title}: measured at commit {measured}"
                + (f" (a note covers the changes up to {noted})" if noted else "")
                + f"; since then {len(changes)} commit(s) changed the runtime or the templates:\n    "
                + "\n    ".join(line[:110] for line in changes[:12])
                + ("\n    ..." if len(changes) > 12 else ""))
    assert not problems, (
        "\n".join(problems) + f"\nRun that benchmark again and commit the page ({PAGE.name} says how), "
        "or add a row to its table saying why not: | not rerun for | the changes up to commit Y: why |")
