"""The config corpora: every invalid file gives its exact code at its exact
line and column; every legacy file and example checks; both forms of a
legacy file give the same IR."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

import pytest

from harness import examples
from ybg.backends import LoweringError, RenderOptions, backend_names, check_result, get_backend
from ybg.cli import _formatted
from ybg.compiler import ir
from ybg.compiler.options import Options
from ybg.compiler.fmt import format_document
from ybg.compiler.parser import parse_text
from ybg.compiler.diagnostics import CODES, PROBE_CODES, Sink
from ybg.compiler.pipeline import compile_path, compile_text

ROOT = Path(__file__).resolve().parent.parent
INVALID = sorted((ROOT / "tests" / "invalid").glob("*.ini"))
#: cases across configs: a folder of configs, each checking alone, wrong together
INVALID_FOLDERS = sorted(p for p in (ROOT / "tests" / "invalid").iterdir() if p.is_dir())
LEGACY_DIR = ROOT.parent / "shared" / "legacy"
LEGACY = sorted(LEGACY_DIR.glob("*.ini"))
#: every example: the single configs, then each robot folder's (tests/harness/examples.py)
EXAMPLES = examples.configs()
#: the examples of a user's own messages and services find them in msgpkgs/
EXAMPLE_OPTIONS = Options(msg_path=(str(ROOT / "msgpkgs"),))

#: the warnings each legacy file deserves, and why
LEGACY_WARNINGS = {
    # figure 5 omits rate (event-driven) and ros_msg_name (inferred from topic + 5 fields)
    "thesis_figure5_rviz.ini": {"W504", "W505"},
    # MotorsInertial is a custom message of the original tutorial, not shipped anywhere;
    # `ports = /dummy_head/state:o,`: the original read the comma as part of the name
    "tutorial_example_yarp_ros.ini": {"W503", "W509"},
    "tutorial_example_yarp_ros_more_ports.ini": {"W503"},
    # `ros_msg_name = JointState` has no package
    "vizzy_upper_body.ini": {"W502"},
    # the Point takes 3 of pf3dTracker's 7 values, which the port does not declare
    "ball_point_bridge.ini": {"W511"},
}


def test_every_code_is_documented_and_shown():
    doc = (ROOT / "docs" / "diagnostics.md").read_text(encoding="utf-8")
    rows = dict(re.findall(r"^\| ([EWN][0-9]{3}) \| ([^|]+?) \|", doc, re.M))
    assert rows == CODES, "docs/diagnostics.md and CODES disagree"
    assert not set(CODES) & set(PROBE_CODES), "a code of `ybgc check` is also one of `ybgc probe`"
    shown = {p.name[:4] for p in INVALID + INVALID_FOLDERS}
    assert set(CODES) - shown == {"E001"}  # E001 (unreadable file) is shown by test_cli


@pytest.mark.parametrize("folder", INVALID_FOLDERS, ids=lambda p: p.name)
def test_invalid_across_configs_said_in_each_config_naming_the_other(folder: Path, tmp_path: Path):
    """`ybgc check` of the folder's configs, as a user runs it in that folder:
    each config alone checks clean; together, each gets the code of the
    folder's name at its `# expect:` line and column, naming the other's
    file:line:column; the check exits 1 (for a warning, 0, and 1 with
    --strict) and writes nothing."""
    import subprocess
    import shutil
    import sys

    configs = sorted(folder.glob("*.ini"))
    assert len(configs) >= 2
    code = folder.name[:4]
    for path in configs:
        assert not compile_path(path).errors, f"{path.name} alone must check"
    exe = shutil.which("ybgc", path=str(Path(sys.executable).parent)) or "ybgc"
    r = subprocess.run([exe, "check", "--format", "json"], cwd=folder, capture_output=True, text=True, timeout=60)
    assert r.returncode == (1 if code.startswith("E") else 0), r.stderr
    if code.startswith("W"):  # a warning fails the check of a pre-commit hook (--strict)
        strict = subprocess.run([exe, "check", "--strict"], cwd=folder, capture_output=True, text=True, timeout=60)
        assert strict.returncode == 1, strict.stdout + strict.stderr
    import json

    found = json.loads(r.stdout)
    found = found["diagnostics"] if isinstance(found, dict) else found
    expected = {}
    for path in configs:
        m = re.search(r"# expect: ([EWN][0-9]{3}) ([0-9]+):([0-9]+)", path.read_text(encoding="utf-8"))
        assert m and m.group(1) == code, f"{path.name}: `# expect: {code} LINE:COL`"
        expected[path.name] = (int(m.group(2)), int(m.group(3)))
    for path in configs:
        mine = [d for d in found if Path(d["file"]).name == path.name and d["code"] == code]
        assert [(d["line"], d["column"]) for d in mine] == [expected[path.name]], (path.name, found)
        # the other config named at its own position (the value there, as here)
        others = [f"{o}:{line}:{column}" for o, (line, column) in expected.items() if o != path.name]
        assert any(o in mine[0]["message"] for o in others), (mine[0]["message"], others)
    assert sorted(p.name for p in folder.iterdir()) == sorted(p.name for p in configs)


def test_corpora_are_there():
    assert len(INVALID) >= 40
    assert len(LEGACY) == 7, "the legacy configs are read from ../shared/legacy"
    assert len(EXAMPLES) >= 6


@pytest.mark.parametrize("path", INVALID, ids=lambda p: p.stem)
def test_invalid_config_exact_code_and_position(path: Path):
    head = path.read_bytes().decode("utf-8", "replace")
    m = re.search(r"# expect: ([EWN][0-9]{3}) ([0-9]+):([0-9]+)", head)
    assert m, f"{path.name} has no `# expect: CODE LINE:COL` line"
    code, line, col = m.group(1), int(m.group(2)), int(m.group(3))
    backend = re.search(r"# backend: (\S+)", head)
    yarp = re.search(r"# yarp: (\S+)", head)
    msg_path = re.search(r"# msg-path: (\S+)", head)  # relative to tests/
    options = Options(yarp=yarp.group(1) if yarp else None,
                      msg_path=(str(path.parent.parent / msg_path.group(1)),) if msg_path else ())
    result = compile_path(path, options)
    if backend:
        result = check_result(result, backend.group(1))
    shown = [d for d in result.diagnostics if d.severity.value != "note" or code.startswith("N")]
    assert shown, f"{path.name}: no diagnostic at all"
    first = shown[0]
    assert (first.code, first.span.line, first.span.column) == (code, line, col), \
        f"{path.name}: got {first.code} at {first.span.line}:{first.span.column}: {first.message}"
    assert first.message and first.file == str(path)
    if code.startswith("E"):
        assert result.program is None
    # the code named in the file name is the one found
    assert path.stem.split("_")[0] == code


@pytest.mark.parametrize("path", LEGACY, ids=lambda p: p.stem)
def test_legacy_config_checks(path: Path):
    result = compile_path(path)
    assert not result.errors, [f"{d.code} {d.message}" for d in result.errors]
    assert result.program is not None
    assert result.form == "legacy"
    assert {d.code for d in result.warnings} == LEGACY_WARNINGS.get(path.name, set())


@pytest.mark.parametrize("path", LEGACY, ids=lambda p: p.stem)
def test_legacy_to_named_gives_the_same_ir(path: Path):
    direct = compile_path(path).program
    named_text, _ = _formatted(str(path), argparse.Namespace(to="named", ros2=False), Options())
    assert named_text is not None
    converted = compile_text(named_text, str(path))
    assert converted.form == "named"
    assert not converted.errors
    assert converted.program == direct
    # and the conversion is already canonical
    sink = Sink()
    assert format_document(parse_text(named_text, sink)) == named_text


def test_thesis_figure5_layout():
    p = compile_path(LEGACY_DIR / "thesis_figure5_rviz.ini").program
    assert p.output == ir.Output("ros1", "/yarp/joint_states", "sensor_msgs/JointState",
                                 "/yarp/thesis_figure5_rviz", None, None)
    header, name, position, velocity, effort = p.message.fields
    assert [f.name for f in header.source.fields] == ["seq", "stamp", "frame_id"]
    assert header.source.fields[0].source == ir.Counter("uint32")
    assert header.source.fields[1].source == ir.Timestamp("wall", None, "ros1")
    assert header.source.fields[2].source == ir.Literal(("0",), "string", False)
    assert len(name.source.values) == 8 and name.source.values[4] == "l_elbow_flection_joint"
    assert position.source == ir.MuxRef("mux1", 0, None, None, False, "float64")
    # empty lists typed from the .msg, not untyped
    assert velocity.source == ir.Literal((), "float64", True)
    assert effort.type == ir.TypeRef("float64", "sequence")
    conv = p.muxes[0].converters[0]
    assert conv.name == "deg_to_rad" and conv.scale == pytest.approx(0.017453292519943295, rel=0, abs=1e-18)
    assert p.timing.rate is None  # no rate: event-driven


def test_legacy_yarp_output_layout():
    """to_ros = false: mux elements are appended flat, as the original did."""
    p = compile_path(LEGACY_DIR / "tutorial_example_ros_yarp.ini").program
    assert p.output.kind == "yarp" and p.output.connect_to == "/fakebot/motor/rpc:i"
    a, b, c = p.message.fields
    assert a.source == ir.Literal(("set",), "string", False)
    assert b.source == ir.Literal(("pos",), "string", False)
    assert c.source.splice is True
    assert p.muxes[0].inputs[0].kind == "ros1"  # from_ros_topics


def test_legacy_to_ros2_conversion_drops_seq():
    text, _ = _formatted(str(LEGACY_DIR / "thesis_figure5_rviz.ini"),
                         argparse.Namespace(to="named", ros2=True), Options())
    assert "header.seq" not in text.split("# dropped")[-1].split("\n", 1)[1]
    assert "# dropped `header.seq`" in text
    r = check_result(compile_text(text, "thesis_figure5_rviz.ini"), "ros2")
    assert not r.errors, r.errors
    assert r.program.output.kind == "ros2"
    assert r.program.message.fields[0].source.fields[0].source.style == "ros2"


@pytest.mark.parametrize("path", EXAMPLES, ids=lambda p: str(p.relative_to(ROOT / "examples")))
def test_example_checks_clean_and_is_canonical(path: Path):
    result = compile_path(path, EXAMPLE_OPTIONS)
    assert result.form == "named"
    assert not result.errors and not result.warnings, result.diagnostics
    text = path.read_text(encoding="utf-8")
    assert format_document(parse_text(text, Sink())) == text, "examples are in canonical form"


def test_every_example_passes_its_own_check_command(ybgc, monkeypatch):
    """The commands scripts/demo.sh runs (tests/harness/examples.py): each
    single example by `ybgc check` or by the command its header gives, each
    robot's folder together; clean, warnings failing too. An example that
    needs an option its header does not give fails here."""
    monkeypatch.chdir(ROOT)
    commands = examples.check_commands()
    named = [ROOT / a for args in commands for a in args if not a.startswith("-")]
    checked = {c for n in named for c in (n.glob("*.ini") if n.is_dir() else [n])}
    assert set(examples.configs()) <= checked  # every example, by some command
    for args in commands:
        status, err = ybgc(*args, "--strict")
        assert (status, err) == (0, ""), ("ybgc " + " ".join(args), err)


def test_an_example_without_its_options_fails_its_plain_check(ybgc, monkeypatch):
    """The command of an example's own check is needed: without its
    options, the plain `ybgc check` of that example fails."""
    monkeypatch.chdir(ROOT)
    own = [p for p in EXAMPLES if examples.own_check(p) is not None]
    assert own, "some example documents a check of its own (gaze_look_at.ini: --msg-path msgpkgs)"
    for path in own:
        status, err = ybgc("check", str(path.relative_to(ROOT)))
        assert status == 1 and " error " in err, err


@pytest.mark.parametrize("path", EXAMPLES + LEGACY, ids=lambda p: str(p.relative_to(p.parents[1])))
def test_ir_json_round_trip(path: Path):
    p = compile_path(path, EXAMPLE_OPTIONS).program
    assert ir.from_json(ir.to_json(p)) == p


def _agreement_corpus() -> list[tuple[str, str]]:
    """(name, text) of every example, every legacy config (in ../shared/legacy
    and its folders, and the original's history in tests/legacy_history),
    and the named forms that `ybgc fmt --to named` and `--to named --ros2`
    make of them."""
    legacy = sorted(LEGACY_DIR.rglob("*.ini")) + sorted((ROOT / "tests" / "legacy_history").glob("*.ini"))
    out = [(p.name, p.read_text(encoding="utf-8")) for p in EXAMPLES + legacy]
    for p in legacy:
        for ros2 in (False, True):
            text, _ = _formatted(str(p), argparse.Namespace(to="named", ros2=ros2), Options())
            if text is not None:
                out.append((f"{p.stem}_named{'_ros2' if ros2 else ''}.ini", text))
    return out


def test_legacy_to_ros2_needs_the_definition_of_the_type():
    """On ROS 2 a message is built field by field, named from its
    definition, and the legacy fields are matched to it by position: without
    the definition (a custom message of the original's tutorial) the
    conversion refuses (E321, at `ros_msg_name`) and writes nothing; with
    `--msg-path` it converts into a config the ros2 backend builds."""
    path = LEGACY_DIR / "tutorial_example_yarp_ros.ini"
    args = argparse.Namespace(to="named", ros2=True)
    text, result = _formatted(str(path), args, Options())
    assert text is None
    assert [(d.code, d.span.line, d.span.column) for d in result.errors] == [("E321", 6, 16)]
    assert "--msg-path" in result.errors[0].hint
    options = Options(msg_path=(str(ROOT / "msgpkgs"),))
    text, _ = _formatted(str(path), args, options)
    assert "type = ybg_demo_msgs/MotorsInertial" in text and "motors = mux1" in text
    assert not check_result(compile_text(text, path.name, options), "ros2").errors


@pytest.mark.parametrize("backend", backend_names())
def test_check_and_generate_agree(backend: str):
    """For each backend: every config of the corpora that `ybgc check
    --backend B` passes generates (rendered, not built), and every config
    that B's generation refuses is refused by the check, with a code and a
    position."""
    generated, refused = [], []
    for name, text in _agreement_corpus():
        front = compile_text(text, name)
        checked = check_result(front, backend)
        lowering_refuses = None
        if front.program is not None:
            try:
                get_backend(backend).render(front.program)
            except LoweringError as e:
                lowering_refuses = e
        if checked.program is not None:
            assert not checked.errors
            assert lowering_refuses is None, f"{name}: checks for {backend}, but: {lowering_refuses}"
            for options in (RenderOptions(), RenderOptions(package=True), RenderOptions(single_file=True)):
                assert get_backend(backend).render(checked.program, options), name
            generated.append(name)
            continue
        assert checked.errors, name
        for d in checked.errors:
            assert d.code in CODES and d.file == name and d.span.line >= 1 and d.span.column >= 1, (name, d)
            assert d.hint, (name, d)
        refused.append((name, checked.errors[0].code))
    # not vacuous: each backend builds part of the corpus and refuses another part
    assert generated and refused, (generated, refused)
    if backend == "ros2":
        assert ("tutorial_example_yarp_ros.ini", "E318") in refused
        assert "thesis_figure5_rviz_named_ros2.ini" in generated
    else:
        assert {p.name for p in LEGACY} <= set(generated)


@pytest.mark.parametrize("typo, code", [
    (("num_fiels = 2", "num_fields = 2"), "E202"),  # the original's own README has it
    (("1_typ = msg\n1_msg = position", "1_type = msg\n1_msg = position"), "E202"),
    (("2_type = mesg\n2_msg = orientation", "2_type = msg\n2_msg = orientation"), "E210"),
])
def test_a_misspelt_key_is_one_error(typo, code):
    """A misspelt key of a legacy file is reported once: not again as the
    key that is missing, nor as the sections it no longer reaches (E201)."""
    path = ROOT / "tests" / "invalid" / "E202_num_fields_misspelt.ini"
    wrong, right = typo
    text = path.read_text(encoding="utf-8").replace("num_fiels = 2", "num_fields = 2").replace(right, wrong)
    assert wrong in text
    assert [d.code for d in compile_text(text, path.name).errors] == [code]
    for key, misspelt in (("num_mux", "num_muxes"), ("num_ports", "num_port"), ("output_name", "outputname")):
        text2 = path.read_text(encoding="utf-8").replace("num_fiels", "num_fields").replace(f"{key} =", f"{misspelt} =")
        assert [d.code for d in compile_text(text2, path.name).errors] == ["E202"], key


FINGERTIPS = """\
[output]
topic = /fingertips
type = hand_msgs/Fingertips
via = ros2
rate = 10

[mux thumb]
ports = /hand/thumb:o (float64 x3)

[message]
tips[3].y = 0.25
tips[0] = thumb
grasps[0].orientation.w = 1.0
"""


def test_fixed_and_bounded_arrays_of_messages():
    """A fixed-size array of messages has its size, the elements not given
    their defaults; a bounded one the elements given; the ros2 node makes
    them and fills what the config sets."""
    result = compile_text(FINGERTIPS, "fingertips.ini",
                          Options(msg_path=(str(ROOT / "tests" / "msgs"),)))
    assert not result.errors, result.errors
    fields = {f.name: f.source for f in result.program.message.fields}
    tips, grasps = fields["tips"], fields["grasps"]
    assert isinstance(tips, ir.MessageArray) and tips.msg_type == "geometry_msgs/Point"
    assert len(tips.elements) == 5
    assert tips.elements[0] == ir.MuxRef("thumb", 0, None, None, False, "float64", ("x", "y", "z"),
                                         ("float64",) * 3)
    assert [f.source for f in tips.elements[3].fields] == [ir.Default(), ir.Literal((0.25,), "float64"),
                                                          ir.Default()]
    assert all(isinstance(f.source, ir.Default) for e in tips.elements[1:3] for f in e.fields)
    assert isinstance(grasps, ir.MessageArray) and len(grasps.elements) == 1
    node = "\n".join(text for name, text in get_backend("ros2").render(result.program).items()
                     if name.endswith("_node.py"))
    assert "msg.tips = [ros_geometry_msgs_Point() for _ in range(5)]" in node
    assert "msg.tips[0].x = float(v['thumb'][0])" in node and "msg.tips[3].y = 0.25" in node
    assert "msg.grasps = [ros_geometry_msgs_Pose() for _ in range(1)]" in node
    compile(node, "node.py", "exec")
    assert ir.from_json(ir.to_json(result.program)) == result.program
