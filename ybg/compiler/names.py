"""Names that reach generated code or the middleware: YARP ports, ROS topics
and node names, module and mux identifiers. Validated here, once, so that no
backend pastes an unchecked name."""

from __future__ import annotations

import keyword
import re
import shlex
from pathlib import Path

CPP_KEYWORDS = frozenset("""
alignas alignof and and_eq asm auto bitand bitor bool break case catch char
char8_t char16_t char32_t class compl concept const consteval constexpr
constinit const_cast continue co_await co_return co_yield decltype default
delete do double dynamic_cast else enum explicit export extern false float for
friend goto if inline int long mutable namespace new noexcept not not_eq
nullptr operator or or_eq private protected public register reinterpret_cast
requires return short signed sizeof static static_assert static_cast struct
switch template this thread_local throw true try typedef typeid typename union
unsigned using virtual void volatile wchar_t while xor xor_eq main
""".split())

PY_KEYWORDS = frozenset(keyword.kwlist) | frozenset(getattr(keyword, "softkwlist", []))

#: words with a meaning of their own in a `[message]` value
RESERVED = frozenset({"counter", "timestamp", "time", "true", "false", "nan", "inf", "none"})

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")
_PORT = re.compile(r"/[^\s\"'\\,;#@]*\Z")
_TOPIC_TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"
_TOPIC = re.compile(rf"(/|~/)?{_TOPIC_TOKEN}(/{_TOPIC_TOKEN})*\Z")


def identifier_problem(name: str) -> str | None:
    """Why ``name`` cannot name a module or mux in generated C++ and Python."""
    if not _IDENT.match(name):
        return "must start with a letter or `_` and hold only letters, digits and `_`"
    if name in CPP_KEYWORDS or name in PY_KEYWORDS:
        return "is a C++ or Python keyword"
    if name.lower() in RESERVED:
        return "is a reserved word of the `[message]` section"
    if name.startswith("__"):
        return "must not start with `__`"
    return None


def port_problem(name: str) -> str | None:
    """Why ``name`` is not a valid YARP port name (None if it is)."""
    if not name.startswith("/"):
        return "a YARP port name starts with `/`"
    if name == "/":
        return "`/` alone is not a port name"
    if "@" in name:
        return "`@` is reserved for YARP's `topic@node` ROS names; use a ROS topic instead"
    if "//" in name:
        return "`//` is not allowed in a port name"
    if not _PORT.match(name):
        return "a port name holds no white space, quotes, backslashes, `,`, `;` or `#`"
    return None


def topic_problem(name: str) -> str | None:
    """Why ``name`` is not a valid ROS topic name (None if it is)."""
    if not _TOPIC.match(name):
        if "//" in name:
            return "`//` is not allowed in a topic name"
        if name.endswith("/"):
            return "a topic name does not end with `/`"
        if re.search(r"(^|/)[0-9]", name):
            return "a topic name component cannot start with a digit"
        return "a topic name holds letters, digits, `_` and `/` separators"
    return None


def sanitize_identifier(text: str) -> str:
    """A legal identifier from a file stem (`vizzy-upper.body` -> `vizzy_upper_body`)."""
    out = re.sub(r"[^A-Za-z0-9_]", "_", text)
    if not out or out[0].isdigit():
        out = "m_" + out
    if identifier_problem(out):
        out = out + "_module"
    return out


def converted_name(path: str) -> str:
    """The file the hints' `ybgc fmt --to named` commands write: the
    config's stem with `.named.ini`, in the current folder. A name of its
    own, so that converting several configs of one folder does not write
    them all into one file."""
    stem = Path(path).stem if path and not path.startswith("<") else ""
    return shlex.quote(f"{stem or 'config'}.named.ini")
