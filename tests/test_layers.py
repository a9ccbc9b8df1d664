"""The layers of the tree, read from its imports::

    ybg/compiler  (front end: text -> AST -> IR)
        <- ybg/lower     (the lowering library: IR -> what backends share)
            <- ybg/backends/<name>  (one package a backend, siblings)
    ybg/runtime   (what generated modules run on)

- the compiler imports no backend and not the lowering library;
- the lowering library imports no backend;
- no backend imports another backend, nor what finds backends by name
  (``ybg.backends`` itself, its registry and support);
- the runtime imports nothing of the compiler, the lowering library or the
  backends (a generated module carries it alone);
- backends and the lowering library read no AST: they import no module of
  the front end's syntax (``ast``, ``parser``, ``legacy``, ``fmt``,
  ``passes``) and touch no document of a result (``.named``, ``.document``).

Every import counts: at a module's top or inside a function, relative or
absolute, ``importlib.import_module`` of a constant name.
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
YBG = ROOT / "ybg"
COMPILER = YBG / "compiler"
LOWER = YBG / "lower"
RUNTIME = YBG / "runtime"
BACKENDS = YBG / "backends"
BACKEND_PACKAGES = sorted(p.name for p in BACKENDS.iterdir() if (p / "__init__.py").is_file())
#: the front end's syntax, which no backend reads
SYNTAX = ("ybg.compiler.ast", "ybg.compiler.parser", "ybg.compiler.legacy", "ybg.compiler.fmt",
          "ybg.compiler.passes")
#: the parts of ybg.backends that find backends by name (and so import them)
FINDERS = ("ybg.backends", "ybg.backends.registry", "ybg.backends.support")


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


def _under(name: str, prefix: str) -> bool:
    return name == prefix or name.startswith(prefix + ".")


def violations(path: Path, forbidden, root: Path = ROOT) -> list[str]:
    """The imports of ``path`` under any of the module names ``forbidden``."""
    return [f"{path.relative_to(root)}:{line}: {name}" for line, name in imported(path, root)
            if any(_under(name, f) for f in forbidden)]


def modules(folder: Path) -> list[Path]:
    return sorted(folder.rglob("*.py"))


def backend_of(path: Path, root: Path = ROOT) -> str | None:
    """The backend package ``path`` belongs to (``cpp``), or None."""
    parts = path.relative_to(root / "ybg" / "backends").parts
    return parts[0] if len(parts) > 1 else None


def backend_violations(path: Path, root: Path = ROOT) -> list[str]:
    """The imports by which the backend module ``path`` reaches another backend."""
    own = backend_of(path, root)
    allowed = [f"ybg.backends.{ok}" for ok in ("base", "features", "runtime", own)]
    others = [f"ybg.backends.{b}" for b in BACKEND_PACKAGES if b != own]
    return [v for v in violations(path, others + list(FINDERS), root)
            if not any(_under(v.rpartition(": ")[2], ok) for ok in allowed)]


def test_the_walks_see_every_layer():
    assert COMPILER / "check.py" in modules(COMPILER) and COMPILER / "passes" / "context.py" in modules(COMPILER)
    assert LOWER / "python.py" in modules(LOWER) and RUNTIME / "core.py" in modules(RUNTIME)
    assert BACKEND_PACKAGES == ["cpp", "py", "ros2"]


@pytest.mark.parametrize("path", modules(COMPILER), ids=lambda p: str(p.relative_to(COMPILER)))
def test_the_compiler_imports_no_backend_and_no_lowering(path: Path):
    assert violations(path, ("ybg.backends", "ybg.lower")) == []


@pytest.mark.parametrize("path", modules(LOWER), ids=lambda p: str(p.relative_to(LOWER)))
def test_the_lowering_library_imports_no_backend(path: Path):
    assert violations(path, ("ybg.backends",)) == []


@pytest.mark.parametrize("path", [p for p in modules(BACKENDS) if backend_of(p)],
                         ids=lambda p: str(p.relative_to(BACKENDS)))
def test_no_backend_imports_another(path: Path):
    assert backend_violations(path) == []


@pytest.mark.parametrize("path", modules(RUNTIME), ids=lambda p: str(p.relative_to(RUNTIME)))
def test_the_runtime_imports_nothing_of_the_compiler(path: Path):
    assert violations(path, ("ybg.compiler", "ybg.lower", "ybg.backends", "ybg.cli")) == []


def _reads_documents(path: Path) -> list[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    return [f"{path.relative_to(ROOT)}:{n.lineno}: .{n.attr}" for n in ast.walk(tree)
            if isinstance(n, ast.Attribute) and n.attr in ("named", "document")]


@pytest.mark.parametrize("path", modules(BACKENDS) + modules(LOWER), ids=lambda p: str(p.relative_to(YBG)))
def test_backends_read_no_ast(path: Path):
    assert violations(path, SYNTAX) == [] and _reads_documents(path) == []


# --------------------------------------------------------------------------
# the checks themselves


@pytest.mark.parametrize("source", [
    "import ybg.backends",
    "import ybg.backends.cpp as cpp",
    "from ybg.backends import REGISTRY",
    "from ybg import backends",
    "from .. import backends",
    "from ..backends.runtime import PY_PACKAGE",
    "def f():\n    from ybg.backends import check\n",
    "import importlib\nimportlib.import_module('ybg.backends.py')",
    "from ybg.lower.python import py_literal",
])
def test_every_form_of_import_is_caught(tmp_path: Path, source: str):
    """Each way of importing the backends or the lowering library, in a
    module placed as ybg/compiler/x.py would be."""
    module = tmp_path / "ybg" / "compiler" / "x.py"
    module.parent.mkdir(parents=True)
    module.write_text(source + "\n", encoding="utf-8")
    assert violations(module, ("ybg.backends", "ybg.lower"), tmp_path), source


@pytest.mark.parametrize("source,caught", [
    ("from ybg.backends.py.lower import py_literal", True),
    ("from ..py import PyBackend", True),
    ("from ybg.backends import get_backend", True),
    ("from ybg.backends.registry import REGISTRY", True),
    ("from ybg.backends.base import Backend", False),
    ("from ybg.backends.cpp.escape import comment", False),
    ("from . import lower", False),
    ("from ybg.lower.python import py_literal", False),
])
def test_a_backend_importing_another_is_caught(tmp_path: Path, source: str, caught: bool):
    module = tmp_path / "ybg" / "backends" / "cpp" / "x.py"
    module.parent.mkdir(parents=True)
    module.write_text(source + "\n", encoding="utf-8")
    assert bool(backend_violations(module, tmp_path)) == caught, source
