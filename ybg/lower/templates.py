"""The Jinja environment of every backend, and the filters through which
every value reaches a template: templates only print what lowering built."""

from __future__ import annotations

from typing import TYPE_CHECKING

from ybg.lower.errors import Line

if TYPE_CHECKING:
    import jinja2


def xml_filter(text) -> str:
    """Text for an XML element or attribute value (a package.xml)."""
    from xml.sax.saxutils import escape

    if not isinstance(text, str):
        raise TypeError(f"expected a str, got {type(text).__name__}")
    return escape(text, {'"': "&quot;", "'": "&apos;"})


def xml_comment_filter(text) -> str:
    """Text for inside an XML comment (which cannot hold ``--``)."""
    return xml_filter(text).replace("--", "- -")


def code_filter(text) -> str:
    """A one-line fragment of code that lowering already built from escaped
    parts (anything else is a bug, not something to print)."""
    if not isinstance(text, str):
        raise TypeError(f"expected lowered code, got {type(text).__name__}")
    if "\n" in text or "\r" in text:
        raise ValueError("lowered code must be one line")
    return text


def indent_line_filter(line: Line) -> str:
    """A :class:`Line` at its indentation (4 spaces a level)."""
    if not isinstance(line, Line):
        raise TypeError(f"expected a Line, got {type(line).__name__}")
    return "    " * line.indent + code_filter(line.text)


def py_comment_filter(text) -> str:
    """Text for a Python comment: one line."""
    if not isinstance(text, str):
        raise TypeError(f"expected a str, got {type(text).__name__}")
    return " ".join(text.splitlines())


def template_environment(folders, filters: dict) -> "jinja2.Environment":
    """A Jinja environment in which templates only print (autoescape off,
    undefined names are errors, whitespace as written), and every value
    reaches them through one of ``filters``."""
    import jinja2

    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader([str(f) for f in folders]),
        autoescape=False,
        undefined=jinja2.StrictUndefined,
        trim_blocks=True,
        lstrip_blocks=True,
        keep_trailing_newline=True,
    )
    env.filters.update(filters)
    return env


__all__ = ["xml_filter", "xml_comment_filter", "code_filter", "indent_line_filter", "py_comment_filter",
           "template_environment"]
