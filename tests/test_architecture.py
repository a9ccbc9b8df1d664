"""docs/architecture.md's lists of files, held to the tree.

"Where to add" gives, for each change (a converter, an input kind, an output
kind, a message feature, a kind of bridge, a backend), every file it
touches. Each list has a witness: what every file of ``ybg/`` that holds one
of its kind says (``fixed_array`` for a message feature, a test of an
input's kind for an input kind...). A file of ``ybg/`` the witness finds and
the list leaves out fails, naming it, and so does a file a list names that
does not exist: a file newly added to a concern is listed from the start.

"The stages" names each file of the runtime library (Python and C++), of
the lowering library and of each backend package, and the C++ runtime's
static libraries as the generated CMakeLists.txt names them.

Pure reads of the files, no import of ybg.
"""
from __future__ import annotations

import functools
import re
from collections.abc import Callable
from pathlib import Path

import pytest

from harness.markdown import ROOT, section, tables

DOC = ROOT / "docs" / "architecture.md"
YBG = ROOT / "ybg"
#: the files of ybg/ a witness reads: code and templates (ybg/grammar is
#: grammar/; ybg/msgs holds vendored .msg definitions, no code)
SUFFIXES = (".py", ".j2", ".lark", ".cpp", ".hpp")


@functools.lru_cache(maxsize=None)
def text() -> str:
    return DOC.read_text(encoding="utf-8")


@functools.lru_cache(maxsize=None)
def code_files() -> dict[str, str]:
    """Every file of ybg/ a witness reads: its path from the root -> its text."""
    out = {}
    for path in sorted(YBG.rglob("*")):
        if (path.is_file() and path.name.endswith(SUFFIXES) and "__pycache__" not in path.parts
                and path.relative_to(YBG).parts[0] != "msgs"):
            out[path.relative_to(ROOT).as_posix()] = path.read_text(encoding="utf-8")
    return out


def paths_in(body: str) -> set[str]:
    """The repository paths a Markdown text names in backticks (those with a
    placeholder, ``<name>``, are the files a change adds)."""
    return {p for p in re.findall(r"`([^`\s]+)`", body)
            if re.fullmatch(r"(ybg|docs|tests|grammar|bench|scripts)/[\w./<>-]*|README\.md", p)}


def _any(*patterns: str) -> Callable[[str, str], bool]:
    one = re.compile("|".join(f"(?:{p})" for p in patterns))
    return lambda path, t: one.search(t) is not None


def _all(*patterns: str) -> Callable[[str, str], bool]:
    each = [re.compile(p) for p in patterns]
    return lambda path, t: all(p.search(t) for p in each)


def _linear_or_geometry(path: str, t: str) -> bool:
    return (("none_double" in t and _all(r"\bnone_double\b", r"\bdeg_to_rad\b", r"\brad_to_deg\b")(path, t))
            or (("matrix_to_quat" in t or "MatrixToQuat" in t) and _any(r"\bmatrix_to_quat\b", r"\bMatrixToQuat\b")(path, t)))


#: an input's kind tested: `i.kind ==`, `inp.kind != "yarp"`, `in.kind == InputKind::Ros2`...
_INPUT = (r"\b(i|inp|spec|in|inputs\[0\])\.kind\s*(==|!=|not in\b|in\b)", r"\[(i|inp)\.kind\]",
          r"\.get\(\s*(i|inp)\.kind\b", r"\bInputKind\b", r"\binputs=frozenset\(")
#: an output's kind tested
_OUTPUT = (r"\b(out|output|program\.output|ctx\.output|self\.output|spec_?\.output)\.kind\s*(==|!=|not in\b|in\b)",
           r"\[(out|output)\.kind\]", r'getattr\(self\.output, "kind"', r"\bOutputKind\b", r"\b_OUTPUT_KINDS\b",
           r"\boutputs=frozenset\(")


_KIND_TABLE = _all(r'"stream"', r'"commands"')
_KIND_NAMED = _any(r"\bBRIDGE_KINDS\s*=", r"\(BridgeKind\)", r"\bCommands\.kind\b",
                   r"isinstance\([^)]*\bir\.Commands\)")


def _bridge_kind(path: str, t: str) -> bool:
    return _KIND_TABLE(path, t) or _KIND_NAMED(path, t)


BACKENDS = sorted(p.name for p in (YBG / "backends").iterdir() if (p / "__init__.py").is_file())
#: a backend's name -> what names it: its module or folder, or its Backend class
_BACKEND_NAMED = {
    name: re.compile("|".join([rf"ybg[./]backends[./]{name}\b"] + [
        rf"\b{c}\b" for c in re.findall(r"^class (\w+)\(Backend\):",
                                        (YBG / "backends" / name / "__init__.py").read_text(), re.M)]))
    for name in BACKENDS}


def _names_a_backend(path: str, t: str) -> bool:
    """Outside a backend's package: naming it (its module or folder) or its Backend class."""
    return any(not path.startswith(f"ybg/backends/{name}/") and named.search(t)
               for name, named in _BACKEND_NAMED.items())


#: (the title of the section of "Where to add", its witness)
WITNESSES: list[tuple[str, Callable[[str, str], bool]]] = [
    ("A converter", _linear_or_geometry),
    ("An input kind", _any(*_INPUT)),
    ("An output kind", _any(*_OUTPUT)),
    ("A message feature", _any(r"\bfixed_array\b")),
    ("A kind of bridge", _bridge_kind),
    ("A backend", _names_a_backend),
]


@functools.lru_cache(maxsize=None)
def witnessed(title: str) -> tuple[str, ...]:
    """The files of ybg/ the witness of ``title`` finds."""
    witness = dict(WITNESSES)[title]
    return tuple(p for p, t in code_files().items() if witness(p, t))


@pytest.mark.parametrize("title", [t for t, _ in WITNESSES])
def test_each_list_names_every_file_of_its_concern(title):
    listed = paths_in(section(text(), title, level=3))
    found = witnessed(title)
    assert found, f"the witness of `### {title}` finds no file: it no longer says what such a file holds"
    missed = sorted(set(found) - listed)
    assert not missed, (f"docs/architecture.md, `### {title}`, leaves out files of that concern "
                        f"(its witness finds them): {missed}")


def test_every_file_the_document_names_exists():
    missing = sorted(p for p in paths_in(text()) if "<" not in p and not (ROOT / p).exists())
    assert not missing, f"docs/architecture.md names files that do not exist: {missing}"


def test_the_witnesses_tell_concerns_apart():
    """A witness that found every file would hold no list to anything."""
    for title, _ in WITNESSES:
        assert len(witnessed(title)) < len(code_files()) / 2, title


# --------------------------------------------------------------------------
# the stages: the files of the runtime, the lowering library and the backends


def paragraph(title: str) -> str:
    """The paragraph of "The stages" that starts with ``**title**``, with
    the list or table right after it."""
    body = section(text(), "The stages")
    start = body.index(f"**{title}**")
    nxt = body.find("\n\n**", start)
    return body[start:] if nxt < 0 else body[start:nxt]


def named(body: str) -> set[str]:
    return set(re.findall(r"`([^`\s]+)`", body))


@pytest.mark.parametrize("title, folder", [
    ("Runtime library", "ybg/runtime"),
    ("Runtime library", "ybg/runtime/cpp"),
    ("Lowering library", "ybg/lower"),
])
def test_the_stages_name_every_file_of_a_library(title, folder):
    here = named(paragraph(title))
    files = sorted(p.relative_to(ROOT / folder).as_posix() for p in (ROOT / folder).rglob("*")
                   if p.is_file() and "__pycache__" not in p.parts and p.suffix in (".py", ".cpp", ".hpp", ".j2")
                   and (folder != "ybg/runtime" or p.parent == ROOT / folder))
    assert files
    missed = [f for f in files if f not in here]
    assert not missed, f"docs/architecture.md, **{title}**, leaves out files of {folder}/: {missed}"
    gone = sorted(n for n in here if re.fullmatch(r"[\w/]+\.(py|cpp|hpp)", n) and "/" not in n
                  and not any((ROOT / d / n).exists() for d in ("ybg/runtime", "ybg/runtime/cpp", "ybg/lower")))
    assert not gone, f"docs/architecture.md, **{title}**, names files that do not exist: {gone}"


def test_the_stages_name_the_static_libraries_of_the_cpp_runtime():
    version = re.search(r'^VERSION = "([^"]+)"', (YBG / "runtime" / "__init__.py").read_text(), re.M).group(1)
    cpp = (YBG / "backends" / "cpp" / "__init__.py").read_text()
    parts = {m or "runtime" for m in re.findall(r'runtime_library\((?:"(\w+)")?\)', cpp)}
    assert parts >= {"runtime", "ros2", "images", "services"}
    here = named(paragraph("Runtime library"))
    suffix = re.sub(r"[^0-9A-Za-z]", "_", version)
    missed = sorted(f"ybgc_{p}_{suffix}" for p in parts if f"ybgc_{p}_{suffix}" not in here)
    assert not missed, f"docs/architecture.md, **Runtime library**, leaves out the static libraries {missed}"


def test_the_table_of_backends_names_every_file_of_each_backend():
    table = next(t for t in tables(section(text(), "The stages")) if t.header[0] == "Backend")
    rows = {r[0].strip("`"): " ".join(r[1:]) for r in table.rows}
    assert sorted(rows) == BACKENDS
    for name in BACKENDS:
        package = YBG / "backends" / name
        files = sorted(p.relative_to(package).as_posix() for p in package.rglob("*")
                       if p.is_file() and "__pycache__" not in p.parts)
        here = named(rows[name])
        missed = [f for f in files if f.rpartition("/")[2] not in here]
        assert not missed, f"docs/architecture.md's table of backends leaves out files of ybg/backends/{name}/: {missed}"
        gone = sorted(n for n in here if re.fullmatch(r"[\w.]+\.(py|j2|md)", n)
                      and not (package / n).exists() and not (package / "templates" / n).exists())
        assert not gone, f"docs/architecture.md's table of backends names files ybg/backends/{name}/ lacks: {gone}"
