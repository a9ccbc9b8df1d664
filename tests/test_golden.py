"""Golden files, one test for every backend: what a backend writes for each
of its cases (the module, not the runtime library written beside it, which
tests/test_runtime.py checks once) is byte for byte what
tests/golden/<backend>/<key>/ holds, no file more or less.

The cases: each backend's hand-made programs (tests/harness/programs.py:
``CPP_GOLDEN_PROGRAMS``, ``PY_GOLDEN_PROGRAMS``), every example and legacy
config the cpp and py backends build (by its stem), every example of the
ros2 backend (two of them with their ament package too, under package/).

``pytest --update-goldens`` (or ``YBG_UPDATE_GOLDENS=1``) writes the golden
files instead of comparing: each case's folder then holds exactly its files.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import pytest

from harness.generated import without_runtime
from harness.programs import (CPP_GOLDEN_PROGRAMS, PY_GOLDEN_PROGRAMS, command_examples, command_program,
                              config_program, ros2_example, ros2_examples, supported_configs)
from ybg.backends import RenderOptions, get_backend
from ybg.backends.runtime import cpp_files, is_runtime_file
from ybg.compiler.ir import Commands, Program

GOLDEN = Path(__file__).resolve().parent / "golden"
#: the ROS 2 examples whose golden files hold their ament package too
ROS2_PACKAGES = ("vizzy_rviz_joint_states", "ros2_to_yarp_gaze")


@dataclass(frozen=True)
class Case:
    """What one folder of golden files holds: ``backend``'s files for the
    program ``make`` gives."""
    backend: str
    key: str                        # the folder: a program's key or a config's stem
    make: Callable[[], Program]

    @property
    def folder(self) -> Path:
        return GOLDEN / self.backend / self.key


def _configs(backend: str) -> list[Case]:
    return [Case(backend, p.stem, lambda p=p: config_program(p, backend)) for p in supported_configs(backend)]


CASES = ([Case("cpp", key, make) for key, make in CPP_GOLDEN_PROGRAMS.items()] + _configs("cpp")
         + [Case("py", key, make) for key, make in PY_GOLDEN_PROGRAMS.items()] + _configs("py")
         + [Case("ros2", stem, lambda stem=stem: ros2_example(stem)) for stem in ros2_examples()]
         # the examples of commands, by both backends that build them
         + [Case(b, p.stem, lambda p=p, b=b: command_program(p, b)) for b in ("cpp", "ros2") for p in command_examples()])


def uses_rcl(program: Program) -> bool:
    if isinstance(program, Commands):
        return True
    return program.output.kind == "ros2" or any(i.kind == "ros2" for m in program.muxes for i in m.inputs)


def rendered(case: Case, program: Program) -> dict[str, str]:
    """Every file the backend writes for ``program``, the runtime too."""
    backend = get_backend(case.backend)
    files = backend.render(program)
    if case.backend == "ros2" and case.key in ROS2_PACKAGES:
        package = backend.render(program, RenderOptions(package=True))
        files.update({f"package/{rel}": text for rel, text in package.items()})
    return files


def check_rendered(case: Case, program: Program, files: dict[str, str]) -> None:
    """What every generation of the case holds, golden or not: the same files
    from a program compiled again; Python that compiles; a C++ module's own
    files by name, the rest the runtime library's."""
    assert rendered(case, case.make()) == files, "output is not deterministic"
    for name, text in files.items():
        if name.endswith(".py"):
            compile(text, name, "exec")
    if case.backend == "cpp":  # the module's three files, and the runtime library's (its ROS 2 side for rcl)
        own = {f"{program.module}.cpp", "CMakeLists.txt"} | (
            set() if isinstance(program, Commands) else {f"{program.module}.xml"})
        runtime = set(files) - own
        assert own <= set(files) and all(is_runtime_file(name) for name in runtime), sorted(files)
        assert set(cpp_files(ros2=uses_rcl(program))) <= runtime, sorted(files)


def on_disk(folder: Path) -> list[str]:
    return sorted(str(p.relative_to(folder)) for p in folder.rglob("*") if p.is_file())


def write_golden(folder: Path, files: dict[str, str]) -> None:
    """``folder`` holds exactly ``files`` (a file no longer generated is removed)."""
    if folder.is_dir():
        for rel in on_disk(folder):
            if rel not in files:
                (folder / rel).unlink()
    for rel, text in files.items():
        path = folder / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8", newline="\n")


@pytest.mark.parametrize("case", CASES, ids=[f"{c.backend}-{c.key}" for c in CASES])
def test_golden_files(case: Case, update_goldens):
    program = case.make()
    files = rendered(case, program)
    check_rendered(case, program, files)
    files = without_runtime(files)  # the runtime's own checks: tests/test_runtime.py
    where = f"{case.backend}/{case.key}"
    if update_goldens or os.environ.get("YBG_UPDATE_GOLDENS") == "1":
        write_golden(case.folder, files)
        return
    assert case.folder.is_dir(), f"no golden files for {where} (tests/golden/{where}/): run pytest --update-goldens"
    assert on_disk(case.folder) == sorted(files), \
        f"the golden files of {where} differ in name; run pytest --update-goldens"
    for rel, text in files.items():
        assert (case.folder / rel).read_text(encoding="utf-8") == text, \
            f"{where}/{rel} differs from its golden file; run pytest --update-goldens"
