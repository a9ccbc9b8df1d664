"""What a backend returns, as the tests use it: the module (the files this
config made) apart from the runtime library written beside it (the same for
every config, compared once against its own golden files by
tests/test_runtime.py)."""

from __future__ import annotations

from pathlib import Path

from ybg.backends.runtime import CPP_HEADER, CPP_SOURCE, PY_PACKAGE


def is_runtime(name: str) -> bool:
    """Is ``name`` (a path relative to the output folder) a runtime file?"""
    parts = Path(name).parts
    return PY_PACKAGE in parts[:-1] or parts[-1] in (CPP_HEADER, CPP_SOURCE)


def without_runtime(files: dict[str, str]) -> dict[str, str]:
    return {name: text for name, text in files.items() if not is_runtime(name)}


def module_file(files: dict[str, str], suffix: str) -> tuple[str, str]:
    """The one generated file ending in ``suffix`` that is not the runtime."""
    (name, text), = ((n, t) for n, t in files.items() if n.endswith(suffix) and not is_runtime(n))
    return name, text


def write_generated(folder: Path, files: dict[str, str]) -> None:
    """Every file of ``files`` under ``folder`` (the runtime beside the module)."""
    for name, text in files.items():
        path = folder / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


def load_module(path: Path, name: str):
    """The generated module at ``path`` imported as ``name`` (it runs nothing
    on import), with the runtime beside it: its folder on sys.path as when
    it is run as a script. Returns (module, its runtime's modules by name)."""
    import importlib
    import importlib.util
    import sys

    folder = str(path.parent)
    for key in [k for k in sys.modules if k == PY_PACKAGE or k.startswith(PY_PACKAGE + ".")]:
        del sys.modules[key]  # another folder's runtime
    sys.path.insert(0, folder)
    try:
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        runtime = {k[len(PY_PACKAGE) + 1:]: v for k, v in sys.modules.items()
                   if k.startswith(PY_PACKAGE + ".")}
    finally:
        sys.path.remove(folder)
    return module, runtime
