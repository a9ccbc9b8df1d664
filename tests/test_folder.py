"""The folder's config: every command run with no config named, through the
real ``ybgc`` command in a temporary folder, takes ``ybgc.ini``, else the one
ybgc config of the folder (foreign ``.ini`` files skipped as the pre-commit
hook skips them); none or several is a clear usage error; ``ybgc check``
with no file checks every config of the folder."""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from harness.generated import YBGC

ROOT = Path(__file__).resolve().parent.parent
HAND = ROOT / "examples" / "mixed_types_yarp.ini"  # module `hand_status`
IMU = ROOT / "examples" / "imu_ros2.ini"
EFFECTOR = ROOT / "examples" / "yarp_to_yarp_end_effector.ini"
FIGURE5 = ROOT.parent / "shared" / "legacy" / "thesis_figure5_rviz.ini"  # legacy, warns W504
BAD = ROOT / "tests" / "invalid" / "E313_unknown_converter.ini"

#: .ini files of a robot's repository that are not ybgc configs
FOREIGN = {
    "icub_robot.ini": "[GENERAL]\nname icub\nparts (left_arm right_arm)\n",
    "yarpmanager.ini": "[general]\nrate 10\n",  # a [general] section but no [message]
    "message_only.ini": "[message]\ntext hello\n",  # a [message] section alone
}

#: every command that takes one config, as run with none named
ONE_CONFIG = {
    "generate": ["--backend", "py"],  # the design card's `ybgc --backend py`
    "ir": ["ir"],
    "fmt": ["fmt", "--check"],
    "graph": ["graph", "--format", "dot"],
}


def ybgc_in(folder: Path, *args) -> subprocess.CompletedProcess:
    """The ybgc command run in ``folder``, as a user runs it there."""
    return subprocess.run([str(YBGC), *map(str, args)], capture_output=True, text=True, cwd=folder,
                          timeout=60)


def folder(tmp_path: Path, *configs: Path, foreign: bool = True, **named: Path) -> Path:
    """A folder holding copies of ``configs`` (``named``: under another
    name), and the foreign files."""
    for c in configs:
        shutil.copy(c, tmp_path / c.name)
    for name, c in named.items():
        shutil.copy(c, tmp_path / f"{name}.ini")
    if foreign:
        for name, text in FOREIGN.items():
            (tmp_path / name).write_text(text, encoding="utf-8")
    return tmp_path


def test_foreign_files_are_those_the_pre_commit_hook_skips(tmp_path):
    """The folder's config is chosen by the rule the hook uses: each file
    skipped here is skipped by the hook's own command, and would be an
    error if it were checked."""
    d = folder(tmp_path)
    entry = {h["id"]: h for h in yaml.safe_load((ROOT / ".pre-commit-hooks.yaml").read_text())}["ybgc-check"]
    r = ybgc_in(d, *entry["entry"].split()[1:], *FOREIGN)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    r = ybgc_in(d, "check", *FOREIGN)
    assert r.returncode == 1
    assert all(f"{name}:" in r.stderr for name in FOREIGN), r.stderr


def test_every_command_takes_the_one_config_of_the_folder(tmp_path):
    d = folder(tmp_path, HAND)
    r = ybgc_in(d, *ONE_CONFIG["generate"])
    assert r.returncode == 0, r.stderr
    assert (d / "hand_status" / "hand_status.py").is_file()
    r = ybgc_in(d, *ONE_CONFIG["ir"])
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["module"] == "hand_status"
    assert ybgc_in(d, *ONE_CONFIG["fmt"]).returncode == 0
    r = ybgc_in(d, *ONE_CONFIG["graph"])
    assert r.returncode == 0 and "/icub/left_hand/status:o" in r.stdout, r.stderr
    r = ybgc_in(d, "graph")  # svg into ./<module>.svg
    assert r.returncode == 0 and (d / "hand_status.svg").is_file(), r.stderr
    r = ybgc_in(d, "check")
    assert r.returncode == 0 and r.stderr == "", r.stderr


def test_fmt_rewrites_the_folder_config_in_place(tmp_path):
    d = folder(tmp_path, foreign=False, bridge=HAND)
    (d / "bridge.ini").write_text(HAND.read_text().replace("trigger = any", "trigger   =   any"))
    assert ybgc_in(d, "fmt", "--check").returncode == 1
    r = ybgc_in(d, "fmt")
    assert r.returncode == 0 and "bridge.ini: reformatted" in r.stderr, r.stderr
    assert "trigger = any" in (d / "bridge.ini").read_text()
    assert ybgc_in(d, "fmt", "--check").returncode == 0


def test_ybgc_ini_is_taken_before_the_others(tmp_path):
    d = folder(tmp_path, HAND, ybgc=EFFECTOR)
    for command, args in ONE_CONFIG.items():
        r = ybgc_in(d, *args)
        if command == "ir":
            assert json.loads(r.stdout)["source"] == "ybgc.ini"
        assert r.returncode == 0, (command, r.stderr)
        assert "hand" not in r.stderr, (command, r.stderr)


def test_several_configs_is_a_clear_error_naming_them(tmp_path):
    d = folder(tmp_path, HAND, IMU)
    before = sorted(p.name for p in d.iterdir())
    for command, args in ONE_CONFIG.items():
        if command == "graph":  # the robot's graph (test_a_folder_is_a_robot)
            continue
        r = ybgc_in(d, *args)
        assert r.returncode == 2, (command, r.stderr)
        assert "2 ybgc configs" in r.stderr and "imu_ros2.ini" in r.stderr and "mixed_types_yarp.ini" in r.stderr
        assert "hint: name the one to use" in r.stderr and "ybgc.ini" in r.stderr
        assert not any(name in r.stderr for name in FOREIGN), r.stderr
        assert "Traceback" not in r.stderr and r.stdout == ""
    assert sorted(p.name for p in d.iterdir()) == before  # nothing written


def test_no_config_is_a_clear_error(tmp_path):
    d = folder(tmp_path)
    for args in [*ONE_CONFIG.values(), ["check"]]:
        r = ybgc_in(d, *args)
        assert r.returncode == 2, (args, r.stderr)
        assert "no config named, and no ybgc config in" in r.stderr and "hint: name the config" in r.stderr
        assert "Traceback" not in r.stderr


def test_check_with_no_file_checks_every_config_of_the_folder(tmp_path):
    d = folder(tmp_path, FIGURE5, BAD, HAND)
    r = ybgc_in(d, "check")
    assert r.returncode == 1, r.stderr
    assert "thesis_figure5_rviz.ini:1:1: warning W504" in r.stderr
    assert "E313_unknown_converter.ini:9:11: error E313" in r.stderr
    assert not any(name in r.stderr for name in FOREIGN), r.stderr
    r = ybgc_in(d, "check", "--format", "json")
    assert {p["file"] for p in json.loads(r.stdout)} >= {"thesis_figure5_rviz.ini", "E313_unknown_converter.ini"}
    (d / BAD.name).unlink()
    assert ybgc_in(d, "check").returncode == 0
    assert ybgc_in(d, "check", "--strict").returncode == 1  # the legacy file's warnings


@pytest.mark.parametrize("args, message", [
    (["generate"], "the following arguments are required: --backend"),
    (["check", "--format", "xml"], "invalid choice: 'xml'"),
    (["graph", "--format", "png"], "invalid choice: 'png'"),
    (["--backend", "java"], "invalid choice: 'java'"),
])
def test_argparse_usage_errors_stay(tmp_path, args, message):
    r = ybgc_in(folder(tmp_path, HAND), *args)
    assert r.returncode == 2 and message in r.stderr, r.stderr


def test_a_named_config_is_used_whatever_the_folder_holds(tmp_path):
    d = folder(tmp_path, HAND, IMU)
    r = ybgc_in(d, "ir", "imu_ros2.ini")
    assert r.returncode == 0 and json.loads(r.stdout)["source"] == "imu_ros2.ini", r.stderr
    r = ybgc_in(d, "ir", "missing.ini")
    assert r.returncode == 2 and "missing.ini" in r.stderr and "Traceback" not in r.stderr


# --------------------------------------------------------------------------
# A folder named is a robot: its configs, as if each were named

ICUB = ROOT / "examples" / "icub_robot"
HOMING = ROOT / "examples" / "home_arm_trigger.ini"


def test_check_of_a_robot_folder_and_a_folder_with_a_file(tmp_path):
    """`ybgc check examples/icub_robot` checks its 14 configs, as `ybgc
    check` does in that folder; a folder and a file mixed check together,
    across configs too; a folder with no config is a usage error."""
    for args in (["check", "examples/icub_robot"], ["check", "examples/icub_robot/"],
                 ["check", "examples/icub_robot", "examples/home_arm_trigger.ini"],
                 ["check", "--strict", "--skip-foreign", "examples/icub_robot"]):
        r = ybgc_in(ROOT, *args)
        assert (r.returncode, r.stdout, r.stderr) == (0, "", ""), (args, r.stderr)
    r = ybgc_in(ROOT, "check", "--format", "json", "examples/icub_robot", "examples/home_arm_trigger.ini")
    assert (r.returncode, r.stdout) == (0, "[]\n"), r.stderr
    # a copy of one of its bridges beside the folder: the clash said in both, at the values
    shutil.copytree(ICUB, tmp_path / "robot")
    shutil.copy(ICUB / "head.ini", tmp_path / "twin.ini")
    r = ybgc_in(tmp_path, "check", "robot", "twin.ini")
    assert r.returncode == 1
    hint = ("    hint: two bridges of one name open the same ports (`/<name>/rpc:i` ...) and the same ROS node: give "
            "each its own `name` in [module]")
    assert r.stderr.splitlines() == [
        "robot/head.ini:5:8: error E362 module `icub_head` is also the name of another bridge (twin.ini:5:8)", hint,
        "twin.ini:5:8: error E362 module `icub_head` is also the name of another bridge (robot/head.ini:5:8)", hint,
    ], r.stderr
    empty = tmp_path / "empty"
    empty.mkdir()
    r = ybgc_in(tmp_path, "check", "empty", "twin.ini")
    assert r.returncode == 2 and r.stderr == (
        "ybgc: error: no ybgc config in the folder empty (no .ini file there has a [message] section and an "
        "[output] or [general] one, nor [service] or [action] sections)\n"
        "    hint: name the configs: ybgc check empty/config.ini\n"), r.stderr


def test_compose_of_a_robot_folder_and_a_file(tmp_path):
    """`ybgc compose examples/icub_robot` composes the folder's 14 bridges
    into a module named after the folder, the same files as `ybgc compose`
    in the folder; with a file beside the folder, 15 bridges."""
    r = ybgc_in(tmp_path, "compose", ICUB, "--backend", "ros2", "-o", "named")
    written = sorted(p.relative_to(tmp_path / "named") for p in (tmp_path / "named").rglob("*") if p.is_file())
    assert (r.returncode, r.stdout) == (0, ""), r.stderr
    assert r.stderr == (f"ybgc: ros2 module `icub_robot` of 14 bridges in named/ "
                        f"({len(written)} files written, 0 unchanged)\n"), r.stderr
    here = ybgc_in(ICUB, "compose", "--backend", "ros2", "-o", tmp_path / "here")
    assert here.returncode == 0, here.stderr
    in_folder = sorted(p.relative_to(tmp_path / "here") for p in (tmp_path / "here").rglob("*") if p.is_file())
    assert in_folder == written
    node = "icub_robot_node.py"
    assert (tmp_path / "named" / node).read_text() == (tmp_path / "here" / node).read_text()
    r = ybgc_in(tmp_path, "compose", ICUB, HOMING, "--backend", "ros2", "-o", "mixed")
    assert r.returncode == 0 and "`icub_robot` of 15 bridges in mixed/" in r.stderr, r.stderr
    assert "left_arm_homing" in (tmp_path / "mixed" / node).read_text()


def test_graph_of_a_robot_folder(tmp_path):
    """`ybgc graph DIR`: every bridge of the robot in one picture, a box
    (cluster, subgraph) a bridge, each port read once; the same picture
    as `ybgc graph` in the folder, and as the configs named one by one."""
    configs = sorted(ICUB.glob("*.ini"))
    r = ybgc_in(tmp_path, "graph", ICUB, "--format", "dot")
    assert r.returncode == 0, r.stderr
    dot = r.stdout.splitlines()
    assert dot[:2] == [f"// generated by ybgc from {ICUB}: the dataflow of module icub_robot",
                       'digraph "icub_robot" {']
    clusters = [line for line in dot if line.startswith("  subgraph cluster_bridge")]
    assert len(clusters) == len(configs) == 14
    modules = [line.split('"')[1] for line in dot if line.startswith('    label="')]
    assert modules == [program_module(c) for c in configs]
    ports = [line for line in dot if re.match(r"  in[0-9]+ \[label=", line)]
    assert len(ports) == len({line.split('"')[1].split("\\n")[0] for line in ports}) == 15
    here = ybgc_in(ICUB, "graph", "--format", "dot")
    assert here.stdout.splitlines()[1:] == dot[1:], here.stderr
    each = ybgc_in(tmp_path, "graph", *configs, "--format", "dot")
    assert each.stdout.splitlines()[1:] == dot[1:], each.stderr
    r = ybgc_in(tmp_path, "graph", ICUB, HOMING, "--format", "mermaid")
    assert r.returncode == 0 and r.stdout.count("  subgraph bridge") == 15, r.stderr
    r = ybgc_in(tmp_path, "graph", ICUB)  # a picture: ./<robot>.svg
    assert r.stderr == "ybgc: svg graph of `icub_robot` (14 bridges) in icub_robot.svg\n"
    assert (tmp_path / "icub_robot.svg").read_text().count('<g class="node output"') == 14


def test_commands_of_one_config_take_a_folders_one_config(tmp_path):
    """`ybgc ir DIR`, `ybgc DIR --backend B`: the folder's one config (its
    ybgc.ini first); several: the error names them and, for a module, the
    compose command of the folder."""
    one = tmp_path / "one"
    one.mkdir()
    folder(one, HAND)
    r = ybgc_in(tmp_path, "ir", "one")
    assert r.returncode == 0 and json.loads(r.stdout)["module"] == "hand_status", r.stderr
    r = ybgc_in(tmp_path, "one", "--backend", "py", "-o", "out")
    assert r.returncode == 0 and (tmp_path / "out" / "hand_status.py").is_file(), r.stderr
    r = ybgc_in(tmp_path, ICUB, "--backend", "cpp")
    assert r.returncode == 2
    assert r.stderr.startswith(f"ybgc: error: the folder {ICUB} has 14 ybgc configs: {ICUB}/ft_left_arm.ini, "), r.stderr
    assert r.stderr.endswith(f"hint: name the one to use (ybgc {ICUB}/ft_left_arm.ini --backend cpp), or call it "
                             f"ybgc.ini; for all of them as one module: ybgc compose {ICUB} --backend cpp\n")


def program_module(path: Path) -> str:
    from ybg.compiler.pipeline import compile_path

    return compile_path(path).program.module
