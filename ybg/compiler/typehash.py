"""ROS 2 type hashes (RIHS01, REP-2011), computed from ybgc's own definitions.

Since Iron, a ROS 2 message type has a hash of its description: every
publisher and subscription advertises it, and the graph reports it with each
endpoint (``ros2 topic info --verbose``). Two sides that disagree on the hash
disagree on the type, even when its name is the same. This module computes
the hash of a type from the ``.msg`` definitions of a
:class:`~ybg.compiler.msgtypes.TypeStore`, as rosidl's type description
generator does from the ``.idl`` that rosidl_adapter makes of a ``.msg``:

- the *type description* is the type and every type it references
  (transitively, sorted by name), each as its name (``pkg/msg/Name``) and its
  fields in order; a field is its name and its type: a type id (the
  constants of ``type_description_interfaces/msg/FieldType``), a capacity
  (the size of a fixed array, the bound of a bounded sequence, else 0), a
  string capacity (``N`` of ``string<=N``, else 0) and the nested type's name
  (``""`` for a primitive). Constants are not part of it; default values are,
  but not of what is hashed, so they are left out here.
- a ``.msg`` type becomes its IDL type: ``char`` is ``uint8`` and ``byte`` an
  octet; a message without fields gets the one field IDL requires,
  ``uint8 structure_needs_at_least_one_member``; ``wstring<=N[]`` is a
  sequence bounded by ``N``, as rosidl_parser reads its IDL.
- the hash is the SHA-256 of that description as JSON (keys in the order
  above, separators ``", "`` and ``": "``, ASCII), written
  ``RIHS01_<64 hex digits>``.

A service ``pkg/Name`` (:func:`service_hash`) is described as rosidl
describes the ``.idl`` of a ``.srv``: the type ``pkg/srv/Name`` with three
message fields, ``request_message`` (``pkg/srv/Name_Request``),
``response_message`` (``pkg/srv/Name_Response``) and ``event_message``
(``pkg/srv/Name_Event``: ``service_msgs/ServiceEventInfo info``,
``Name_Request[<=1] request``, ``Name_Response[<=1] response``, the message of
service introspection); the request and the response are described as
messages of that name, and every type they reference is in the description.

Humble predates type hashes, and ROS 1 has none (it has MD5 sums of another
text): :func:`type_hash` and :func:`service_hash` give ``None`` for them.

Pure Python, the standard library and ybgc's message model only: it runs
without ROS installed, and nothing imports it on the way of a command that
does not print hashes (``ybgc ir`` does).
"""

from __future__ import annotations

import hashlib
import json
import os
from typing import Any, Iterable, Mapping

from .ir import Program, TypeRef
from .msgtypes import MsgDef, TypeStore, load_store, normalize_name, parse_msg
from .options import Options

RIHS01_PREFIX = "RIHS01_"

NO_TYPE_HASH_DISTROS = frozenset({"humble"})
"""The ROS 2 distros ybgc knows that predate type hashes (REP-2011 came with Iron)."""

EMPTY_STRUCTURE_MEMBER = "structure_needs_at_least_one_member"
"""The field IDL gives a message without fields (rosidl_parser's name, type uint8)."""

FIELD_TYPE_NESTED_TYPE = 1
"""The type id of a message field (``FIELD_TYPE_NESTED_TYPE``)."""

FIELD_TYPE_IDS = {
    "int8": 2, "uint8": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7,
    "int64": 8, "uint64": 9, "float32": 10, "float64": 11,
    "char": 3,  # a .msg char is an IDL uint8
    "bool": 15, "byte": 16,  # boolean, octet
    "string": 17, "wstring": 18,
}
"""The type id of each ``.msg`` primitive (``FieldType.msg``'s ``FIELD_TYPE_*``)."""

BOUNDED_STRING_IDS = {"string": 21, "wstring": 22}
"""``string<=N`` and ``wstring<=N`` (``FIELD_TYPE_BOUNDED_STRING``, ``..._WSTRING``)."""

ARRAY_ID_OFFSET = {None: 0, "fixed": 48, "bounded": 96, "sequence": 144}
"""What an array adds to its element's type id: ``T[N]`` 48, ``T[<=N]`` 96, ``T[]`` 144."""


SERVICE_EVENT_INFO = "service_msgs/ServiceEventInfo"
"""The first field of every service's ``Name_Event`` message (its type, ``pkg/Name``)."""

SERVICE_EVENT_INFO_MSG = """\
uint8 REQUEST_SENT = 0
uint8 REQUEST_RECEIVED = 1
uint8 RESPONSE_SENT = 2
uint8 RESPONSE_RECEIVED = 3
uint8 event_type
builtin_interfaces/Time stamp
char[16] client_gid
int64 sequence_number
"""
"""``service_msgs/msg/ServiceEventInfo.msg`` (ros2/rcl_interfaces, unchanged since
Iron, comments left out), for a store that has no definition of it: ybgc
ships no service_msgs, which only services' introspection uses."""

SERVICE_SUFFIXES = ("_Request", "_Response", "_Event")
"""The messages of a service ``pkg/Name``: ``pkg/srv/Name_Request`` ..."""


def has_type_hashes(store: TypeStore) -> bool:
    """Do the types of ``store``'s distro have type hashes?"""
    return store.ros == "ros2" and store.distro not in NO_TYPE_HASH_DISTROS


def ros2_name(name: str) -> str:
    """``pkg/Name`` -> ``pkg/msg/Name``, the spelling of type descriptions."""
    pkg, _, msg = name.partition("/")
    return f"{pkg}/msg/{msg}"


def field_type(ref: TypeRef, string_bound: int | None = None) -> dict[str, Any]:
    """The ``FieldType`` of a field of type ``ref`` (``string_bound``: ``N``
    of ``string<=N``, of the elements for an array), keys in hashed order."""
    if ref.is_message:
        element_id = FIELD_TYPE_NESTED_TYPE
    elif string_bound is not None and ref.base in BOUNDED_STRING_IDS:
        element_id = BOUNDED_STRING_IDS[ref.base]
    else:
        element_id = FIELD_TYPE_IDS[ref.base]
    size = ref.size
    if ref.array == "sequence" and size is None and ref.base == "wstring" and string_bound is not None:
        # rosidl_parser reads the IDL of `wstring<=N[]`, `sequence<wstring<N>>`, as a
        # sequence bounded by N (it skips the string's bound for `string<N>` only):
        # so is the type ROS builds, and so its hash
        size = string_bound
    array = "bounded" if ref.array == "sequence" and size is not None else ref.array
    return {
        "type_id": element_id + ARRAY_ID_OFFSET[array],
        "capacity": size or 0,
        "string_capacity": string_bound or 0,
        "nested_type_name": ros2_name(ref.base) if ref.is_message else "",
    }


def individual_description(msgdef: MsgDef) -> dict[str, Any]:
    """The ``IndividualTypeDescription`` of one message, without default values."""
    fields = [{"name": f.name, "type": field_type(f.type, f.string_bound)} for f in msgdef.fields]
    if not fields:
        fields = [{"name": EMPTY_STRUCTURE_MEMBER, "type": field_type(TypeRef("uint8"))}]
    return {"type_name": ros2_name(msgdef.name), "fields": fields}


class _Descriptions:
    """Individual descriptions of one store's types, each made once."""

    def __init__(self, store: TypeStore):
        self.store = store
        self.made: dict[str, dict[str, Any]] = {}

    def individual(self, name: str) -> dict[str, Any]:
        """By ``pkg/Name``; ``LookupError`` when the store has no (valid) definition."""
        if name not in self.made:
            msgdef = self.store.resolve(name)
            if msgdef is None and name == SERVICE_EVENT_INFO and self.store.path_of(name) is None:
                msgdef, _ = parse_msg(SERVICE_EVENT_INFO_MSG, name, "ros2")
            if msgdef is None:
                raise LookupError(f"no definition of `{name}` ({self.store.ros}, {self.store.distro})")
            self.made[name] = individual_description(msgdef)
        return self.made[name]

    def _closure(self, top: dict[str, Any], local: Mapping[str, dict[str, Any]]) -> dict[str, Any]:
        """The full description of ``top``: it and every type it references,
        by ``type_name``, from ``local`` (the types of a service) or the store."""
        referenced: dict[str, dict[str, Any]] = {}
        queue = [top]
        while queue:
            for f in queue.pop()["fields"]:
                nested = f["type"]["nested_type_name"]
                if nested and nested not in referenced:
                    if nested in local:
                        referenced[nested] = local[nested]
                    else:
                        pkg, _, msg = nested.split("/")
                        referenced[nested] = self.individual(f"{pkg}/{msg}")
                    queue.append(referenced[nested])
        return {
            "type_description": top,
            "referenced_type_descriptions": [referenced[n] for n in sorted(referenced)],
        }

    def full(self, name: str) -> dict[str, Any]:
        key = normalize_name(name)
        if key is None:
            raise LookupError(f"`{name}` is not a message type name (pkg/Name)")
        return self._closure(self.individual(key), {})

    def service(self, name: str) -> dict[str, Any]:
        """The full description of the service ``name`` (``pkg/Name`` or ``pkg/srv/Name``)."""
        srv = self.store.resolve_service(name)
        if srv is None:
            raise LookupError(f"no definition of the service `{name}` ({self.store.ros}, {self.store.distro})")
        pkg, _, base = srv.name.partition("/")
        prefix = f"{pkg}/srv/{base}"
        request, response, event = (prefix + s for s in SERVICE_SUFFIXES)

        def nested(type_name: str, bound: int | None = None) -> dict[str, Any]:
            array = None if bound is None else "bounded"
            return {"type_id": FIELD_TYPE_NESTED_TYPE + ARRAY_ID_OFFSET[array], "capacity": bound or 0,
                    "string_capacity": 0, "nested_type_name": type_name}

        local = {
            request: {**individual_description(srv.request), "type_name": request},
            response: {**individual_description(srv.response), "type_name": response},
            event: {"type_name": event, "fields": [
                {"name": "info", "type": nested(ros2_name(SERVICE_EVENT_INFO))},
                {"name": "request", "type": nested(request, 1)},
                {"name": "response", "type": nested(response, 1)},
            ]},
        }
        top = {"type_name": prefix, "fields": [
            {"name": "request_message", "type": nested(request)},
            {"name": "response_message", "type": nested(response)},
            {"name": "event_message", "type": nested(event)},
        ]}
        return self._closure(top, local)


def type_description(store: TypeStore, name: str) -> dict[str, Any]:
    """The ``TypeDescription`` of ``name`` (``pkg/Name`` or ``pkg/msg/Name``)
    as hashed: the type and every type it references, sorted by name, no
    default values. ``LookupError`` when a definition is missing."""
    return _Descriptions(store).full(name)


def hash_description(description: Mapping[str, Any]) -> str:
    """``RIHS01_<sha256>`` of a type description (as :func:`type_description` gives)."""
    text = json.dumps(description, ensure_ascii=True, allow_nan=False, separators=(", ", ": "))
    return RIHS01_PREFIX + hashlib.sha256(text.encode("utf-8")).hexdigest()


def type_hashes(store: TypeStore, names: Iterable[str]) -> dict[str, str | None]:
    """The RIHS01 hash of each of ``names`` by that name, from ``store``'s
    definitions; all ``None`` for ROS 1 and Humble. ``LookupError`` when a
    definition is missing (the type's or one it references)."""
    names = list(names)
    if not has_type_hashes(store):
        return {n: None for n in names}
    descriptions = _Descriptions(store)
    return {n: hash_description(descriptions.full(n)) for n in names}


def type_hash(store: TypeStore, name: str) -> str | None:
    """The RIHS01 hash of one type (see :func:`type_hashes`)."""
    return type_hashes(store, [name])[name]


def service_description(store: TypeStore, name: str) -> dict[str, Any]:
    """The ``TypeDescription`` of the service ``name`` (``pkg/Name`` or
    ``pkg/srv/Name``) as hashed: ``pkg/srv/Name`` with its request, response
    and event messages, and every type they reference, sorted by name, no
    default values. ``LookupError`` when a definition is missing."""
    return _Descriptions(store).service(name)


def service_hashes(store: TypeStore, names: Iterable[str]) -> dict[str, str | None]:
    """The RIHS01 hash of each of the services ``names`` by that name, from
    ``store``'s definitions; all ``None`` for ROS 1 and Humble. ``LookupError``
    when a definition is missing (the service's, or a type it references)."""
    names = list(names)
    if not has_type_hashes(store):
        return {n: None for n in names}
    descriptions = _Descriptions(store)
    return {n: hash_description(descriptions.service(n)) for n in names}


def service_hash(store: TypeStore, name: str) -> str | None:
    """The RIHS01 hash of one service (see :func:`service_hashes`): the hash
    a ROS 2 service server or client of that type advertises."""
    return service_hashes(store, [name])[name]


# --------------------------------------------------------------------------
# What ``ybgc ir`` prints


def program_store(program: Program, options: Options) -> TypeStore | None:
    """The ROS 2 definitions ``program`` was checked against (its distro, the
    user's folders and environment of ``options``); ``None`` for a program
    without ROS 2."""
    if program.ros != "ros2":
        return None
    env = options.environ if options.environ is not None else os.environ
    return load_store("ros2", program.distro, options.msg_path, env)


def with_type_hashes(ir_dict: dict[str, Any], store: TypeStore | None) -> dict[str, Any]:
    """The IR as ``ybgc ir`` prints it: the dict of :func:`ybg.compiler.ir.to_dict`
    whose ROS ends also carry ``type_hash``, the RIHS01 hash of their type
    from ``store`` (:func:`program_store`), by the bridge's kind (a stream's
    topics, a config of commands' services). Changes ``ir_dict`` and returns it."""
    return _WITH_TYPE_HASHES[ir_dict.get("bridge", "stream")](ir_dict, store)


def _stream_type_hashes(ir_dict: dict[str, Any], store: TypeStore | None) -> dict[str, Any]:
    """The output and each input, when a ROS topic: ``None`` for a ROS 1
    topic, for Humble, and for a type whose definition (or one it
    references) is missing."""
    descriptions = _Descriptions(store) if store is not None and has_type_hashes(store) else None
    ends = [(ir_dict["output"], ir_dict["output"].get("msg_type"))]
    ends += [(i, i.get("ros_type")) for m in ir_dict["muxes"] for i in m["inputs"]]
    for end, name in ends:
        if end.get("kind") not in ("ros1", "ros2"):
            continue
        end["type_hash"] = None
        if end["kind"] == "ros2" and name and descriptions is not None:
            try:
                end["type_hash"] = hash_description(descriptions.full(name))
            except LookupError:
                pass
    return ir_dict


def _commands_type_hashes(ir_dict: dict[str, Any], store: TypeStore | None) -> dict[str, Any]:
    """Each service: ``None`` where its definition cannot be read."""
    for svc in ir_dict["services"]:
        try:
            svc["type_hash"] = service_hash(store, svc["srv_type"]) if store is not None else None
        except LookupError:
            svc["type_hash"] = None
    return ir_dict


def _actions_type_hashes(ir_dict: dict[str, Any], store: TypeStore | None) -> dict[str, Any]:
    """Actions: no hash yet (an action's type description holds its goal,
    result and feedback, and the services and the message rcl_action makes
    of them); the IR as it is."""
    return ir_dict


#: kind of bridge (the IR dict's ``bridge``) -> its ends' type hashes
_WITH_TYPE_HASHES = {"stream": _stream_type_hashes, "commands": _commands_type_hashes,
                     "actions": _actions_type_hashes}


__all__ = [
    "RIHS01_PREFIX", "NO_TYPE_HASH_DISTROS", "FIELD_TYPE_IDS", "has_type_hashes", "field_type",
    "individual_description", "type_description", "hash_description", "type_hashes", "type_hash",
    "service_description", "service_hashes", "service_hash", "program_store", "with_type_hashes",
]
