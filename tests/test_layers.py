"""Stages depend downward only: the compiler knows no backend. Each backend
says itself what it can build (``ybg.backends.check``), so no module of
``ybg/compiler/`` imports ``ybg.backends``, at its top or inside a function."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
COMPILER = ROOT / "ybg" / "compiler"
MODULES = sorted(COMPILER.rglob("*.py"))
FORBIDDEN = "ybg.backends"


def module_name(path: Path, root: Path) -> str:
    parts = path.relative_to(root).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imported(path: Path, root: Path) -> list[tuple[int, str]]:
    """(line, absolute module name) of every import in ``path``: ``import``,
    ``from ... import`` (relative ones resolved, each imported name counted as
    a possible submodule) and ``importlib.import_module``/``__import__`` of a
    constant name."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    name = module_name(path, root)
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    out = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                base = ".".join(anchor + ([node.module] if node.module else []))
            out.append((node.lineno, base))
            out += [(node.lineno, f"{base}.{a.name}") for a in node.names]
        elif isinstance(node, ast.Call) and node.args and isinstance(node.args[0], ast.Constant) \
                and isinstance(node.args[0].value, str):
            func = node.func
            name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", "")
            if name in ("import_module", "__import__"):
                out.append((node.lineno, node.args[0].value))
    return out


def imports_backends(path: Path, root: Path = ROOT) -> list[str]:
    return [f"{path.relative_to(root)}:{line}: {name}" for line, name in imported(path, root)
            if name == FORBIDDEN or name.startswith(FORBIDDEN + ".")]


def test_the_walk_sees_the_compiler():
    assert COMPILER / "check.py" in MODULES and COMPILER / "passes" / "context.py" in MODULES


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(COMPILER)))
def test_no_compiler_module_imports_a_backend(path: Path):
    assert imports_backends(path) == []


@pytest.mark.parametrize("source", [
    "import ybg.backends",
    "import ybg.backends.cpp as cpp",
    "from ybg.backends import REGISTRY",
    "from ybg import backends",
    "from .. import backends",
    "from ..backends.wire import WIRE_ROS1",
    "def f():\n    from ybg.backends import check\n",
    "import importlib\nimportlib.import_module('ybg.backends.py')",
])
def test_every_form_of_import_is_caught(tmp_path: Path, source: str):
    """The check itself: each way of importing the backends, in a module
    placed as ybg/compiler/x.py would be."""
    module = tmp_path / "ybg" / "compiler" / "x.py"
    module.parent.mkdir(parents=True)
    module.write_text(source + "\n", encoding="utf-8")
    assert imports_backends(module, tmp_path), source
