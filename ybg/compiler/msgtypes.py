"""The ROS message type model: ``.msg`` definitions, parsed lazily.

A :class:`TypeStore` knows every message of one ROS dialect (``"ros1"`` or
``"ros2"``) and distro: the user's own definitions first, then the standard
ones shipped in ``ybg/msgs/<distro>/<pkg>/<Name>.msg``. A file is parsed only
when its type is asked for, then cached. Problems in a file are data
(:class:`MsgProblem`), collected in :attr:`TypeStore.problems`.

Field types are :class:`~ybg.compiler.ir.TypeRef`: ``base`` is a primitive
(``float64``, ``string``; for ROS 1 also ``time`` and ``duration``) or a
message ``pkg/Name`` (so the ROS 2 stamp is the message
``builtin_interfaces/Time`` with ``sec`` int32 and ``nanosec`` uint32).
Bounds of bounded strings are kept in :attr:`MsgField.string_bound`, not in
the ``TypeRef``.

This module imports nothing outside the standard library and the IR: it is
on the start-up path of every ``ybgc`` command.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from typing import Iterable, Mapping, Union

from .ir import NUMERIC_TYPES, TypeRef

DISTROS = {"noetic": "ros1", "humble": "ros2", "jazzy": "ros2", "kilted": "ros2"}
"""Distros with vendored definitions, and the dialect of each."""

DEFAULT_DISTRO = {"ros1": "noetic", "ros2": "jazzy"}

_COMMON_PRIMITIVES = frozenset(
    {"bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32",
     "int64", "uint64", "float32", "float64", "string"}
)
PRIMITIVES = {
    "ros1": _COMMON_PRIMITIVES | {"time", "duration"},
    "ros2": _COMMON_PRIMITIVES | {"wstring"},
}
"""Primitive type names of each dialect (the ``TypeRef.base`` of non-messages)."""

VENDORED_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "msgs")

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
    if len(parts) != 2 or not all(_IDENT.fullmatch(p) for p in parts):
        return None
    return f"{parts[0]}/{parts[1]}"


# --------------------------------------------------------------------------
# Parsing one .msg file

_IDENT = re.compile(r"[A-Za-z][A-Za-z0-9_]*")
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


def parse_srv(text: str, name: str, ros: str, path: str | None = None
              ) -> tuple[SrvDef, list[MsgProblem]]:
    """Parse the text of the service ``name`` (``pkg/Name``): the request's
    lines, a ``---`` line, the response's. Never raises on bad input."""
    lines = text.splitlines()
    cut = next((k for k, line in enumerate(lines)
                if line.startswith("---") and not line.strip().strip("-")), None)
    where = path if path is not None else f"<{name}>"
    problems: list[MsgProblem] = []
    if cut is None:
        problems.append(MsgProblem(where, max(1, len(lines)), 1,
                                   "no '---' line between the request and the response"))
        cut = len(lines)
    request, p1 = parse_msg("\n".join(lines[:cut]), f"{name}_Request", ros, path)
    response, p2 = parse_msg("\n" * (cut + 1) + "\n".join(lines[cut + 1:]), f"{name}_Response", ros, path)
    return SrvDef(name, request, response, path), problems + p1 + p2


# --------------------------------------------------------------------------
# Where definitions are found


def _list_msgs(folder: str, ext: str = "msg") -> list[tuple[str, str]]:
    """``(Name, path)`` of the ``*.msg`` files (``ext``: ``*.srv``) directly in ``folder``."""
    try:
        entries = os.listdir(folder)
    except OSError:
        return []
    out = []
    suffix = "." + ext
    for e in sorted(entries):
        if e.endswith(suffix) and _IDENT.fullmatch(e[:-len(suffix)]):
            out.append((e[:-len(suffix)], os.path.join(folder, e)))
    return out


def _is_package(folder: str) -> bool:
    return os.path.isfile(os.path.join(folder, "package.xml")) or \
        os.path.isfile(os.path.join(folder, "manifest.xml"))


def _scan_dir(root: str, ext: str = "msg") -> list[tuple[str, str]]:
    """A message folder: ``<root>/<pkg>/msg/<Name>.msg`` and ``<root>/<pkg>/<Name>.msg``;
    ``<root>`` itself when it is a package (has ``package.xml``). With ``ext``
    ``"srv"``, the services: ``<root>/<pkg>/srv/<Name>.srv`` and ``<root>/<pkg>/<Name>.srv``."""
    out: list[tuple[str, str]] = []
    if _is_package(root):
        pkg = os.path.basename(os.path.normpath(root))
        out += [(f"{pkg}/{n}", p) for n, p in _list_msgs(os.path.join(root, ext), ext)]
    try:
        pkgs = sorted(os.listdir(root))
    except OSError:
        return out
    for pkg in pkgs:
        d = os.path.join(root, pkg)
        if not _IDENT.fullmatch(pkg) or not os.path.isdir(d):
            continue
        out += [(f"{pkg}/{n}", p) for n, p in _list_msgs(os.path.join(d, ext), ext)]
        out += [(f"{pkg}/{n}", p) for n, p in _list_msgs(d, ext)]
    return out


def _scan_ros1(root: str, ext: str = "msg") -> list[tuple[str, str]]:
    """A ``ROS_PACKAGE_PATH`` entry: every package folder below it (not below
    a package, nor in folders with ``CATKIN_IGNORE``), ``<pkg>/msg/*.msg``."""
    out: list[tuple[str, str]] = []
    for dirpath, dirnames, _files in os.walk(root, followlinks=True):
        if _is_package(dirpath):
            pkg = os.path.basename(os.path.normpath(dirpath))
            out += [(f"{pkg}/{n}", p) for n, p in _list_msgs(os.path.join(dirpath, ext), ext)]
            dirnames[:] = []
            continue
        if os.path.exists(os.path.join(dirpath, "CATKIN_IGNORE")):
            dirnames[:] = []
            continue
        dirnames[:] = sorted(d for d in dirnames if not d.startswith("."))
    return out


def _scan_ament(prefix: str, ext: str = "msg") -> list[tuple[str, str]]:
    """An ``AMENT_PREFIX_PATH`` entry: ``<prefix>/share/<pkg>/msg/*.msg`` (``srv/*.srv``)."""
    share = os.path.join(prefix, "share")
    try:
        pkgs = sorted(os.listdir(share))
    except OSError:
        return []
    out: list[tuple[str, str]] = []
    for pkg in pkgs:
        if _IDENT.fullmatch(pkg):
            out += [(f"{pkg}/{n}", p) for n, p in _list_msgs(os.path.join(share, pkg, ext), ext)]
    return out


def _scan_vendored(root: str, ext: str = "msg") -> list[tuple[str, str]]:
    out: list[tuple[str, str]] = []
    try:
        pkgs = sorted(os.listdir(root))
    except OSError:
        return out
    for pkg in pkgs:
        out += [(f"{pkg}/{n}", p) for n, p in _list_msgs(os.path.join(root, pkg), ext)]
    return out


_SCANNERS = {"dir": _scan_dir, "ros1": _scan_ros1, "ament": _scan_ament, "vendored": _scan_vendored}


# --------------------------------------------------------------------------
# The store


class TypeStore:
    """Every message of one dialect and distro, parsed on demand.

    ``roots`` are ``(kind, folder)`` in search order (the first definition of
    a name wins): kind ``"dir"`` (``<dir>/<pkg>/msg/<Name>.msg`` or
    ``<dir>/<pkg>/<Name>.msg``), ``"ros1"`` (a ``ROS_PACKAGE_PATH`` entry),
    ``"ament"`` (an ``AMENT_PREFIX_PATH`` prefix), ``"vendored"``
    (``<dir>/<pkg>/<Name>.msg``, the standard definitions). Use
    :func:`load_store` to build one.
    """

    def __init__(self, ros: str, distro: str, roots: Iterable[tuple[str, str]]):
        if ros not in PRIMITIVES:
            raise ValueError(f"unknown ROS dialect {ros!r} (expected ros1 or ros2)")
        self.ros = ros
        self.distro = distro
        self.roots = tuple(roots)
        for kind, _ in self.roots:
            if kind not in _SCANNERS:
                raise ValueError(f"unknown search path kind {kind!r}")
        self.problems: list[MsgProblem] = []
        """Problems of the files parsed so far (each file's once)."""
        self._index: dict[str, str] | None = None
        self._cache: dict[str, MsgDef | None] = {}
        self._srv_index: dict[str, str] | None = None
        self._srv_cache: dict[str, SrvDef | None] = {}

    @property
    def search_paths(self) -> list[str]:
        """The folders searched, in order (existing or not)."""
        return [folder for _, folder in self.roots]

    @property
    def primitives(self) -> frozenset[str]:
        return PRIMITIVES[self.ros]

    def _names(self) -> dict[str, str]:
        if self._index is None:
            index: dict[str, str] = {}
            for kind, folder in self.roots:
                for name, path in _SCANNERS[kind](folder):
                    index.setdefault(name, path)
            self._index = index
        return self._index

    def path_of(self, name: str) -> str | None:
        """The file that defines ``name`` (``pkg/Name`` or ``pkg/msg/Name``)."""
        key = normalize_name(name)
        return None if key is None else self._names().get(key)

    def __contains__(self, name: str) -> bool:
        return self.path_of(name) is not None

    def resolve(self, name: str) -> MsgDef | None:
        """The definition of ``pkg/Name`` (or ``pkg/msg/Name``); ``None`` when
        no file defines it, or its file has problems (then in :attr:`problems`)."""
        key = normalize_name(name)
        if key is None:
            return None
        if key in self._cache:
            return self._cache[key]
        path = self._names().get(key)
        result = None if path is None else self._load(key, path)
        self._cache[key] = result
        return result

    def _load(self, key: str, path: str) -> MsgDef | None:
        try:
            with open(path, encoding="utf-8") as f:
                text = f.read()
        except (OSError, UnicodeDecodeError) as e:
            self.problems.append(MsgProblem(path, 0, 0, f"cannot read: {e}"))
            return None
        msgdef, problems = parse_msg(text, key, self.ros, path)
        if problems:
            self.problems.extend(problems)
            return None
        index = self._names()
        for f in msgdef.fields:
            if f.type.is_message and f.type.base not in index:
                self.problems.append(MsgProblem(
                    path, f.line, f.column, f"unknown message type {f.type.base!r}"
                    f" (field {f.name!r})"))
        return msgdef

    def _services(self) -> dict[str, str]:
        if self._srv_index is None:
            index: dict[str, str] = {}
            for kind, folder in self.roots:
                for name, path in _SCANNERS[kind](folder, "srv"):
                    index.setdefault(name, path)
            self._srv_index = index
        return self._srv_index

    def service_path(self, name: str) -> str | None:
        """The file that defines the service ``name`` (``pkg/Name`` or ``pkg/srv/Name``)."""
        key = normalize_name(name.replace("/srv/", "/msg/", 1) if name.count("/") == 2 else name)
        return None if key is None else self._services().get(key)

    def resolve_service(self, name: str) -> SrvDef | None:
        """The definition of the service ``pkg/Name`` (or ``pkg/srv/Name``);
        ``None`` when no file defines it or its file has problems (then in
        :attr:`problems`). Its request and response then resolve as the
        messages ``pkg/Name_Request`` and ``pkg/Name_Response``."""
        key = normalize_name(name.replace("/srv/", "/msg/", 1) if name.count("/") == 2 else name)
        if key is None:
            return None
        if key in self._srv_cache:
            return self._srv_cache[key]
        path = self._services().get(key)
        result = None
        if path is not None:
            try:
                with open(path, encoding="utf-8") as f:
                    text = f.read()
            except (OSError, UnicodeDecodeError) as e:
                self.problems.append(MsgProblem(path, 0, 0, f"cannot read: {e}"))
                text = None
            if text is not None:
                srv, problems = parse_srv(text, key, self.ros, path)
                index = self._names()
                for part in (srv.request, srv.response):
                    for f in part.fields:
                        if f.type.is_message and f.type.base not in index:
                            problems.append(MsgProblem(path, f.line, f.column, f"unknown message type "
                                                       f"{f.type.base!r} (field {f.name!r})"))
                if problems:
                    self.problems.extend(problems)
                else:
                    result = srv
                    self._cache[srv.request.name] = srv.request
                    self._cache[srv.response.name] = srv.response
        self._srv_cache[key] = result
        return result

    def service_names(self) -> list[str]:
        """Every known service ``pkg/Name`` (sorted), e.g. for "did you mean"."""
        return sorted(self._services())

    def service_candidates(self, bare_name: str) -> list[str]:
        """Every service ``pkg/Name`` whose ``Name`` is ``bare_name`` (sorted)."""
        suffix = "/" + bare_name
        return sorted(n for n in self._services() if n.endswith(suffix))

    def candidates(self, bare_name: str) -> list[str]:
        """Every ``pkg/Name`` whose ``Name`` is ``bare_name`` (sorted)."""
        suffix = "/" + bare_name
        return sorted(n for n in self._names() if n.endswith(suffix))

    def all_names(self) -> list[str]:
        """Every known ``pkg/Name`` (sorted), e.g. for "did you mean"."""
        return sorted(self._names())

    def __repr__(self) -> str:
        return f"TypeStore({self.ros!r}, {self.distro!r}, {len(self.roots)} roots)"


def _env_list(environ: Mapping[str, str], var: str) -> list[str]:
    return [p for p in environ.get(var, "").split(os.pathsep) if p]


def load_store(ros: str, distro: str | None = None, msg_path: Iterable[str] = (),
               environ: Mapping[str, str] = os.environ) -> TypeStore:
    """The type store of dialect ``ros`` (``"ros1"``/``"ros2"``) and ``distro``
    (default :data:`DEFAULT_DISTRO`).

    Searched in order: each folder of ``msg_path``, then of ``YBG_MSG_PATH``
    (both ``<dir>/<pkg>/msg/<Name>.msg`` or ``<dir>/<pkg>/<Name>.msg``), then
    ``ROS_PACKAGE_PATH`` (ros1) or ``AMENT_PREFIX_PATH`` (ros2), then the
    vendored definitions of ``distro``. Folders that do not exist are skipped.
    Raises ``ValueError`` for an unknown dialect or distro, or a distro of the
    other dialect."""
    if ros not in PRIMITIVES:
        raise ValueError(f"unknown ROS dialect {ros!r} (expected ros1 or ros2)")
    if distro is None:
        distro = DEFAULT_DISTRO[ros]
    if distro not in DISTROS:
        raise ValueError(f"unknown distro {distro!r} (known: {', '.join(DISTROS)})")
    if DISTROS[distro] != ros:
        raise ValueError(f"distro {distro!r} is {DISTROS[distro]}, not {ros}")
    if isinstance(msg_path, (str, os.PathLike)):
        msg_path = [msg_path]
    roots = [("dir", os.fspath(p)) for p in msg_path]
    roots += [("dir", p) for p in _env_list(environ, "YBG_MSG_PATH")]
    if ros == "ros1":
        roots += [("ros1", p) for p in _env_list(environ, "ROS_PACKAGE_PATH")]
    else:
        roots += [("ament", p) for p in _env_list(environ, "AMENT_PREFIX_PATH")]
    roots.append(("vendored", os.path.join(VENDORED_DIR, distro)))
    return TypeStore(ros, distro, roots)


# --------------------------------------------------------------------------
# Helpers


def numeric_leaves(store: TypeStore, msgdef: MsgDef | str) -> list[tuple[str, str]] | None:
    """The numeric scalar leaves of an all-numeric message, in wire order, as
    ``(dotted_path, primitive)``: ``geometry_msgs/Point`` ->
    ``[("x", "float64"), ("y", "float64"), ("z", "float64")]``; fixed arrays
    expand to ``name[0]``, ``name[1]`` ... ``None`` when the message (or a
    nested one) has a non-numeric field (bool, string, time ...), a variable
    length array, or an unknown type."""
    if isinstance(msgdef, str):
        resolved = store.resolve(msgdef)
        if resolved is None:
            return None
        msgdef = resolved
    return _leaves(store, msgdef, ())


def _leaves(store: TypeStore, msgdef: MsgDef, stack: tuple[str, ...]):
    out: list[tuple[str, str]] = []
    for f in msgdef.fields:
        t = f.type
        if t.array == "sequence":
            return None
        names = [f.name] if t.array is None else [f"{f.name}[{i}]" for i in range(t.size or 0)]
        if t.is_message:
            if t.base in stack or t.base == msgdef.name:
                return None
            sub = store.resolve(t.base)
            if sub is None:
                return None
            leaves = _leaves(store, sub, stack + (msgdef.name,))
            if leaves is None:
                return None
            out += [(f"{n}.{p}", prim) for n in names for p, prim in leaves]
        elif t.base in NUMERIC_TYPES:
            out += [(n, t.base) for n in names]
        else:
            return None
    return out


def field_positions(store: TypeStore, msg_type: str, fields) -> tuple[tuple[int, ...], ...]:
    """Where each field (``point.x``, ``position``, ``covariance[3]``) sits
    in the message ``msg_type``, as an index path: at each level the field's
    index among its message's fields, then the element's index for an array
    element. ``point.x`` of ``geometry_msgs/PointStamped`` is ``(1, 0)``.
    The fields must exist (the checker found them with :func:`numeric_leaves`
    or by name)."""
    out = []
    for path in fields:
        cur = store.resolve(msg_type)
        at: list[int] = []
        for part in path.split("."):
            name, _, rest = part.partition("[")
            assert cur is not None, (msg_type, path)
            names = [f.name for f in cur.fields]
            k = names.index(name)
            at.append(k)
            t = cur.fields[k].type
            if rest:
                at.append(int(rest.rstrip("]")))
                t = t.element()
            cur = store.resolve(t.base) if t.is_message and t.array is None else None
        out.append(tuple(at))
    return tuple(out)


__all__ = [
    "DISTROS", "DEFAULT_DISTRO", "PRIMITIVES", "VENDORED_DIR", "MsgProblem", "MsgField",
    "MsgConstant", "MsgDef", "TypeStore", "load_store", "parse_msg", "normalize_name",
    "numeric_leaves", "field_positions",
]
