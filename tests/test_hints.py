"""A hint that gives a literal fix is right: applied as it is to a copy of a
config of the invalid corpus, it makes progress (docs/diagnostics.md,
"Fixes"), never gives the same diagnostic again, and never loses a key.

The fix of a diagnostic is its ``fix`` (edits of the text, or a command), or
the ``ybgc fmt`` command its hint quotes (:func:`~ybg.compiler.diagnostics.fix_of`).
A command is run as the hint writes it, ``FILE`` (``CONFIG``) standing for the
config and ``<stem>`` for its name without ``.ini``, in a folder holding only
the config; what it writes (``-o``, else the config itself) is checked again.
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import shlex
from pathlib import Path

import pytest

from ybg import cli
from ybg.backends import check_result
from ybg.compiler.diagnostics import Diagnostic, Fix, Severity, apply_edits, fix_of
from ybg.compiler.fmt import format_item
from ybg.compiler.options import Options
from ybg.compiler.pipeline import Result, compile_path

ROOT = Path(__file__).resolve().parent.parent
INVALID = sorted((ROOT / "tests" / "invalid").glob("*.ini"))
RUN_YBGC = "import sys; from ybg.cli import main; sys.exit(main(sys.argv[1:]))"

#: fixes that cannot work yet, and why ("<file stem>:<code>:<line>:<column>" -> the cause)
XFAIL: dict[str, str] = {}


def _options(path: Path) -> tuple[Options, str | None]:
    """The options a file of the corpus is checked with (its `# backend:`, `# yarp:`, `# msg-path:` lines)."""
    head = path.read_bytes().decode("utf-8", "replace")
    backend = re.search(r"# backend: (\S+)", head)
    yarp = re.search(r"# yarp: (\S+)", head)
    msg_path = re.search(r"# msg-path: (\S+)", head)
    return (Options(yarp=yarp.group(1) if yarp else None,
                    msg_path=(str(ROOT / "tests" / msg_path.group(1)),) if msg_path else ()),
            backend.group(1) if backend else None)


def _check(path: Path, options: Options, backend: str | None) -> Result:
    result = compile_path(path, options)
    return check_result(result, backend) if backend else result


def _subject(path: Path, result: Result) -> Diagnostic | None:
    """The diagnostic the file shows (its `# expect:` line)."""
    m = re.search(r"# expect: ([EWN][0-9]{3}) ([0-9]+):([0-9]+)", path.read_bytes().decode("utf-8", "replace"))
    for d in result.diagnostics:
        if m and (d.code, d.span.line, d.span.column) == (m.group(1), int(m.group(2)), int(m.group(3))):
            return d
    return None


def _cases():
    """(file, diagnostic, fix) for each diagnostic of the corpus whose hint gives a fix: every
    error and warning, and the note a file shows."""
    for path in INVALID:
        options, backend = _options(path)
        result = _check(path, options, backend)
        subject = _subject(path, result)
        for d in result.diagnostics:
            fix = fix_of(d, result.form == "legacy")
            if fix is None or (d.severity is Severity.NOTE and d is not subject):
                continue
            case = f"{path.stem}:{d.code}:{d.span.line}:{d.span.column}"
            marks = [pytest.mark.xfail(strict=True, reason=XFAIL[case])] if case in XFAIL else []
            yield pytest.param(path, d, fix, id=case, marks=marks)


CASES = list(_cases())


def _stage(code: str) -> int:
    """Where in the pipeline a code is found: syntax, structure and names, types, what a backend
    or the target YARP refuses."""
    if code in ("E318", "E320", "E321"):
        return 4
    return {"E0": 1, "E1": 1, "E2": 2, "E4": 2, "E3": 3}[code[:2]]


def _same(a: Diagnostic, b: Diagnostic) -> bool:
    return (a.code, a.message) == (b.code, b.message)


def _keys(result: Result) -> set[tuple[str, ...]]:
    """What a config sets, in the named form: ``(section, key)`` of each entry; for the named
    sections of a file that mixes the forms, which the conversion of its legacy sections does
    not make, ``(section, key, value)`` as written too, which a conversion must keep."""
    keys: set[tuple[str, ...]] = set()
    if result.named is not None:
        keys.update((sec.title, e.key) for sec in result.named.sections for e in sec.entries)
    if result.form == "legacy" and result.document is not None:
        keys.update((sec.title, e.key, ", ".join(map(format_item, e.items)))
                    for sec in result.document.sections if sec.label is not None or sec.name in ("output", "module")
                    for e in sec.entries)
    return keys


def _written(result: Result) -> set[tuple[str, ...]]:
    """``(section, key)`` and ``(section, key, value)`` of each entry of a named config."""
    doc = result.named
    if doc is None:
        return set()
    return ({(sec.title, e.key) for sec in doc.sections for e in sec.entries}
            | {(sec.title, e.key, ", ".join(map(format_item, e.items))) for sec in doc.sections for e in sec.entries})


def _run(command: str, config: Path) -> tuple[int, str, Path]:
    """Run a hint's ``ybgc`` command in the config's folder: (exit status, what it
    printed, the config it writes)."""
    words = [config.name if w in ("FILE", "CONFIG") else w.replace("<stem>", config.stem).replace("<file>", config.name)
             for w in shlex.split(command)]
    assert words[0] == "ybgc", command
    out = next((words[k + 1] for k, w in enumerate(words[:-1]) if w in ("-o", "--output")), None)
    printed = io.StringIO()
    cwd = os.getcwd()
    os.chdir(config.parent)
    try:
        with contextlib.redirect_stdout(printed), contextlib.redirect_stderr(printed):
            try:
                status = cli.main(words[1:])
            except SystemExit as e:
                status = e.code if isinstance(e.code, int) else 2
    finally:
        os.chdir(cwd)
    return status, printed.getvalue(), config.parent / out if out else config


def _apply(fix: Fix, path: Path, tmp: Path) -> tuple[Path, str]:
    """The fixed config (a copy of ``path`` in ``tmp``), and what the command printed."""
    config = tmp / path.name
    text = path.read_text(encoding="utf-8")
    if fix.command is None:
        config.write_text(apply_edits(text, fix.edits), encoding="utf-8")
        return config, ""
    config.write_text(text, encoding="utf-8")
    status, printed, written = _run(fix.command, config)
    assert status == 0, f"`{fix.command}` failed ({status}):\n{printed}"
    return written, printed


@pytest.mark.parametrize("path, d, fix", CASES)
def test_hint_fix_makes_progress(path: Path, d: Diagnostic, fix: Fix, tmp_path: Path):
    options, backend = _options(path)
    before = _check(path, options, backend)
    fixed, printed = _apply(fix, path, tmp_path)
    after = _check(fixed, options, backend)
    shown = [f"{x.code} {x.span.line}:{x.span.column} {x.message}" for x in after.diagnostics]
    assert not any(_same(x, d) for x in after.diagnostics), ("the same diagnostic again", shown)
    new_errors = [x for x in after.errors if not any(_same(x, y) for y in before.errors)]
    if d.severity is Severity.ERROR:
        # fewer errors, or as many, each new one found later: a later stage, or a later line
        assert len(after.errors) < len(before.errors) or (
            len(after.errors) == len(before.errors)
            and all(_stage(x.code) > _stage(d.code) or x.span.line > d.span.line for x in new_errors)), shown
    else:
        assert not new_errors, shown
        fewer = after.warnings if d.severity is Severity.WARNING else after.diagnostics
        assert len(fewer) < len(before.warnings if d.severity is Severity.WARNING else before.diagnostics), shown
    if fix.command is not None:
        # no key is lost, unless the converted file says it dropped it
        text = fixed.read_text(encoding="utf-8")
        dropped = set(re.findall(r"^# dropped `([^`]+)`", text, re.M))
        lost = sorted(k for k in _keys(before) - _written(after) if k[1] not in dropped)
        assert not lost, (f"`{fix.command}` lost keys", lost, printed)


def test_the_fixes_of_the_corpus_are_walked():
    """The fixes the corpus shows are among those walked: a command (legacy ROS 1 config for
    --backend ros2; mixed forms) and edits (a range or a converter; a misspelt parameter)."""
    walked = {(p.values[0].name, p.values[1].code) for p in CASES}
    for case in [("E318_ros1_for_ros2_backend.ini", "E318"), ("E207_mixed_forms.ini", "E207"),
                 ("E207_named_module_in_legacy.ini", "E207"),
                 ("E309_euler_angles_into_quaternion.ini", "E309"), ("E309_mux_width_into_point.ini", "E309"),
                 ("E208_euler_unit_spelt_out.ini", "E208"), ("E311_seq_in_ros2.ini", "E311")]:
        assert case in walked, case
    commands = {p.values[2].command for p in CASES if p.values[2].command}
    assert any("--ros2" in c for c in commands), commands


def test_euler_angles_into_a_quaternion_are_converted():
    """E309 for three Euler angles where a quaternion goes names `euler_to_quat`, not a
    range of four that the mux does not have (E315)."""
    path = ROOT / "tests" / "invalid" / "E309_euler_angles_into_quaternion.ini"
    (d,) = _check(path, Options(), None).diagnostics
    assert "`convert = euler_to_quat(rpy, deg)[0:3]`" in d.hint and "head[0:4]" not in d.hint
    assert d.fix is not None and [e.text for e in d.fix.edits] == ["convert = euler_to_quat(rpy, deg)[0:3]\n"]


def test_a_failed_converter_has_no_follow_on():
    """One mistake, one diagnostic: the lines that use a mux whose converter failed are not
    checked against what the mux would be without it (before: E315 on a converter's range and
    on the message line, W520 asking for the converter the line already has)."""
    path = ROOT / "tests" / "invalid" / "E208_euler_unit_spelt_out.ini"
    result = _check(path, Options(), None)
    assert [(d.code, d.span.line, d.span.column) for d in result.diagnostics] == [("E208", 11, 30)]
    assert result.diagnostics[0].hint == "write `euler_to_quat(rpy, deg)`"


def test_check_json_carries_the_fix_an_editor_applies(tmp_path: Path):
    """`ybgc check --format json` gives each hint's literal fix as data: the
    edits (1-based, end exclusive), applied to the text as an editor would,
    leave a config that checks clean."""
    import json
    import subprocess
    import sys

    config = tmp_path / "c.ini"
    config.write_text((ROOT / "tests" / "invalid" / "E313_unknown_converter.ini").read_text(encoding="utf-8"))
    r = subprocess.run([sys.executable, "-c", RUN_YBGC, "check", "--format", "json", str(config)],
                       capture_output=True, text=True, timeout=60)
    (d,) = [d for d in json.loads(r.stdout) if d["code"] == "E313"]
    lines = config.read_text(encoding="utf-8").splitlines(keepends=True)
    for e in sorted(d["fix"]["edits"], key=lambda e: (e["line"], e["column"]), reverse=True):
        assert e["line"] == e["end_line"]
        line = lines[e["line"] - 1]
        lines[e["line"] - 1] = line[:e["column"] - 1] + e["text"] + line[e["end_column"] - 1:]
    config.write_text("".join(lines), encoding="utf-8")
    again = subprocess.run([sys.executable, "-c", RUN_YBGC, "check", str(config)], capture_output=True, text=True,
                           timeout=60)
    assert again.returncode == 0, again.stderr
