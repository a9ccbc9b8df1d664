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
from typing import Iterable, Mapping

from .ir import NUMERIC_TYPES
# the definitions' model and parser, here for every module that knows them from here
from .msgdef import (IDENTIFIER, PRIMITIVES, ActionDef, MsgConstant, MsgDef, MsgField, MsgProblem,  # noqa: F401
                     SrvDef, Value, normalize_name, parse_action, parse_msg, parse_srv)  # noqa: F401

DISTROS = {"noetic": "ros1", "humble": "ros2", "jazzy": "ros2", "kilted": "ros2"}
"""Distros with vendored definitions, and the dialect of each."""

DEFAULT_DISTRO = {"ros1": "noetic", "ros2": "jazzy"}

VENDORED_DIR = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "msgs")


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
        if e.endswith(suffix) and IDENTIFIER.fullmatch(e[:-len(suffix)]):
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
        if not IDENTIFIER.fullmatch(pkg) or not os.path.isdir(d):
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
        if IDENTIFIER.fullmatch(pkg):
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
        self._iface_index: dict[str, dict[str, str]] = {}
        self._iface_cache: dict[tuple[str, str], SrvDef | ActionDef | None] = {}

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

    def _interfaces(self, ext: str) -> dict[str, str]:
        """``{pkg/Name: path}`` of the ``.srv`` or ``.action`` files (``ext``)."""
        if ext not in self._iface_index:
            index: dict[str, str] = {}
            for kind, folder in self.roots:
                for name, path in _SCANNERS[kind](folder, ext):
                    index.setdefault(name, path)
            self._iface_index[ext] = index
        return self._iface_index[ext]

    def _services(self) -> dict[str, str]:
        return self._interfaces("srv")

    @staticmethod
    def _key(name: str, ext: str) -> str | None:
        return normalize_name(name.replace(f"/{ext}/", "/msg/", 1) if name.count("/") == 2 else name)

    def service_path(self, name: str) -> str | None:
        """The file that defines the service ``name`` (``pkg/Name`` or ``pkg/srv/Name``)."""
        key = self._key(name, "srv")
        return None if key is None else self._services().get(key)

    def resolve_service(self, name: str) -> SrvDef | None:
        """The definition of the service ``pkg/Name`` (or ``pkg/srv/Name``);
        ``None`` when no file defines it or its file has problems (then in
        :attr:`problems`). Its request and response then resolve as the
        messages ``pkg/Name_Request`` and ``pkg/Name_Response``."""
        return self._resolve_interface("srv", name)

    def action_path(self, name: str) -> str | None:
        """The file that defines the action ``name`` (``pkg/Name`` or ``pkg/action/Name``)."""
        key = self._key(name, "action")
        return None if key is None else self._interfaces("action").get(key)

    def resolve_action(self, name: str) -> ActionDef | None:
        """The definition of the action ``pkg/Name`` (or ``pkg/action/Name``);
        ``None`` when no file defines it or its file has problems (then in
        :attr:`problems`). Its goal, result and feedback then resolve as the
        messages ``pkg/Name_Goal``, ``pkg/Name_Result``, ``pkg/Name_Feedback``."""
        return self._resolve_interface("action", name)

    def action_names(self) -> list[str]:
        """Every known action ``pkg/Name`` (sorted)."""
        return sorted(self._interfaces("action"))

    def _resolve_interface(self, ext: str, name: str):
        key = self._key(name, ext)
        if key is None:
            return None
        if (ext, key) in self._iface_cache:
            return self._iface_cache[ext, key]
        path = self._interfaces(ext).get(key)
        result = None
        if path is not None:
            try:
                with open(path, encoding="utf-8") as f:
                    text = f.read()
            except (OSError, UnicodeDecodeError) as e:
                self.problems.append(MsgProblem(path, 0, 0, f"cannot read: {e}"))
                text = None
            if text is not None:
                parsed, problems = (parse_srv if ext == "srv" else parse_action)(text, key, self.ros, path)
                parts = (parsed.request, parsed.response) if ext == "srv" else parsed.parts
                index = self._names()
                for part in parts:
                    for f in part.fields:
                        if f.type.is_message and f.type.base not in index:
                            problems.append(MsgProblem(path, f.line, f.column, f"unknown message type "
                                                       f"{f.type.base!r} (field {f.name!r})"))
                if problems:
                    self.problems.extend(problems)
                else:
                    result = parsed
                    for part in parts:
                        self._cache[part.name] = part
        self._iface_cache[ext, key] = result
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
