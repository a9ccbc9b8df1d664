"""The ybgc command as users and pre-commit run it: exit codes, report
formats, fmt, ir, generate (atomic, no clobbering, user code kept)."""

from __future__ import annotations

import argparse
import io
import json
import os
import re
import shlex
import shutil
import subprocess
import sys
import sysconfig
from pathlib import Path

import yaml

from ybg.compiler.pipeline import compile_path
from ybg.report import report_text

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted((ROOT / "examples").glob("*.ini"))
LEGACY = sorted((ROOT.parent / "shared" / "legacy").glob("*.ini"))
INVALID = ROOT / "tests" / "invalid"


def run(*args, cwd=None, input=None):
    """Run the installed console script, as a user would."""
    exe = shutil.which("ybgc", path=os.path.dirname(sys.executable)) or shutil.which("ybgc")
    assert exe, "the ybgc console script is not installed (pip install -e .)"
    return subprocess.run([exe, *map(str, args)], capture_output=True, text=True, cwd=cwd, input=input,
                          timeout=120)


def test_check_exit_codes():
    # the examples of a user's own messages and services find them in msgpkgs/
    assert run("check", "--msg-path", ROOT / "msgpkgs", *EXAMPLES).returncode == 0
    legacy = run("check", *LEGACY)
    assert legacy.returncode == 0, legacy.stderr  # warnings only
    assert "warning W504" in legacy.stderr
    assert run("check", "--strict", *LEGACY).returncode == 1  # warnings fail with --strict
    assert run("check", "--strict", "--msg-path", ROOT / "msgpkgs", *EXAMPLES).returncode == 0
    assert run("check", INVALID / "E301_unknown_type.ini").returncode == 1
    assert run("check", "/nonexistent/config.ini").returncode == 2
    assert run("check", INVALID / "E002_not_utf8.ini").returncode == 2
    assert run("check").returncode == 2  # usage
    assert run("check", "--format", "xml", EXAMPLES[0]).returncode == 2


def test_text_format_is_file_line_col():
    r = run("check", INVALID / "E313_unknown_converter.ini")
    path = INVALID / "E313_unknown_converter.ini"
    assert re.search(rf"^{re.escape(str(path))}:9:11: error E313 unknown converter `deg2rad`$", r.stderr, re.M), r.stderr
    assert "hint: did you mean `deg_to_rad`?" in r.stderr
    assert "Traceback" not in r.stderr


def test_terminal_output_shows_source_and_caret():
    path = INVALID / "E313_unknown_converter.ini"
    result = compile_path(path)
    out = io.StringIO()
    report_text(result.diagnostics, {str(path): result.text}, out, color=True)
    text = re.sub(r"\x1b\[[0-9;]*m", "", out.getvalue())
    lines = text.splitlines()
    src = next(i for i, l in enumerate(lines) if "convert = deg2rad" in l)
    caret = lines[src + 1]
    assert caret.index("^") == lines[src].index("deg2rad")
    assert caret.count("^") == len("deg2rad")


def test_json_format():
    r = run("check", "--format", "json", INVALID / "E312_joint_lengths.ini", EXAMPLES[0])
    assert r.returncode == 1
    data = json.loads(r.stdout)
    (d,) = [x for x in data if x["severity"] == "error"]
    assert d["code"] == "E312" and d["line"] == 12 and d["column"] == 1
    assert d["title"] == "array lengths disagree" and d["hint"]


def test_github_format():
    r = run("check", "--format", "github", INVALID / "W501_unused_mux.ini")
    assert r.returncode == 0
    assert re.match(r"::warning file=.*W501_unused_mux\.ini,line=10,col=1,title=W501::mux `spare` is not used",
                    r.stdout), r.stdout
    # notes are notices with -v, as in the text format
    legacy = INVALID / "N601_legacy_form.ini"
    quiet = run("check", "--format", "github", legacy)
    loud = run("check", "--format", "github", "-v", legacy)
    assert quiet.returncode == loud.returncode == 0
    assert "title=N601" not in quiet.stdout
    assert re.search(r"^::notice file=.*N601_legacy_form\.ini,line=[0-9]+,col=[0-9]+,title=N601::legacy form", loud.stdout,
                     re.M), loud.stdout
    assert "N601" in run("check", "-v", legacy).stderr


def test_check_with_backend(tmp_path):
    r = run("check", "--backend", "ros2", ROOT.parent / "shared" / "legacy" / "thesis_figure5_rviz.ini")
    assert r.returncode == 1
    assert "E318" in r.stderr and "ybgc fmt --to named --ros2" in r.stderr
    assert run("check", "--backend", "cpp", ROOT.parent / "shared" / "legacy" / "thesis_figure5_rviz.ini").returncode == 0


def test_e318_hint_command_converts_into_a_new_file(tmp_path):
    """The command E318's hint gives, run as written: the legacy file stays
    as it was, a new file named after it holds it converted for ROS 2, which
    the ros2 backend builds."""
    legacy = ROOT.parent / "shared" / "legacy" / "thesis_figure5_rviz.ini"
    config = tmp_path / legacy.name
    shutil.copy(legacy, config)
    original = config.read_bytes()
    r = run("check", "--backend", "ros2", "--format", "json", config.name, cwd=tmp_path)
    (e318,) = [d for d in json.loads(r.stdout) if d["code"] == "E318"]
    command = re.search(r"`(ybgc [^`]*)`", e318["hint"]).group(1)
    words = [config.name if w == "FILE" else w for w in shlex.split(command)]
    assert words[0] == "ybgc" and config.name in words, command
    target = words[words.index("-o") + 1]  # a new file, named after the config
    assert target not in (config.name, "new.ini"), command
    done = run(*words[1:], cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert config.read_bytes() == original
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([config.name, target])
    converted = run("fmt", "--to", "named", "--ros2", "--stdout", config.name, cwd=tmp_path).stdout
    assert converted and (tmp_path / target).read_text(encoding="utf-8") == converted
    assert run("check", "--backend", "ros2", target, cwd=tmp_path).returncode == 0


def test_fmt_check_and_rewrite(tmp_path):
    messy = tmp_path / "messy.ini"
    messy.write_text("[output]\r\nport=/out:o\r\n\r\n\r\n[mux m]\r\nports=/a:o , /b:o ,\r\n[message]\r\nx=m ;c\r\n")
    before = messy.read_bytes()
    r = run("fmt", "--check", messy)
    assert r.returncode == 1 and "would be reformatted" in r.stderr
    assert messy.read_bytes() == before  # --check writes nothing
    assert run("fmt", messy).returncode == 0
    assert messy.read_text() == "[output]\nport = /out:o\n\n[mux m]\nports = /a:o, /b:o\n\n[message]\nx = m  ;c\n"
    assert run("fmt", "--check", messy).returncode == 0
    assert run("fmt", "--check", *EXAMPLES).returncode == 0


def test_fmt_refuses_broken_files(tmp_path):
    bad = tmp_path / "bad.ini"
    bad.write_text('[output]\nport = "unterminated\n')
    before = bad.read_bytes()
    r = run("fmt", bad)
    assert r.returncode == 1 and "E102" in r.stderr
    assert bad.read_bytes() == before


def test_fmt_to_named_in_one_command(tmp_path):
    src = ROOT.parent / "shared" / "legacy" / "vizzy_upper_body.ini"
    out = tmp_path / "vizzy_named.ini"
    r = run("fmt", "--to", "named", src, "-o", out)
    assert r.returncode == 0, r.stderr
    text = out.read_text()
    assert "[mux mux1]" in text and "type = sensor_msgs/JointState" in text and "header.seq = counter" in text
    assert run("check", "--strict", out).returncode == 0
    assert compile_path(out).program.message == compile_path(src).program.message
    r2 = run("fmt", "--to", "named", "--ros2", src, "-o", tmp_path / "ros2.ini")
    assert r2.returncode == 0
    assert run("check", "--backend", "ros2", tmp_path / "ros2.ini").returncode == 0


def test_ir_command():
    r = run("ir", EXAMPLES[0])
    assert r.returncode == 0
    data = json.loads(r.stdout)
    assert data["ir_version"] == 1 and data["output"]["kind"] in ("ros1", "ros2", "yarp")
    assert run("ir", INVALID / "E301_unknown_type.ini").returncode == 1


def test_unknown_backend_is_a_usage_error():
    r = run(EXAMPLES[0], "--backend", "rust")
    assert r.returncode == 2
    assert "backends are cpp, py, ros2" in r.stderr


def test_backend_choices_come_from_the_registry(monkeypatch):
    """Every command's --backend takes the registry's names, and generate's
    help says what each backend makes, in the registry's words."""
    from ybg import backends, cli

    extra = backends.registry.BackendInfo("nowhere:Nothing", "a test entry",
                                          backends.Builds(frozenset(), frozenset(), {}))
    monkeypatch.setitem(backends.REGISTRY, "zz", extra)
    parser = cli.build_parser()
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for command in ("check", "ir", "generate"):
        (action,) = [a for a in sub.choices[command]._actions if "--backend" in a.option_strings]
        assert list(action.choices) == sorted(backends.REGISTRY), command
    help_text = sub.choices["generate"].format_help()
    for name, info in backends.REGISTRY.items():
        assert re.search(rf"^  {name} +{re.escape(info.description)}$", help_text, re.M), name


def test_generate_writes_atomically_and_keeps_user_code(tmp_path):
    cfg = ROOT / "examples" / "yarp_to_yarp_end_effector.ini"
    out = tmp_path / "mod"
    r = run(cfg, "--backend", "py", "-o", out)
    assert r.returncode == 0, r.stderr
    (gen,) = [p for p in out.iterdir() if p.suffix == ".py"]
    text = gen.read_text()
    assert "generated by ybgc" in "".join(text.splitlines(True)[:3]).lower()
    m = re.search(r"ybgc:user-begin (\S+)\n", text)
    assert m, "the generated module has a place for custom code"
    edited = text.replace(m.group(0), m.group(0) + "# my own computation\n", 1)
    gen.write_text(edited)
    r = run(cfg, "--backend", "py", "-o", out)
    assert r.returncode == 0, r.stderr
    assert "# my own computation" in gen.read_text()
    assert not [p for p in out.iterdir() if p.name.endswith(".tmp")]


class _RecordingBackend:
    """Stands for a backend: records the options it is given and returns a
    module with its runtime beside it, in a subfolder."""

    def __init__(self):
        self.options = []

    def render(self, program, options):
        self.options.append(options)
        head = f"# generated by ybgc from {program.source}; do not edit\n"
        if options.single_file:
            return {f"{program.module}.py": head + "# the runtime inside\n"}
        return {f"{program.module}.py": head + "from ybgc_runtime import core\n",
                "ybgc_runtime/__init__.py": head,
                "ybgc_runtime/core.py": head + "# the runtime\n"}


def test_generate_passes_single_file_and_writes_every_file(tmp_path, monkeypatch):
    from ybg import backends, cli

    fake = _RecordingBackend()
    monkeypatch.setattr(backends, "get_backend", lambda name: fake)
    cfg = ROOT / "examples" / "yarp_to_yarp_end_effector.ini"
    beside, single = tmp_path / "beside", tmp_path / "single"
    assert cli.main(["generate", str(cfg), "--backend", "py", "-o", str(beside)]) == 0
    assert cli.main([str(cfg), "--backend", "py", "-o", str(single), "--single-file"]) == 0
    assert [o.single_file for o in fake.options] == [False, True]
    assert sorted(str(p.relative_to(beside)) for p in beside.rglob("*") if p.is_file()) == \
        ["end_effector_compare.py", "ybgc_runtime/__init__.py", "ybgc_runtime/core.py"]
    assert [p.name for p in single.iterdir()] == ["end_effector_compare.py"]


def test_generate_does_not_clobber_foreign_files(tmp_path):
    cfg = ROOT / "examples" / "yarp_to_yarp_end_effector.ini"
    out = tmp_path / "mod"
    out.mkdir()
    mine = out / "end_effector_compare.py"
    mine.write_text("print('my own module')\n")
    r = run(cfg, "--backend", "py", "-o", out)
    assert r.returncode == 2 and "--force" in r.stderr
    assert mine.read_text() == "print('my own module')\n"
    assert run(cfg, "--backend", "py", "-o", out, "--force").returncode == 0
    assert "generated by ybgc" in mine.read_text().lower()


def test_generate_with_errors_writes_nothing(tmp_path):
    out = tmp_path / "mod"
    r = run(INVALID / "E312_joint_lengths.ini", "--backend", "py", "-o", out)
    assert r.returncode == 1
    assert not out.exists()


def test_pre_commit_hooks():
    hooks = yaml.safe_load((ROOT / ".pre-commit-hooks.yaml").read_text())
    ids = {h["id"]: h for h in hooks}
    assert set(ids) == {"ybgc-check", "ybgc-fmt"}
    for h in hooks:
        pattern = re.compile(h["files"])
        for f in EXAMPLES + LEGACY:
            assert pattern.search(f.relative_to(f.parents[1]).as_posix()), (h["id"], f)
        assert h["entry"].split()[0] == "ybgc"


def test_pre_commit_entry_skips_foreign_ini_files(tmp_path):
    robot = tmp_path / "icub_robot.ini"  # a YARP robot config, not a bridge
    robot.write_text("[GENERAL]\nname icub\nparts (left_arm right_arm)\n")
    hooks = {h["id"]: h for h in yaml.safe_load((ROOT / ".pre-commit-hooks.yaml").read_text())}
    for hid in ("ybgc-check", "ybgc-fmt"):
        args = hooks[hid]["entry"].split()[1:]
        if hid == "ybgc-fmt":
            args.append("--check")
        else:  # the examples of a user's own service find it in msgpkgs/
            args += ["--msg-path", str(ROOT / "msgpkgs")]
        r = run(*args, robot, *EXAMPLES)
        assert r.returncode == 0, (hid, r.stderr)
    # without the flag the robot file is an error, as it should be
    assert run("check", robot).returncode == 1


def test_user_messages_from_msg_path_and_environment(tmp_path):
    cfg = ROOT.parent / "shared" / "legacy" / "tutorial_example_yarp_ros.ini"
    msgs = ROOT / "tests" / "msgs"
    without = run("check", cfg)
    assert "W503" in without.stderr  # custom type not found: not checked
    r = run("check", "--msg-path", msgs, cfg)
    assert r.returncode == 0 and "W503" not in r.stderr
    assert "taken as `motors_inertial_msgs/MotorsInertial`" in r.stderr  # bare name resolved
    data = json.loads(run("ir", "--msg-path", msgs, cfg).stdout)
    assert [f["name"] for f in data["message"]["fields"]] == ["inertial", "motors"]
    env = dict(os.environ, YBG_MSG_PATH=str(msgs))
    r = subprocess.run([shutil.which("ybgc", path=os.path.dirname(sys.executable)), "check", str(cfg)],
                       capture_output=True, text=True, env=env)
    assert r.returncode == 0 and "W503" not in r.stderr
    # and a wrong field count against the real definition is now an error
    bad = tmp_path / "bad.ini"
    bad.write_text(cfg.read_text().replace("num_fields = 2", "num_fields = 1").replace("2_type = mux\n2_mux = mux1\n", ""))
    r = run("check", "--msg-path", msgs, bad)
    assert r.returncode == 1 and "E303" in r.stderr
    assert run("check", "--msg-path", tmp_path / "nowhere", cfg).returncode == 2


def test_target_yarp_version(tmp_path):
    """`--yarp`: ROS 1 through YARP is an error for YARP 4, a warning for 3.10
    to 3.12, nothing for 3.5; a version that is not one is a usage error."""
    ros1 = str(ROOT / "examples" / "rviz_joint_states_ros1.ini")
    r4 = run("check", "--yarp", "4.0.0", ros1)
    assert r4.returncode == 1 and "E320" in r4.stdout + r4.stderr and "via = ros2" in r4.stdout + r4.stderr
    r312 = run("check", "--yarp", "3.12", ros1)
    assert r312.returncode == 0 and "W507" in r312.stdout + r312.stderr
    assert run("check", "--strict", "--yarp", "3.12", ros1).returncode == 1
    r35 = run("check", "--yarp", "3.5", ros1)
    assert r35.returncode == 0 and "W507" not in r35.stdout + r35.stderr and "E320" not in r35.stdout + r35.stderr
    yarp_only = str(ROOT / "examples" / "yarp_to_yarp_end_effector.ini")
    assert run("check", "--strict", "--yarp", "4.0", yarp_only).returncode == 0
    gen = run("generate", ros1, "--backend", "cpp", "--yarp", "4.0", "-o", str(tmp_path / "out"))
    assert gen.returncode == 1 and "E320" in gen.stdout + gen.stderr and not (tmp_path / "out").exists()
    bad = run("check", "--yarp", "four", ros1)
    assert bad.returncode == 2 and "not a YARP version" in bad.stderr


def _text_diagnostics(stderr: str) -> list[str]:
    """`FILE:LINE:COL: severity CODE` of each diagnostic printed as text."""
    return re.findall(r"^(\S+:[0-9]+:[0-9]+: (?:error|warning|note) [EWN][0-9]{3})\b", stderr, re.M)


def test_generate_reports_what_check_reports(tmp_path):
    """What a backend cannot build is refused by `check --backend` with a
    code, a position and a hint, and `generate` reports the same lines: a
    ROS 2 output whose type is not found (E321), and what only the
    backend's lowering refuses (E318 at the field's line)."""
    # the original tutorial's config in the named form, for ROS 2: its message
    # type is the tutorial's own, which is not on the message path
    named = tmp_path / "motors.ini"
    named.write_text("[output]\ntopic = /motors_inertial_port\nvia = ros2\ntype = MotorsInertial\nrate = 60\n\n"
                     "[mux mux1]\nports = /dummy_head/state:o\nconvert = deg_to_rad\n\n"
                     "[mux mux2]\nports = /inertial\n\n[message]\nfield1 = mux2\nfield2 = mux1\n")
    check = run("check", "--backend", "ros2", named)
    gen = run("generate", named, "--backend", "ros2", "-o", tmp_path / "out")
    assert check.returncode == gen.returncode == 1
    assert f"{named}:4:8: error E321" in _text_diagnostics(check.stderr)
    assert _text_diagnostics(gen.stderr) == _text_diagnostics(check.stderr)
    assert "hint: write `pkg/Name`" in gen.stderr and "Traceback" not in gen.stderr
    assert not (tmp_path / "out").exists()

    # a wstring field: the ros2 backend's lowering refuses it, so the check does
    msgs = tmp_path / "msgs" / "my_msgs" / "msg"
    msgs.mkdir(parents=True)
    (msgs / "Label.msg").write_text("wstring text\nfloat64 value\n")
    cfg = tmp_path / "label.ini"
    cfg.write_text("[output]\ntopic = /label\ntype = my_msgs/Label\n\n[mux m]\nports = /value:o\n\n"
                   "[message]\ntext = \"wide\"\nvalue = m[0]\n")
    check = run("check", "--backend", "ros2", "--msg-path", tmp_path / "msgs", cfg)
    gen = run("generate", cfg, "--backend", "ros2", "--msg-path", tmp_path / "msgs", "-o", tmp_path / "out")
    assert check.returncode == gen.returncode == 1
    assert _text_diagnostics(check.stderr) == _text_diagnostics(gen.stderr) == [f"{cfg}:9:1: error E318"]
    assert "hint: a limit of the ros2 backend" in check.stderr
    assert run("check", "--msg-path", tmp_path / "msgs", cfg).returncode == 0  # the config itself is fine


def test_generate_maps_a_rendering_error_to_its_line(tmp_path, monkeypatch, capsys):
    """A LoweringError that only rendering raises is reported as a
    diagnostic at the span of the IR element it refuses, never as a bare message."""
    from ybg import backends, cli

    class Refusing:
        def render(self, program, options):  # refuses the field `name`, at its span in the IR
            field = next(f for f in program.message.fields if f.name == "name")
            raise backends.LoweringError("no such thing", field.span)

    monkeypatch.setattr(backends, "get_backend", lambda name: Refusing())
    cfg = ROOT / "examples" / "vizzy_rviz_joint_states.ini"
    assert cli.main(["generate", str(cfg), "--backend", "ros2", "-o", str(tmp_path / "out")]) == 1
    err = capsys.readouterr().err
    line = next(n for n, text in enumerate(cfg.read_text().splitlines(), 1) if text.startswith("name ="))
    assert f"{cfg}:{line}:1: error E318 the ros2 backend cannot build this: no such thing" in err
    assert not (tmp_path / "out").exists()


def test_fmt_to_ros2_retargets_the_inputs_or_says_why(tmp_path):
    """`fmt --to named --ros2` of a ROS-to-YARP legacy config: its topics
    are read from ROS 2 too. A ROS 2 topic needs its type, which the legacy
    form does not give: E319 at the topic, nothing written, and the hint's
    two steps give a config that the ros2 backend builds."""
    legacy = ROOT.parent / "shared" / "legacy" / "fixation_point_goal.ini"
    config = tmp_path / legacy.name
    shutil.copy(legacy, config)
    r = run("fmt", "--to", "named", "--ros2", config.name, "-o", "new.ini", cwd=tmp_path)
    assert r.returncode == 1
    assert _text_diagnostics(r.stderr) == [f"{config.name}:10:9: error E319"]
    assert "legacy form gives none" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "new.ini").exists()
    # the hint, followed: convert, give the type, read it from ROS 2
    hint = re.search(r"hint: convert without --ros2 \(`(ybgc [^`]*)`\)", r.stderr).group(1)
    words = [config.name if w == "FILE" else w for w in shlex.split(hint)]
    assert run(*words[1:], cwd=tmp_path).returncode == 0
    new = tmp_path / words[words.index("-o") + 1]
    text = new.read_text(encoding="utf-8")
    assert "topics = /fixation_point_goal_ros\nvia = ros1\n" in text
    new.write_text(text.replace("topics = /fixation_point_goal_ros\nvia = ros1\n",
                                "topics = /fixation_point_goal_ros (geometry_msgs/Point)\nvia = ros2\n"))
    assert run("check", "--backend", "ros2", new).returncode == 0

    # a topic declared in the legacy file is retargeted with its type
    declared = tmp_path / "goal.ini"
    declared.write_text(legacy.read_text(encoding="utf-8").replace(
        "ports = /fixation_point_goal_ros", "ports = /fixation_point_goal_ros (geometry_msgs/Point)"))
    assert run("check", "--backend", "ros2", declared).returncode == 1  # ROS 1 topics: E318
    r = run("fmt", "--to", "named", "--ros2", declared, "-o", tmp_path / "goal_ros2.ini")
    assert r.returncode == 0, r.stderr
    converted = (tmp_path / "goal_ros2.ini").read_text(encoding="utf-8")
    assert "[mux mux1]\ntopics = /fixation_point_goal_ros (geometry_msgs/Point)\nvia = ros2\n" in converted
    assert "ros1" not in converted
    assert run("check", "--strict", "--backend", "ros2", tmp_path / "goal_ros2.ini").returncode == 0


def _original_ini_problems(text: str) -> list[str]:
    """The lines the original tool's INI reader refuses: it takes one line
    for each value, so a line must be blank, a comment, `[section]` or
    `key = value` (a continuation line is none of them)."""
    bad = []
    for n, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if not s or s[0] in "#;" or re.fullmatch(r"\[[^\]]+\]", s) or re.match(r"[^\s=]+\s*=", line):
            continue
        bad.append(f"{n}: {line}")
    return bad


def test_fmt_keeps_a_legacy_file_readable_by_the_original(tmp_path):
    """A legacy file formatted in place is not wrapped: the original's
    reader takes it. Figure 5 of the thesis continues a list on the next line
    (which the original refuses: fmt joins it), vizzy's lists are longer than
    the width at which the named form wraps."""
    for name in ("thesis_figure5_rviz.ini", "vizzy_upper_body.ini"):
        legacy = ROOT.parent / "shared" / "legacy" / name
        config = tmp_path / name
        shutil.copy(legacy, config)
        r = run("fmt", config)
        assert r.returncode == 0, r.stderr
        text = config.read_text(encoding="utf-8")
        assert _original_ini_problems(text) == [], name
        assert max(len(line) for line in text.splitlines()) > 100  # long values stay on their line
        assert compile_path(config).program == compile_path(legacy).program
        assert run("fmt", "--check", config).returncode == 0
    assert _original_ini_problems((ROOT.parent / "shared" / "legacy" / "thesis_figure5_rviz.ini").read_text())
    # the named form still wraps
    named = run("fmt", "--to", "named", "--stdout", ROOT.parent / "shared" / "legacy" / "vizzy_upper_body.ini").stdout
    assert max(len(line) for line in named.splitlines()) <= 100 and _original_ini_problems(named)


def test_a_trailing_comma_the_original_misread_is_reported(tmp_path):
    """`ports = /dummy_head/state:o,` (the original's tutorial): the
    original waited for a port named with the comma; ybgc reads the port
    without it, and says so (W509) until fmt removes the comma."""
    config = tmp_path / "tutorial.ini"
    shutil.copy(ROOT.parent / "shared" / "legacy" / "tutorial_example_yarp_ros.ini", config)
    r = run("check", config)
    assert r.returncode == 0 and f"{config}:11:28: warning W509" in _text_diagnostics(r.stderr)
    assert "`/dummy_head/state:o,`" in r.stderr and "remove the comma" in r.stderr
    assert run("fmt", config).returncode == 0
    assert "ports = /dummy_head/state:o\n" in config.read_text(encoding="utf-8")
    assert "W509" not in run("check", config).stderr


def test_an_installation_missing_a_file_of_its_own_says_so(tmp_path):
    """ybgc installed without one of its files (a broken or partial
    install): generating a module that needs it ends in an error naming the
    file and how to repair the install, exit 2, no traceback, nothing written."""
    broken = tmp_path / "site"
    shutil.copytree(ROOT / "ybg", broken / "ybg", ignore=shutil.ignore_patterns("__pycache__"))
    (broken / "ybg" / "runtime" / "cpp" / "ybgc_runtime.hpp").unlink()
    out = tmp_path / "m"
    # -S: without site's .pth files, which map `ybg` to this checkout (editable install)
    deps = sysconfig.get_paths()["purelib"]
    r = subprocess.run([sys.executable, "-S", "-c", "import sys; from ybg.cli import main; sys.exit(main(sys.argv[1:]))",
                        str(ROOT / "examples" / "yarp_to_yarp_end_effector.ini"), "--backend", "cpp", "-o", str(out)],
                       capture_output=True, text=True, env={**os.environ, "PYTHONPATH": f"{broken}:{deps}"},
                       cwd=tmp_path, timeout=120)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    assert "cannot read" in r.stderr and "ybgc_runtime.hpp" in r.stderr and "hint: reinstall ybgc" in r.stderr
    assert not out.exists()
