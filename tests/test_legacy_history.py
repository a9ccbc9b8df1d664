"""The original tool's configs from its git history (tests/legacy_history/):
each file in one of its first layouts gets one diagnostic that names the
layout, E217 or W512, and the hint, followed as written, brings it closer
to a valid config; Vizzy's configs of July 2015, which name no message type,
convert for ROS 2 with the type their topic names; converting a file that
mixes the two forms loses none of its keys."""

from __future__ import annotations

import re
import shlex
import shutil
from pathlib import Path

import pytest

from ybg.backends import check_result
from ybg.compiler.pipeline import compile_path, compile_text

ROOT = Path(__file__).resolve().parent.parent
HISTORY = ROOT / "tests" / "legacy_history"
EARLY = sorted(HISTORY.glob("config_*.ini"))
VIZZY = sorted(HISTORY.glob("vizzy_*.ini"))
INVALID = ROOT / "tests" / "invalid"

#: the day the original tool first built a message from [message] (commit 6b88a40,
#: BottleCreatorGenerator); before it, [message] and [type] were notes it did not read
FIRST_MESSAGE = "2015-03-13"


def _hint_command(hint: str, config: str) -> list[str]:
    """The `ybgc fmt ...` command quoted in ``hint``, `FILE` replaced by
    ``config``, as arguments of ``cli.main``."""
    (command,) = re.findall(r"`(ybgc fmt [^`]*)`", hint)
    words = [config if w == "FILE" else w for w in shlex.split(command)]
    assert words[0] == "ybgc" and config in words, command
    return words[1:]


def _errors(result) -> list[tuple[str, int, int]]:
    return [(d.code, d.span.line, d.span.column) for d in result.errors]


def test_the_history_is_there():
    assert len(EARLY) == 18, "the 18 versions of the original's config.ini in its first layouts"
    assert len(VIZZY) == 3


@pytest.mark.parametrize("path", EARLY, ids=lambda p: p.stem)
def test_an_early_layout_gets_one_diagnostic_that_names_it(path: Path, tmp_path, ybgc):
    """One diagnostic names the layout, at its first section: E217 for a
    file from before the original read a [message] (nothing else is
    reported), W512 for one from after (the file is read). None of the codes
    of a misread file (a named mux without its name, missing sections,
    unknown sections, text into numbers)."""
    text = path.read_text(encoding="utf-8")
    first = next(i for i, line in enumerate(text.splitlines(), 1)
                 if re.fullmatch(r"\[(mux|mux_general|converter[0-9]*)\]", line.strip()))
    r = compile_path(path)
    layout = [d for d in r.diagnostics if d.code in ("E217", "W512")]
    assert [(d.code, d.span.line, d.span.column) for d in layout] == \
        [("E217" if path.stem.split("_")[1] < FIRST_MESSAGE else "W512", first, 1)]
    (d,) = layout
    assert "original tool's" in d.message and ("first layout" in d.message or "March to May 2015" in d.message)
    assert not {"E104", "E201", "E203", "E304"} & {x.code for x in r.diagnostics}, r.diagnostics
    assert r.form == "legacy"
    if d.code == "E217":
        assert [x.code for x in r.diagnostics if x.severity.value != "note"] == ["E217"]
        assert "[message]" in d.hint and "num_fields" in d.hint and "ybgc fmt" not in d.hint
        # fmt refuses with the same one error, writing nothing
        shutil.copy(path, tmp_path / path.name)
        status, err = ybgc("fmt", "--to", "named", path.name, "-o", "out.ini")
        assert status == 1 and f"{path.name}:{first}:1: error E217" in err
        assert not (tmp_path / "out.ini").exists()
        return
    # W512: the hint's command, run as written, converts the file; the converted file has no W512,
    # and exactly the errors the file had, those its conversion uncovers (placeholder port names of
    # the original's README: E401); a conversion that stops does so at an error the check reports
    shutil.copy(path, tmp_path / path.name)
    words = _hint_command(d.hint, path.name)
    target = tmp_path / words[words.index("-o") + 1]
    status, err = ybgc(*words)
    if status != 0:
        assert not target.exists()
        refused = {(code, int(line)) for line, code in re.findall(r":([0-9]+):[0-9]+: error (E[0-9]{3})", err)}
        assert {(c, line) for c, line, _ in _errors(r)} == refused
        assert r.errors and all(x.code.startswith("E2") for x in r.errors)
        return
    assert target.name == f"{path.stem}.named.ini"
    assert (tmp_path / path.name).read_bytes() == path.read_bytes()
    converted = compile_text(target.read_text(encoding="utf-8"), str(path))
    assert converted.form == "named"
    assert "W512" not in {x.code for x in converted.diagnostics}
    assert sorted(x.code for x in converted.errors) == sorted(x.code for x in r.errors)
    assert all(x.code == "E401" for x in converted.errors), converted.errors
    if not r.errors:
        assert converted.program == r.program  # the file is read as its conversion says


def test_the_early_layouts_are_read_as_the_later_layout():
    """What W512 says the reading does, in the IR: [mux_general]'s keys and
    the converters moved, the output the ROS 1 topic those versions
    published, event-driven; the unnumbered [mux] is mux1, its converter
    with it."""
    p = compile_path(INVALID / "W512_mux_general_without_general.ini").program
    assert (p.output.kind, p.output.name, p.output.msg_type) == ("ros1", "/vizzy/joint_states",
                                                                   "sensor_msgs/JointState")
    assert p.timing.rate is None
    (mux,) = p.muxes
    assert [i.name for i in mux.inputs] == ["/vizzySim/torso/state:o", "/vizzySim/left_shoulder_arm/state:o"]
    assert [c.name for c in mux.converters] == ["deg_to_rad"] and mux.verbose
    p = compile_path(INVALID / "W512_unnumbered_mux.ini").program
    assert (p.output.kind, p.output.name) == ("ros1", "/head_joint_states")
    (mux,) = p.muxes
    assert mux.name == "mux1" and [c.name for c in mux.converters] == ["deg_to_rad"] and not mux.verbose
    assert p.message.fields[2].source.mux == "mux1"  # `3_mux = mux`


def test_an_early_layout_with_a_key_twice_or_astray_is_an_error_where_it_is():
    """Moving the keys of the first layouts to where the later layout has
    them never drops one: given both ways, or in a section that has no
    place for it, it is an error at its line."""
    path = INVALID / "W512_mux_general_without_general.ini"
    text = path.read_text(encoding="utf-8")
    twice = text.replace("[mux1]\n", "[mux1]\nfunction = none\n")
    assert _errors(compile_text(twice, path.name)) == [("E206", 13, 1)]  # function of [converter1], line 13
    astray = text.replace("output_name = /vizzy/joint_states\n", "output_name = /vizzy/joint_states\nports = /a:o\n")
    assert [(c, line) for c, line, _ in _errors(compile_text(astray, path.name))] == [("E202", 6)]
    both = "[general]\noutput_name = /other\n\n" + text
    assert [(c, line) for c, line, _ in _errors(compile_text(both, path.name))] == [("E206", 8)]


@pytest.mark.parametrize("path", VIZZY, ids=lambda p: p.stem)
def test_vizzy_of_july_2015_converts_for_ros2_as_e318_says(path: Path, tmp_path, ybgc):
    """No `ros_msg_name`: the type is inferred from the topic name
    (`/head_joint_states`: JointState) and the fields; E318's hint for
    `--backend ros2`, run as written, writes a config the ros2 backend
    builds, header.seq dropped and said so."""
    r = check_result(compile_path(path), "ros2")
    assert [d.code for d in r.warnings] == ["W504", "W505"]
    (e318,) = r.errors
    assert e318.code == "E318"
    shutil.copy(path, tmp_path / path.name)
    words = _hint_command(e318.hint, path.name)
    assert "--ros2" in words
    status, err = ybgc(*words)
    assert status == 0, err
    target = tmp_path / words[words.index("-o") + 1]
    text = target.read_text(encoding="utf-8")
    assert "type = sensor_msgs/JointState" in text and "# dropped `header.seq`" in text
    converted = check_result(compile_text(text, target.name), "ros2")
    assert not converted.errors and not converted.warnings, converted.diagnostics
    header, name, position, _, _ = converted.program.message.fields
    assert [f.name for f in header.source.fields] == ["stamp", "frame_id"]
    assert len(name.source.values) == len(re.findall(r'"[a-z_]+_joint"', path.read_text(encoding="utf-8")))
    assert position.source.mux == "mux1"


def test_a_type_that_cannot_be_inferred_is_asked_for_before_converting(tmp_path, ybgc):
    """A topic name that names no type: the ROS 1 output is read unchecked
    (W503); for ROS 2, E318's hint asks for `ros_msg_name` first, the
    conversion refuses (E204) and writes nothing, and with the type given
    the command converts it into a config the ros2 backend builds."""
    source = VIZZY[0].read_text(encoding="utf-8").replace("output_name = /head_joint_states",
                                                          "output_name = /vizzy/head")
    config = tmp_path / "head.ini"
    config.write_text(source, encoding="utf-8")
    r = check_result(compile_path(config), "ros2")
    assert "W503" in {d.code for d in r.warnings}
    (e318,) = r.errors
    assert "`ros_msg_name = pkg/Name`" in e318.hint and not re.findall(r"`ybgc fmt [^`]*`", e318.hint)
    command = re.search(r"then (ybgc fmt [^;]*?) converts", e318.hint).group(1)
    words = [config.name if w == "FILE" else w for w in shlex.split(command)][1:]
    status, err = ybgc(*words)
    assert status == 1 and "head.ini:2:1: error E204" in err and "ros_msg_name" in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["head.ini"]
    config.write_text(source.replace("to_ros = true\n", "to_ros = true\nros_msg_name = sensor_msgs/JointState\n"),
                      encoding="utf-8")
    status, err = ybgc(*words)
    assert status == 0, err
    out = tmp_path / words[words.index("-o") + 1]
    assert not check_result(compile_text(out.read_text(encoding="utf-8"), out.name), "ros2").errors


@pytest.mark.parametrize("name", ["E207_mixed_forms.ini", "E207_named_key_in_legacy_file.ini"])
def test_converting_a_file_of_both_forms_keeps_every_key(name: str, tmp_path, ybgc):
    """E207: the legacy sections are converted and the named ones carried
    over, key by key. A key given both ways is then given twice, for the
    user to choose (E206, which the check of the mixed file reported too):
    strictly fewer errors, none lost."""
    path = INVALID / name
    shutil.copy(path, tmp_path / name)
    before = compile_path(tmp_path / name)
    assert before.errors[0].code == "E207"
    named_keys = []
    section = None
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("["):
            section = line
        elif section == "[output]" and "=" in line:
            named_keys.append(line.strip())
    assert named_keys
    status, err = ybgc("fmt", "--to", "named", name, "-o", "out.ini")
    assert status == 0, err
    text = (tmp_path / "out.ini").read_text(encoding="utf-8")
    output = text.split("[output]\n", 1)[1].split("\n\n", 1)[0].splitlines()
    assert all(k in output for k in named_keys), (named_keys, output)
    after = compile_text(text, "out.ini")
    assert len(after.errors) < len(before.errors)
    assert [d.code for d in after.errors] == [d.code for d in before.errors if d.code != "E207"]


def test_the_hints_of_ros2_conversions_name_a_file_of_their_own():
    """The commands of E318's and E319's hints write `<stem>.named.ini`:
    two configs converted in one folder never go into one file."""
    hints = []
    for config in ("thesis_figure5_rviz.ini", "fixation_point_goal.ini"):
        path = ROOT.parent / "shared" / "legacy" / config
        hints += [(config, d.hint) for d in check_result(compile_path(path), "ros2").errors]
    assert len(hints) == 2
    for config, hint in hints:
        (target,) = re.findall(r"-o (\S+?)`", hint)
        assert target == config.replace(".ini", ".named.ini")


def test_legacy_topics_declared_in_the_file_convert_for_ros2_in_one_command(tmp_path, ybgc):
    """A legacy file that declares the type of each topic it reads
    (`ports = /topic (pkg/Name)`): E318's hint for `--backend ros2` is the one
    command, and the config it writes the ros2 backend builds; undeclared,
    the hint's conversion is followed by declaring the types in the file it
    writes."""
    source = (ROOT.parent / "shared" / "legacy" / "fixation_point_goal.ini").read_text(encoding="utf-8")
    config = tmp_path / "goal.ini"
    config.write_text(source, encoding="utf-8")
    (e318,) = check_result(compile_path(config), "ros2").errors
    assert "--ros2" not in e318.hint and "declare each topic's type" in e318.hint
    config.write_text(source.replace("ports = /fixation_point_goal_ros",
                                     "ports = /fixation_point_goal_ros (geometry_msgs/Point)"), encoding="utf-8")
    (e318,) = check_result(compile_path(config), "ros2").errors
    words = _hint_command(e318.hint, config.name)
    assert "--ros2" in words
    status, err = ybgc(*words)
    assert status == 0, err
    out = tmp_path / words[words.index("-o") + 1]
    converted = check_result(compile_text(out.read_text(encoding="utf-8"), out.name), "ros2")
    assert not converted.errors, converted.errors
    assert converted.program.muxes[0].inputs[0].kind == "ros2"
