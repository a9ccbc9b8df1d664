"""ROS interface definitions (``.msg``, ``.srv``): their parser, and what it
gives: :class:`MsgDef` (fields and constants), :class:`SrvDef` (a request
and a response message), problems as data (:class:`MsgProblem`). The
message store that finds and caches them is :mod:`ybg.compiler.msgtypes`.

This module imports nothing outside the standard library and the IR: it is
on the start-up path of every ``ybgc`` command.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Union

from .ir import TypeRef

_COMMON_PRIMITIVES = frozenset(
    {"bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32",
     "int64", "uint64", "float32", "float64", "string"}
)
PRIMITIVES = {
    "ros1": _COMMON_PRIMITIVES | {"time", "duration"},
    "ros2": _COMMON_PRIMITIVES | {"wstring"},
}
"""Primitive type names of each dialect (the ``TypeRef.base`` of non-messages)."""

Value = Union[bool, int, float, str]


# --------------------------------------------------------------------------
# The model


@dataclass(frozen=True)
class MsgProblem:
    """Something wrong in a ``.msg`` file. ``line`` and ``column`` count from 1
    (0 when the problem is about the whole file, e.g. it cannot be read)."""

    path: str
    line: int
    column: int
    message: str

    def __str__(self) -> str:
        return f"{self.path}:{self.line}:{self.column}: {self.message}"


@dataclass(frozen=True)
class MsgField:
    """One field. ``default`` is the ROS 2 default value (a tuple for arrays),
    ``None`` when there is none. ``string_bound`` is ``N`` of ``string<=N``
    (of the elements, for an array of bounded strings). ``line`` and ``column``
    locate the field's type in its file; they do not take part in equality."""

    name: str
    type: TypeRef
    default: Union[Value, tuple[Value, ...], None] = None
    string_bound: int | None = None
    line: int = field(default=0, compare=False)
    column: int = field(default=0, compare=False)


@dataclass(frozen=True)
class MsgConstant:
    """A constant (``int32 FOO=1``): ``type`` is a primitive name."""

    name: str
    type: str
    value: Value
    line: int = field(default=0, compare=False)


@dataclass(frozen=True)
class MsgDef:
    """A message: ``name`` is ``pkg/Name``; ``fields`` in wire order; ``path``
    the file it was read from (``None`` when parsed from a string)."""

    name: str
    fields: tuple[MsgField, ...]
    constants: tuple[MsgConstant, ...] = ()
    path: str | None = None

    @property
    def package(self) -> str:
        return self.name.split("/", 1)[0]

    def field(self, name: str) -> MsgField | None:
        for f in self.fields:
            if f.name == name:
                return f
        return None

    def constant(self, name: str) -> MsgConstant | None:
        for c in self.constants:
            if c.name == name:
                return c
        return None


def normalize_name(name: str) -> str | None:
    """``pkg/Name`` or ``pkg/msg/Name`` -> ``pkg/Name``; ``None`` for anything else."""
    parts = name.strip().split("/")
    if len(parts) == 3 and parts[1] == "msg":
        parts = [parts[0], parts[2]]
    if len(parts) != 2 or not all(IDENTIFIER.fullmatch(p) for p in parts):
        return None
    return f"{parts[0]}/{parts[1]}"


# --------------------------------------------------------------------------
# Parsing one .msg file

IDENTIFIER = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
_TYPE = re.compile(
    r"(?P<base>[A-Za-z][A-Za-z0-9_]*(?:/[A-Za-z][A-Za-z0-9_]*){0,2})"
    r"(?:<=(?P<sbound>[^\[]*))?"
    r"(?:\[(?P<array>[^\]]*)\])?"
)
_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")
_ROS2_FIELD = re.compile(r"[a-z](?:[a-z0-9_]*[a-z0-9])?")
_ROS2_CONST = re.compile(r"[A-Z](?:[A-Z0-9_]*[A-Z0-9])?")
_INT_RANGES = {
    "int8": (-(2**7), 2**7 - 1), "uint8": (0, 2**8 - 1), "byte": (0, 2**8 - 1),
    "char": (0, 2**8 - 1), "int16": (-(2**15), 2**15 - 1), "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1), "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1), "uint64": (0, 2**64 - 1),
}
_ESCAPES = {"n": "\n", "t": "\t", "r": "\r", "0": "\0", "\\": "\\", '"': '"', "'": "'"}


class _Bad(Exception):
    """A problem at ``column`` (0-based offset into the line)."""

    def __init__(self, offset: int, message: str):
        super().__init__(message)
        self.offset = offset
        self.message = message


def _skip_ws(s: str, i: int) -> int:
    while i < len(s) and s[i] in " \t":
        i += 1
    return i


def _comment_start(s: str, i: int) -> int:
    """Offset of the ``#`` that starts a comment at or after ``i`` (quotes
    respected), or ``len(s)``."""
    quote = None
    while i < len(s):
        c = s[i]
        if quote:
            if c == "\\":
                i += 1
            elif c == quote:
                quote = None
        elif c in "\"'":
            quote = c
        elif c == "#":
            return i
        i += 1
    return len(s)


def _unquote(text: str, offset: int) -> str:
    q = text[0]
    if len(text) < 2 or text[-1] != q:
        raise _Bad(offset, f"unterminated string {text}")
    out = []
    body = text[1:-1]
    i = 0
    while i < len(body):
        c = body[i]
        if c == "\\" and i + 1 < len(body):
            out.append(_ESCAPES.get(body[i + 1], "\\" + body[i + 1]))
            i += 2
            continue
        if c == q:
            raise _Bad(offset + 1 + i, "unescaped quote inside a string")
        out.append(c)
        i += 1
    return "".join(out)


def _scalar(text: str, typ: str, offset: int, string_bound: int | None = None) -> Value:
    """A constant or default value of primitive ``typ``."""
    if typ in ("string", "wstring"):
        value = _unquote(text, offset) if text[:1] in "\"'" and text else text
        if string_bound is not None and len(value) > string_bound:
            raise _Bad(offset, f"string longer than its bound {string_bound}")
        return value
    if not text:
        raise _Bad(offset, f"missing {typ} value")
    if typ == "bool":
        low = text.lower()
        if low in ("true", "1"):
            return True
        if low in ("false", "0"):
            return False
        raise _Bad(offset, f"invalid bool value {text!r} (expected true or false)")
    if typ in ("float32", "float64"):
        try:
            return float(text)
        except ValueError:
            raise _Bad(offset, f"invalid {typ} value {text!r}") from None
    if typ in _INT_RANGES:
        try:
            value = int(text, 0)
        except ValueError:
            raise _Bad(offset, f"invalid {typ} value {text!r}") from None
        lo, hi = _INT_RANGES[typ]
        if not lo <= value <= hi:
            raise _Bad(offset, f"{typ} value {value} out of range [{lo}, {hi}]")
        return value
    raise _Bad(offset, f"type {typ} cannot have a value")


def _split_list(text: str, offset: int) -> list[tuple[str, int]]:
    """``[a, "b", c]`` -> items with their offsets."""
    if not (text.startswith("[") and text.endswith("]")):
        raise _Bad(offset, f"an array default must be a list in brackets, got {text!r}")
    items: list[tuple[str, int]] = []
    start, quote, i = 1, None, 1
    end = len(text) - 1
    while i <= end:
        c = text[i] if i < end else ","
        if quote:
            if c == "\\":
                i += 1
            elif c == quote:
                quote = None
        elif c in "\"'":
            quote = c
        elif c == ",":
            raw = text[start:i]
            lead = len(raw) - len(raw.lstrip())
            item = raw.strip()
            if item:
                items.append((item, offset + start + lead))
            elif i < end or items:
                raise _Bad(offset + start, "empty list item")
            start = i + 1
        i += 1
    return items


class _TypeSyntax:
    __slots__ = ("ref", "string_bound")

    def __init__(self, ref: TypeRef, string_bound: int | None):
        self.ref = ref
        self.string_bound = string_bound


def _parse_type(tok: str, offset: int, pkg: str, ros: str) -> _TypeSyntax:
    m = _TYPE.fullmatch(tok)
    if not m:
        raise _Bad(offset, f"invalid type {tok!r}")
    base = m["base"]
    parts = base.split("/")
    if len(parts) == 3:
        if parts[1] != "msg":
            raise _Bad(offset, f"invalid type {tok!r} (expected pkg/Name)")
        parts = [parts[0], parts[2]]
    if len(parts) == 1:
        name = parts[0]
        if name in PRIMITIVES[ros]:
            base = name
        elif ros == "ros1" and name == "Header":
            base = "std_msgs/Header"
        elif name[0].islower():
            hint = ""
            if ros == "ros2" and name in ("time", "duration"):
                hint = f" (ROS 2 uses builtin_interfaces/{name.capitalize()})"
            elif ros == "ros1" and name == "wstring":
                hint = " (ROS 1 has no wstring)"
            raise _Bad(offset, f"unknown primitive type {name!r}{hint}")
        else:
            base = f"{pkg}/{name}"
    else:
        base = f"{parts[0]}/{parts[1]}"
    string_bound = None
    if m["sbound"] is not None:
        sb_off = offset + m.start("sbound")
        if base not in ("string", "wstring"):
            raise _Bad(sb_off - 2, f"only strings can have a bound ('<=' after {base})")
        if ros == "ros1":
            raise _Bad(sb_off - 2, "ROS 1 has no bounded strings")
        if not m["sbound"].isdigit() or int(m["sbound"]) == 0:
            raise _Bad(sb_off, f"invalid string bound {m['sbound']!r}")
        string_bound = int(m["sbound"])
    arr = m["array"]
    if arr is None:
        return _TypeSyntax(TypeRef(base), string_bound)
    a_off = offset + m.start("array")
    if arr == "":
        return _TypeSyntax(TypeRef(base, "sequence"), string_bound)
    if arr.startswith("<="):
        if ros == "ros1":
            raise _Bad(a_off, "ROS 1 has no bounded arrays")
        if not arr[2:].isdigit() or int(arr[2:]) == 0:
            raise _Bad(a_off + 2, f"invalid array bound {arr[2:]!r}")
        return _TypeSyntax(TypeRef(base, "sequence", int(arr[2:])), string_bound)
    if not arr.isdigit() or int(arr) == 0:
        raise _Bad(a_off, f"invalid array size {arr!r}")
    return _TypeSyntax(TypeRef(base, "fixed", int(arr)), string_bound)


def _default(text: str, offset: int, ts: _TypeSyntax):
    ref = ts.ref
    if ref.is_message or ref.base in ("time", "duration"):
        raise _Bad(offset, f"a field of type {ref.base} cannot have a default value")
    if ref.array is None:
        return _scalar(text, ref.base, offset, ts.string_bound)
    items = _split_list(text, offset)
    values = tuple(_scalar(t, ref.base, o, ts.string_bound) for t, o in items)
    if ref.array == "fixed" and len(values) != ref.size:
        raise _Bad(offset, f"default has {len(values)} items, the array {ref.size}")
    if ref.size is not None and len(values) > ref.size:
        raise _Bad(offset, f"default has {len(values)} items, more than the bound {ref.size}")
    return values


def _parse_line(s: str, pkg: str, ros: str, lineno: int):
    """One non-blank, non-comment line -> (MsgField | MsgConstant, offset of
    its name); raises _Bad."""
    i = _skip_ws(s, 0)
    j = i
    while j < len(s) and s[j] not in " \t#":
        j += 1
    ts = _parse_type(s[i:j], i, pkg, ros)
    k = _skip_ws(s, j)
    m = _NAME.match(s, k)
    if not m:
        if k >= len(s) or s[k] == "#":
            raise _Bad(k, f"expected a field name after the type {s[i:j]}")
        raise _Bad(k, f"invalid field name starting with {s[k]!r}")
    name = m.group()
    p = _skip_ws(s, m.end())
    if p < len(s) and s[p] == "=":
        # a constant
        if ts.ref.array is not None or ts.ref.base not in PRIMITIVES[ros] \
                or ts.ref.base in ("time", "duration"):
            raise _Bad(i, f"a constant must have a primitive type, not {ts.ref}")
        if ros == "ros2" and not _ROS2_CONST.fullmatch(name):
            raise _Bad(k, f"invalid constant name {name!r} (ROS 2 wants upper case, "
                          "letters, digits and single underscores)")
        v = _skip_ws(s, p + 1)
        if ros == "ros1" and ts.ref.base == "string":
            text = s[v:].strip()
        else:
            text = s[v:_comment_start(s, v)].rstrip()
        value = _scalar(text, ts.ref.base, v, ts.string_bound)
        return MsgConstant(name, ts.ref.base, value, lineno), k
    if ros == "ros2" and (not _ROS2_FIELD.fullmatch(name) or "__" in name):
        raise _Bad(k, f"invalid field name {name!r} (ROS 2 wants lower case, "
                      "letters, digits and single underscores)")
    if m.end() < len(s) and s[m.end()] not in " \t#":
        raise _Bad(m.end(), f"unexpected {s[m.end()]!r} after the field name")
    rest = s[p:_comment_start(s, p)].rstrip()
    default = None
    if rest:
        if ros == "ros1":
            raise _Bad(p, "unexpected text after the field name (ROS 1 has no default values)")
        default = _default(rest, p, ts)
    return MsgField(name, ts.ref, default, ts.string_bound, lineno, i + 1), k


def parse_msg(text: str, name: str, ros: str, path: str | None = None
              ) -> tuple[MsgDef, list[MsgProblem]]:
    """Parse the text of ``name`` (``pkg/Name``) in dialect ``ros``.

    Returns the definition made of the lines that parsed, and the problems of
    the others. Never raises on bad input."""
    if ros not in PRIMITIVES:
        raise ValueError(f"unknown ROS dialect {ros!r}")
    where = path if path is not None else f"<{name}>"
    pkg = name.split("/", 1)[0]
    fields: list[MsgField] = []
    constants: list[MsgConstant] = []
    problems: list[MsgProblem] = []
    seen: dict[str, int] = {}
    for lineno, line in enumerate(text.splitlines(), 1):
        line = line.rstrip("\r")
        start = _skip_ws(line, 0)
        if start >= len(line) or line[start] == "#":
            continue
        if line.startswith("---") and not line.strip("-").strip():
            problems.append(MsgProblem(where, lineno, 1, "'---' separator in a message "
                                       "(that is a service or action definition)"))
            break
        try:
            item, name_offset = _parse_line(line, pkg, ros, lineno)
        except _Bad as e:
            problems.append(MsgProblem(where, lineno, e.offset + 1, e.message))
            continue
        if item.name in seen:
            problems.append(MsgProblem(where, lineno, name_offset + 1, f"{item.name!r} already defined "
                                       f"on line {seen[item.name]}"))
            continue
        seen[item.name] = lineno
        (fields if isinstance(item, MsgField) else constants).append(item)
    return MsgDef(name, tuple(fields), tuple(constants), path), problems


@dataclass(frozen=True)
class SrvDef:
    """A service: ``name`` is ``pkg/Name``; its ``request`` and ``response``
    are messages named ``pkg/Name_Request`` and ``pkg/Name_Response``, as
    rosidl names them."""

    name: str
    request: MsgDef
    response: MsgDef
    path: str | None = None


def _parse_parts(text: str, name: str, ros: str, path: str | None, parts: tuple[str, ...]
                 ) -> tuple[list[MsgDef], list[MsgProblem]]:
    """The messages ``name_<part>`` of a file of ``len(parts)`` messages
    separated by ``---`` lines (a .srv: request, response; an .action: goal,
    result, feedback). A missing ``---`` is a problem; the parts it leaves
    out are empty."""
    lines = text.splitlines()
    cuts = [k for k, line in enumerate(lines) if line.startswith("---") and not line.strip().strip("-")]
    where = path if path is not None else f"<{name}>"
    problems: list[MsgProblem] = []
    if len(cuts) < len(parts) - 1:
        missing = parts[len(cuts)], parts[len(cuts) + 1]
        problems.append(MsgProblem(where, max(1, len(lines)), 1,
                                   f"no '---' line between the {missing[0].lower()} and the {missing[1].lower()}"))
    elif len(cuts) > len(parts) - 1:
        k = cuts[len(parts) - 1]
        problems.append(MsgProblem(where, k + 1, 1, f"a {len(parts)}th '---' line: a file of this kind has "
                                   f"{len(parts)} parts ({', '.join(p.lower() for p in parts)})"))
        cuts = cuts[:len(parts) - 1]
    bounds = [-1] + cuts + [len(lines)] * (len(parts) - len(cuts))
    out = []
    for i, part in enumerate(parts):
        first = bounds[i] + 1
        body = "\n" * first + "\n".join(lines[first:bounds[i + 1]]) if first <= len(lines) else ""
        msg, found = parse_msg(body, f"{name}_{part}", ros, path)
        out.append(msg)
        problems += found
    return out, problems


def parse_srv(text: str, name: str, ros: str, path: str | None = None
              ) -> tuple[SrvDef, list[MsgProblem]]:
    """Parse the text of the service ``name`` (``pkg/Name``): the request's
    lines, a ``---`` line, the response's. Never raises on bad input."""
    (request, response), problems = _parse_parts(text, name, ros, path, ("Request", "Response"))
    return SrvDef(name, request, response, path), problems


@dataclass(frozen=True)
class ActionDef:
    """An action: ``name`` is ``pkg/Name``; its ``goal``, ``result`` and
    ``feedback`` are messages named ``pkg/Name_Goal``, ``pkg/Name_Result``
    and ``pkg/Name_Feedback``, as rosidl names them."""

    name: str
    goal: MsgDef
    result: MsgDef
    feedback: MsgDef
    path: str | None = None

    @property
    def parts(self) -> tuple[MsgDef, MsgDef, MsgDef]:
        return (self.goal, self.result, self.feedback)


def parse_action(text: str, name: str, ros: str, path: str | None = None
                 ) -> tuple[ActionDef, list[MsgProblem]]:
    """Parse the text of the action ``name`` (``pkg/Name``): the goal's lines,
    ``---``, the result's, ``---``, the feedback's. Never raises on bad input."""
    (goal, result, feedback), problems = _parse_parts(text, name, ros, path, ("Goal", "Result", "Feedback"))
    return ActionDef(name, goal, result, feedback, path), problems


__all__ = ["PRIMITIVES", "Value", "MsgProblem", "MsgField", "MsgConstant", "MsgDef", "normalize_name", "IDENTIFIER", "parse_msg", "SrvDef", "parse_srv", "ActionDef", "parse_action"]
