"""The project's Markdown as the tests read it: README.md and docs/*.md, their
sections, fenced blocks, the commands of their shell blocks, and their
tables. What a test holds the documentation to is read from the text
itself, never from a copy of it."""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
README = ROOT / "README.md"


def documents() -> list[Path]:
    """README.md and every page of docs/, in that order."""
    return [README, *sorted((ROOT / "docs").glob("*.md"))]


def name_of(path: Path) -> str:
    """A document as the tests name it: its path from the repository's root."""
    return path.relative_to(ROOT).as_posix()


def section(text: str, title: str, level: int = 2) -> str:
    """The body of the section ``title`` (a heading of ``level`` #) of a
    Markdown text, up to the next heading of that level or higher."""
    hashes = "#" * level
    body: list[str] | None = None
    fence = False
    for line in text.splitlines(keepends=True):
        heading = None if fence else re.match(r"(#{1,6}) (.*?)[ \t]*$", line)
        if line.startswith("```"):
            fence = not fence
        if heading and body is not None and len(heading.group(1)) <= level:
            break
        if body is not None:
            body.append(line)
        elif heading and heading.group(1) == hashes and heading.group(2) == title:
            body = []
    assert body is not None, f"no `{hashes} {title}` section"
    return "".join(body)


@dataclass(frozen=True)
class Block:
    """A fenced code block: its language (``""`` for none), its body and the
    line of the text its body starts on."""

    lang: str
    body: str
    line: int


def blocks(text: str) -> list[Block]:
    """The fenced code blocks of a Markdown text, in order."""
    out = []
    for m in re.finditer(r"^```([\w-]*)[ \t]*\n(.*?)^```[ \t]*$", text, re.M | re.S):
        out.append(Block(m.group(1), m.group(2), text.count("\n", 0, m.start(2)) + 1))
    return out


def fenced(text: str) -> list[tuple[str, str]]:
    """The fenced code blocks of a Markdown text: (language, body)."""
    return [(b.lang, b.body) for b in blocks(text)]


def commands(sh: str) -> list[str]:
    """The commands of a shell block: its lines, a line ending in a
    backslash joined with the next, blank and comment lines left out."""
    return [c for _, c in numbered_commands(sh)]


def numbered_commands(sh: str) -> list[tuple[int, str]]:
    """``commands`` with the line of the block each starts on (0-based)."""
    out, pending, start = [], "", 0
    for i, line in enumerate(sh.splitlines()):
        if pending:
            line = pending + "\n" + line
            pending = ""
        else:
            start = i
        if line.rstrip().endswith("\\"):
            pending = line
            continue
        if line.strip() and not line.lstrip().startswith("#"):
            out.append((start, line))
    assert not pending, f"a shell line continues past its block: {pending!r}"
    return out


@dataclass(frozen=True)
class Table:
    """A Markdown table: its header cells, its rows (each a tuple of cells,
    as written), the heading it is under and the lines it spans (1-based,
    first and last)."""

    header: tuple[str, ...]
    rows: tuple[tuple[str, ...], ...]
    heading: str
    first: int
    last: int

    def column(self, name: str) -> int:
        return self.header.index(name)


def _cells(line: str) -> tuple[str, ...]:
    inner = line.strip()[1:-1]
    # `\|` is a pipe inside a cell
    return tuple(c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", inner))


def tables(text: str) -> list[Table]:
    """Every table of a Markdown text (outside fenced blocks)."""
    out: list[Table] = []
    lines = text.splitlines()
    heading, fence, i = "", False, 0
    while i < len(lines):
        line = lines[i]
        if line.startswith("```"):
            fence = not fence
        elif not fence and re.match(r"#{1,6} ", line):
            heading = line.lstrip("#").strip()
        elif (not fence and line.lstrip().startswith("|") and i + 1 < len(lines)
              and re.fullmatch(r"\s*\|(\s*:?-+:?\s*\|)+\s*", lines[i + 1])):
            header = _cells(line)
            j = i + 2
            rows = []
            while j < len(lines) and lines[j].lstrip().startswith("|"):
                rows.append(_cells(lines[j]))
                j += 1
            out.append(Table(header, tuple(rows), heading, i + 1, j))
            i = j
            continue
        i += 1
    return out


__all__ = ["ROOT", "README", "documents", "name_of", "section", "Block", "blocks", "fenced", "commands",
           "numbered_commands", "Table", "tables"]
