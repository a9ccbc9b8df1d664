#!/usr/bin/env python3
"""Lines of the module ybgc generates for the thesis' three demonstrations,
per backend (docs/runtime-library.md): the file the user reads, without the
runtime library written beside it.

    python scripts/module_lines.py          # the markdown table
    python scripts/module_lines.py --write  # ... into docs/runtime.md

The ROS 1 backends (cpp, py) get the MoveIt demonstration with `via = ros1`
(and no ROS 2 QoS keys): the thesis published it through YARP's ROS 1 support.
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from ybg.backends import check_result, get_backend  # noqa: E402
from ybg.backends.runtime import is_runtime_file  # noqa: E402
from ybg.compiler.pipeline import compile_text  # noqa: E402

EXAMPLES = ROOT / "examples"

#: demonstration -> backend -> config (file name in examples/)
DEMOS = {
    "Rviz joint states": {"cpp": "rviz_joint_states_ros1.ini", "py": "rviz_joint_states_ros1.ini",
                          "ros2": "vizzy_rviz_joint_states.ini"},
    "MoveIt joint states": {b: "icub_moveit_joint_states.ini" for b in ("cpp", "py", "ros2")},
    "YARP to YARP": {b: "yarp_to_yarp_end_effector.ini" for b in ("cpp", "py", "ros2")},
}
BACKENDS = ("cpp", "py", "ros2")
LIMIT = 200


def config_text(name: str, backend: str) -> str:
    text = (EXAMPLES / name).read_text(encoding="utf-8")
    if backend != "ros2" and re.search(r"^via = ros2$", text, re.M):
        text = re.sub(r"^via = ros2$", "via = ros1", text, flags=re.M)
        text = re.sub(r"^(reliability|durability|depth) = .*\n", "", text, flags=re.M)
    return text


def module_lines(demo: str, backend: str) -> tuple[str, int]:
    """(module file name, its lines) for one demonstration and backend."""
    name = DEMOS[demo][backend]
    result = check_result(compile_text(config_text(name, backend), name), backend)
    if not result.ok:
        raise SystemExit(f"{name} ({backend}): " + "; ".join(d.message for d in result.errors))
    files = get_backend(backend).render(result.program)
    suffix = ".cpp" if backend == "cpp" else ".py"
    (file, text), = [(f, t) for f, t in files.items() if f.endswith(suffix)
                     and not is_runtime_file(f)]
    return file, text.count("\n")


def table() -> str:
    rows = ["| demonstration | config | " + " | ".join(f"`{b}`" for b in BACKENDS) + " |",
            "|---|---|" + "---:|" * len(BACKENDS)]
    for demo in DEMOS:
        configs = sorted(set(DEMOS[demo].values()))
        cells = [str(module_lines(demo, b)[1]) for b in BACKENDS]
        rows.append(f"| {demo} | {', '.join(f'`{c}`' for c in configs)} | " + " | ".join(cells) + " |")
    return "\n".join(rows)


DOC = ROOT / "docs" / "runtime.md"


def write_doc() -> None:
    """The table in docs/runtime.md replaced by today's."""
    text = DOC.read_text(encoding="utf-8")
    new = re.sub(r"^\| demonstration \| config \|.*?\n(?=\n)", lambda _m: table() + "\n", text,
                 count=1, flags=re.S | re.M)
    DOC.write_text(new, encoding="utf-8")


if __name__ == "__main__":
    if sys.argv[1:] == ["--write"]:
        write_doc()
    print(table())
