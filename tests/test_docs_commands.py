"""Every command README.md and docs/*.md give to paste is run by a test.

The commands are read from the text: each line of each ```sh block (a line
ending in a backslash joined with the next), split into its simple commands
at `&&`, `||`, `|` and `;`. Each simple command is either

- run here, as written: a `ybgc` command that needs no running middleware
  (check, fmt, ir, graph, generate, compose), in-process, in the folder its
  block starts in (the files it names there as the doc's text says: the
  repository's examples/ and msgpkgs/, a config the same page gives, those
  ``SETUPS`` lays out), after the block's commands before it (a `cd` moves
  the folder); it exits as the doc says (0 unless the doc says another
  status), and the files its comment promises (`-> vizzy/vizzy_node.py`,
  `./icub_robot.svg`) and its `-o` are there; or
- in ``RUN_ELSEWHERE``, which names the test that runs it (a build, a
  module run, a probe of a live robot), a test that exists.

A command of the documentation that is neither fails, so a command newly
documented cannot go untested; an entry of ``RUN_ELSEWHERE`` that no
command of the documentation matches fails too. Nothing here compiles C++
or starts middleware: tests/test_readme.py builds the quick start, the
tests named build and run the rest.
"""
from __future__ import annotations

import filecmp
import re
import shlex
import shutil
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from harness.markdown import ROOT, blocks, documents, fenced, name_of, numbered_commands, section
from ybg import cli

#: the ybgc commands run here: none of them asks the middleware
RUN_HERE = ("check", "fmt", "ir", "generate", "compose", "graph")


@dataclass(frozen=True)
class Command:
    """A simple command of a documented shell line."""

    doc: str
    line: int  # of the document, 1-based
    text: str  # the simple command, without the line's comment
    comment: str  # the line's comment, "" when none
    block: int  # the index of its block among the document's sh blocks

    def __str__(self) -> str:
        return f"{self.doc}:{self.line}: {self.text}"


def split_line(line: str) -> tuple[list[str], str]:
    """The simple commands of a shell line (split at `&&`, `||`, `|` and `;`
    outside quotes and `$(...)`), and its comment."""
    parts, current, quote, depth, i = [], "", None, 0, 0
    while i < len(line):
        c = line[i]
        if quote:
            quote = None if c == quote else quote
        elif c in "'\"":
            quote = c
        elif line.startswith("$(", i):
            depth += 1
            current += c
            i += 1
            c = line[i]
        elif c == ")" and depth:
            depth -= 1
        elif c == "#" and not depth and (not current or current[-1].isspace()):
            parts.append(current)
            return [p.strip() for p in parts if p.strip()], line[i + 1:].strip()
        elif not depth and (line.startswith("&&", i) or line.startswith("||", i)):
            parts.append(current)
            current, i = "", i + 2
            continue
        elif not depth and c in "|;":
            parts.append(current)
            current, i = "", i + 1
            continue
        current += c
        i += 1
    parts.append(current)
    return [p.strip() for p in parts if p.strip()], ""


def documented() -> list[Command]:
    out = []
    for path in documents():
        text = path.read_text(encoding="utf-8")
        sh = [b for b in blocks(text) if b.lang == "sh"]
        for k, block in enumerate(sh):
            for offset, line in numbered_commands(block.body):
                joined = re.sub(r"\s*\\\n\s*", " ", line)
                parts, comment = split_line(joined)
                out += [Command(name_of(path), block.line + offset, p, comment, k) for p in parts]
    return out


def ybgc_command(cmd: Command) -> str | None:
    """The ybgc command a simple command runs (``generate`` for `ybgc CONFIG
    --backend B`), or None for another program."""
    words = shlex.split(cmd.text)
    if not words or words[0] != "ybgc":
        return None
    return words[1] if len(words) > 1 and words[1] in cli.COMMANDS else "generate"


def runs_here(cmd: Command) -> bool:
    return ybgc_command(cmd) in RUN_HERE or cmd.text.split()[0] == "cd"


# --------------------------------------------------------------------------
# the commands run elsewhere: (pattern of the simple command, the test that
# runs it, what it runs)

SETUP_CI = "tests/test_ci.py::test_ci_runs_the_readme_commands_as_written"
QUICK_START = "tests/test_readme.py::test_quick_start_runs_as_written"
PROBE = "tests/test_probe.py"
COLCON = "tests/test_colcon.py"

RUN_ELSEWHERE: list[tuple[str, str, str]] = [
    (r"^scripts/setup\.sh( --yarp 3\.12\.3,4\.0\.0)?$", SETUP_CI, "CI's .ci/run, held to the README's lines"),
    (r"^scripts/demo\.sh$", SETUP_CI, "CI's .ci/run"),
    (r"^\.venv/bin/python -m pytest -q -n 3 --dist loadfile$", SETUP_CI, "CI's .ci/run: the suite"),
    (r"^\.venv/bin/python -m pytest -q tests/test_jazzy\.py tests/test_typehash\.py$",
     "tests/test_jazzy.py::test_kilted_and_jazzy_publishers_and_subscribers_exchange_the_same_messages",
     "those two test files"),
    (r"^source \.venv/bin/activate$", QUICK_START, "the quick start's shell"),
    (r"^SITE=\$\(python -c 'import sysconfig; print\(sysconfig\.get_path\(\"purelib\"\)\)'\)$", QUICK_START,
     "the quick start's shell"),
    (r"^YARP_PREFIX=\"\$SITE/yarp;\$SITE/ycm_cmake_modules\"$", QUICK_START, "the quick start's shell"),
    (r"^cmake -S vizzy -B vizzy/build -DCMAKE_PREFIX_PATH=\"\$YARP_PREFIX\" -DYBGC_ROS2_PYTHON_ENV=\"\$VIRTUAL_ENV\"$",
     QUICK_START, "the native ROS 2 module against the wheels"),
    (r"^cmake -S rviz -B rviz/build -DCMAKE_PREFIX_PATH=\"\$YARP_PREFIX\"$", QUICK_START, "the ROS 1 module"),
    (r"^cmake --build (vizzy|rviz)/build --parallel 2$", QUICK_START, "both builds"),
    (r"^\./vizzy/build/vizzy_rviz_joint_states$",
     "tests/test_backend_cpp.py::test_ros2_output_publishes_what_the_ros2_node_publishes",
     "examples/vizzy_rviz_joint_states.ini's native module, built against the wheels, run"),
    (r"^source /opt/ros/jazzy/setup\.bash$|^cmake -S vizzy -B vizzy/build -DCMAKE_PREFIX_PATH=\"\$YARP_PREFIX\"$",
     "tests/test_cpp_ros2_contract.py::test_built_through_find_package_it_publishes_the_message",
     "no ROS 2 install here: the module built the sourced install's way, the wheels' ament configs standing in"),
    (r"^cmake -S gaze -B gaze/build .*$|^cmake --build gaze/build --parallel 2$|^\./gaze/build/fixation_point_goal$",
     "tests/test_cpp_ros2_inputs.py::test_native_module_writes_what_the_python_node_writes",
     "examples/ros2_to_yarp_gaze.ini's native module, built and run"),
    (r"^cmake -S vizzy -B vizzy/build .*-DYBGC_ROS2_PYTHON_ENV=\"\$PWD/\.venv-jazzy\"$",
     "tests/test_jazzy.py::test_each_native_build_loads_the_libraries_of_its_distro", "the module built against Jazzy"),
    (r"^env -u LD_LIBRARY_PATH -u _ROS_WHEELS_BOOTSTRAP_COMPLETE (\.venv-jazzy/bin/python vizzy/vizzy_node\.py|"
     r"vizzy/build/vizzy)$",
     "tests/test_jazzy.py::test_kilted_and_jazzy_publishers_and_subscribers_exchange_the_same_messages",
     "the Jazzy node and the Jazzy build, started without Kilted's library path"),
    (r"^\./build/vizzy_arm --(name /arm_bridge|from bridge\.ini|context vizzy)$",
     "tests/test_rpc.py::test_name_from_and_context", "--name, --from and --context of both YARP modules"),
    (r"^yarp rpc /vizzy_arm/rpc:i$", "tests/test_rpc.py::test_rpc_port_answers_help_stats_and_quit",
     "help, stats and quit on the RPC port"),
    (r"^yarprun --server /ybgc &$|^yarpmanager-console --application vizzy_arm\.xml --run --connect$",
     "tests/test_yarpmanager.py::test_yarprun_and_yarpmanager_run_the_module", "on YARP 3.12.3 and 4.0.0"),
    (r"^colcon build$|^source install/setup\.bash$|"
     r"^install/tutorial_example_yarp_ros/lib/tutorial_example_yarp_ros/tutorial_example_yarp_ros_node$",
     f"{COLCON}::test_tutorial_package_built_by_colcon", "the tutorial's package built by colcon, its node run"),
    (r"^AMENT_PREFIX_PATH=\$VIRTUAL_ENV colcon build --cmake-args "
     r"-DCMAKE_PROJECT_INCLUDE=\$YBGC/scripts/msgpkg_wheels\.cmake -DPython3_EXECUTABLE=\$\(which python\)$",
     f"{COLCON}::test_message_package_and_node_in_one_workspace", "a message package and a node in one workspace"),
    (r"^colcon build --cmake-args -DCMAKE_PREFIX_PATH=\"\$YARP_PREFIX\"( -DYBGC_ROS2_PYTHON_ENV=\"\$VIRTUAL_ENV\")?$|"
     r"^install/<package>/lib/<package>/<module>$",
     f"{COLCON}::test_native_module_package_built_by_colcon", "the native module's package, with the wheels"),
    (r"^ros2 (run <package> <module>|launch <package> <module>\.launch\.py rate:=50)$",
     f"{COLCON}::test_native_module_package_built_by_colcon",
     "no `ros2` command here: the executable found through the ament index as `ros2 run` finds it, started as "
     "launch_ros starts it with its launch file's parameters"),
    (r"^cmake -S build_icub -B build_icub/build( -DCMAKE_PREFIX_PATH=\"\$YARP_PREFIX\" "
     r"-DYBGC_ROS2_PYTHON_ENV=\"\$VIRTUAL_ENV\")?$|^cmake --build build_icub/build( --parallel 2)?$|"
     r"^\./build_icub/build/icub$",
     "tests/test_compose_cpp.py::TestComposedIcub::test_every_bridge_publishes_its_values",
     "the iCub's 14 bridges composed, built and run"),
    (r"^\./build_icub/build/icub --ros-args -p icub_head:rate:=50 -p diagnostic_updater\.period:=0\.5$",
     "tests/test_compose_cpp.py::TestComposedIcub::test_a_bridge_that_cannot_start_and_parameters_by_node_name",
     "parameters by node name"),
    (r"^python3 build_icub/icub_node\.py$",
     "tests/test_compose_py.py::TestComposedIcub::test_every_bridge_publishes_its_values",
     "the iCub's 14 bridges in one rclpy node"),
    (r"^\.venv/bin/python bench/run\.py( --quick)?$|^\.venv/bin/python bench/compiler\.py$",
     "tests/test_bench.py::test_bench_smoke_floors",
     "the benchmarks take minutes on a quiet machine and measure it: the test runs their harness (--smoke); "
     "the figures are docs/benchmarks.md's"),
    (r"^dot -Tpng -o bridge\.png$", "tests/test_graph.py::test_cli_formats_and_outputs",
     "Graphviz is no dependency: the DOT ybgc prints, which the test checks"),
    (r"^ybgc probe vizzy\.ini$|^ybgc probe vizzy\.ini -v$|"
     r"^ybgc probe vizzy\.ini -p qos_overrides\./vizzy/joint_states\.publisher\.(reliability:=best_effort|"
     r"durability:=transient_local)$",
     f"{PROBE}::test_a_clean_robot_and_the_override_that_mends_the_qos", "a live robot: -v, an override"),
    (r"^ybgc probe arm\.ini head\.ini --wait 4$",
     f"{PROBE}::test_an_incompatible_qos_and_a_type_hash_of_another_definition", "two configs, one discovery"),
    (r"^ybgc probe examples/icub_robot( --wait 4)?$", f"{PROBE}::test_a_folder_is_probed_as_its_configs",
     "a folder: its configs"),
    (r"^ybgc probe vizzy\.ini --format json$", f"{PROBE}::test_another_layout_a_missing_port_and_a_taken_output",
     "json and github"),
    (r"^ybgc probe vizzy\.ini --prefix /left$", f"{PROBE}::test_the_plan_of_a_bridge",
     "the ports a module started with another prefix opens (the plan --prefix gives)"),
    (r"^\./vizzy/build/vizzy --ros-args -p qos_overrides\./vizzy/joint_states\.publisher\.durability:=transient_local$",
     "tests/test_cpp_ros2_qos.py::test_late_transient_local_subscriber", "the native module's QoS override"),
]


def elsewhere(cmd: Command) -> tuple[str, str, str] | None:
    for entry in RUN_ELSEWHERE:
        if re.search(entry[0], cmd.text):
            return entry
    return None


def test_every_documented_command_is_run_here_or_by_a_named_test():
    loose = [str(c) for c in documented() if not runs_here(c) and elsewhere(c) is None]
    assert not loose, ("commands of the documentation that no test runs: run them here, or name the test "
                       "that does in RUN_ELSEWHERE:\n" + "\n".join(loose))


def test_the_tests_named_exist_and_run_a_documented_command():
    commands = [c for c in documented() if not runs_here(c)]
    for pattern, test, _ in RUN_ELSEWHERE:
        assert any(re.search(pattern, c.text) for c in commands), f"no documented command is /{pattern}/: drop it"
        file, *names = test.split("::")
        source = (ROOT / file).read_text(encoding="utf-8")
        for name in names:
            kind = "class" if name[0].isupper() else "def"
            assert re.search(rf"^\s*{kind} {name}\b", source, re.M), f"{test}: no {kind} {name} in {file}"


# --------------------------------------------------------------------------
# the commands run here, a block at a time


def copy_examples(work: Path) -> None:
    """The repository's examples/ (copied: a command may write into it, as
    compose.md's does) and msgpkgs/."""
    shutil.copytree(ROOT / "examples", work / "examples")
    (work / "msgpkgs").symlink_to(ROOT / "msgpkgs")


def quick_start_config(work: Path) -> None:
    """The README's vizzy.ini, from its ini block."""
    [config] = [body for lang, body in fenced(section((ROOT / "README.md").read_text(encoding="utf-8"),
                                                      "Quick start")) if lang == "ini"]
    name = re.match(r"#\s*(\S+\.ini)\b", config).group(1)
    (work / name).write_text(config, encoding="utf-8")


def tutorial_config(work: Path) -> None:
    """The original tool's tutorial config, from ../shared/legacy/ as the README says."""
    shutil.copy(ROOT.parent / "shared" / "legacy" / "tutorial_example_yarp_ros.ini", work)


def a_bridges_folder(work: Path) -> None:
    """`cd my_robot/bridges/arm`: a folder that holds a bridge's config (one the py backend builds)."""
    folder = work / "my_robot" / "bridges" / "arm"
    folder.mkdir(parents=True)
    shutil.copy(ROOT / "examples" / "rviz_joint_states_ros1.ini", folder / "arm.ini")


def graph_configs(work: Path) -> None:
    """graph.md's bridge.ini, arm.ini and head.ini (three configs of the
    examples), and the docs/ folder its -o writes into."""
    shutil.copy(ROOT / "examples" / "vizzy_rviz_joint_states.ini", work / "bridge.ini")
    shutil.copy(ROOT / "examples" / "icub_robot" / "left_arm.ini", work / "arm.ini")
    shutil.copy(ROOT / "examples" / "icub_robot" / "head.ini", work / "head.ini")
    (work / "docs").mkdir()


def repository_folder(work: Path) -> Path:
    """The repository's folder as graph.md runs its figure's command in: its
    docs/, and ../shared/legacy/ beside it."""
    repo = work / "repo"
    (repo / "docs").mkdir(parents=True)
    (work / "shared").mkdir()
    (work / "shared" / "legacy").symlink_to(ROOT.parent / "shared" / "legacy")
    return repo


#: (document, the first command of a block) -> what its folder holds beside
#: examples/ and msgpkgs/; a function that returns a folder starts the block there
SETUPS: dict[tuple[str, str], Callable[[Path], Path | None]] = {
    ("README.md", "source .venv/bin/activate"): quick_start_config,
    ("README.md", "ybgc fmt --to named --ros2 --msg-path msgpkgs tutorial_example_yarp_ros.ini -o tutorial.ini"):
        tutorial_config,
    ("README.md", "cd my_robot/bridges/arm"): a_bridges_folder,
    ("docs/graph.md", "ybgc graph bridge.ini"): graph_configs,
    ("docs/graph.md", "ybgc graph ../shared/legacy/thesis_figure5_rviz.ini -o docs/graph_thesis_figure5.svg"):
        repository_folder,
}

#: after a command, what it made that the test compares (its block's folder, the command's folder)
AFTER: dict[str, Callable[[Path], None]] = {
    # the figure in docs/ is what the command draws
    "ybgc graph ../shared/legacy/thesis_figure5_rviz.ini -o docs/graph_thesis_figure5.svg":
        lambda cwd: filecmp.cmp(cwd / "docs" / "graph_thesis_figure5.svg", ROOT / "docs" / "graph_thesis_figure5.svg",
                                shallow=False) or pytest.fail("docs/graph_thesis_figure5.svg is not what ybgc draws"),
}


def run_blocks() -> list[tuple[str, int, list[Command]]]:
    """(document, block, its commands) of every block with a command run here."""
    by_block: dict[tuple[str, int], list[Command]] = {}
    for c in documented():
        by_block.setdefault((c.doc, c.block), []).append(c)
    return [(doc, k, cmds) for (doc, k), cmds in by_block.items() if any(ybgc_command(c) in RUN_HERE for c in cmds)]


def expected_status(cmd: Command) -> int:
    """0, unless the comment says the command exits otherwise (`exits 1`)."""
    m = re.search(r"\bexits? (\d)\b(?!,| or)", cmd.comment)
    return int(m.group(1)) if m else 0


def promised(cmd: Command) -> list[str]:
    """The files the command writes by what it says: its -o, and the paths
    its comment promises (`-> vizzy/vizzy_node.py`, `./icub_robot.svg`)."""
    words = shlex.split(cmd.text)
    out = [words[i + 1] for i, w in enumerate(words[:-1]) if w in ("-o", "--output") and words[i + 1] != "-"]
    out += re.findall(r"->\s*([\w.-]+(?:/[\w.-]+)+)", cmd.comment)
    out += re.findall(r"(?<![\w/])(\./[\w.-]+\.\w+)\b", cmd.comment)
    return out


def ids(runs: list[tuple[str, int, list[Command]]]) -> list[str]:
    return [f"{doc}:{cmds[0].line}" for doc, _, cmds in runs]


BLOCKS = run_blocks()


@pytest.mark.parametrize("doc, block, cmds", BLOCKS, ids=ids(BLOCKS))
def test_the_ybgc_commands_of_a_block_run_as_written(doc, block, cmds, tmp_path, monkeypatch, capsys):
    work = tmp_path / "work"
    work.mkdir()
    copy_examples(work)
    setup = SETUPS.get((doc, cmds[0].text))
    cwd = (setup(work) if setup else None) or work
    for cmd in cmds:
        words = shlex.split(cmd.text)
        if words[0] == "cd":
            cwd = cwd / words[1]
            assert cwd.is_dir(), f"{cmd}: no folder {words[1]} (lay it out in SETUPS)"
            continue
        if ybgc_command(cmd) not in RUN_HERE:
            continue  # run by the test RUN_ELSEWHERE names
        monkeypatch.chdir(cwd)
        capsys.readouterr()
        try:
            status = cli.main(words[1:])
        except SystemExit as e:
            status = e.code
        out, err = capsys.readouterr()
        assert "Traceback" not in err, f"{cmd}\n{err}"
        assert status == expected_status(cmd), f"{cmd}: exit {status}\n{err[-2000:]}"
        for path in promised(cmd):
            assert (cwd / path).exists(), f"{cmd}: it says it writes {path}, which is not there"
        if cmd.text in AFTER:
            AFTER[cmd.text](cwd)


def test_every_setup_is_for_a_block_that_runs_here():
    firsts = {(doc, cmds[0].text) for doc, _, cmds in BLOCKS}
    assert set(SETUPS) <= firsts, sorted(set(SETUPS) - firsts)
    assert set(AFTER) <= {c.text for _, _, cmds in BLOCKS for c in cmds}, sorted(AFTER)
