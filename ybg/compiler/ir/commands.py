"""A config of commands' checked program (:class:`Commands`): YARP RPC
ports and ROS 2 services, each command a Bottle made from a request or a
reply, and fields filled from a Bottle (docs/services.md)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import ClassVar, Union

from ybg.compiler.diagnostics import Span
from ybg.compiler.ir.streams import Converter, ElementGroup, TypeRef

@dataclass(frozen=True)
class FieldRef:
    """A field of a service's request or response, by ``path``
    (``("target", "x")``): its ``type`` (:class:`TypeRef`, a primitive or an
    array of one; ``time`` and ``duration`` are messages of two integers)."""

    path: tuple[str, ...]
    type: TypeRef
    span: Span | None = field(default=None, compare=False, repr=False)

    @property
    def dotted(self) -> str:
        return ".".join(self.path)


@dataclass(frozen=True)
class BottleItem:
    """One item of a Bottle the module writes: the command it sends to a YARP
    RPC port (from the request), or the reply it gives on its own RPC port
    (from the response).

    ``kind``:
      ``"literal"``  ``value`` of ``type`` (``string``, ``int32``, ``int64``,
                     ``float64``; a bool is written as the int32 0 or 1, as
                     ybgc writes bools in every Bottle)
      ``"field"``    the field ``ref`` of the message, converted by ``converter``
                     (``y = x * scale + offset``; None: as it is); an array
                     field gives one item per element
      ``"list"``     a nested list of ``items``
      ``"error"``    why the call failed, a string (only in a failure reply)
    """

    kind: str
    value: Union[str, int, float, bool, None] = None
    type: str | None = None
    ref: FieldRef | None = None
    converter: Converter | None = None
    items: tuple["BottleItem", ...] = ()
    span: Span | None = field(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class Fill:
    """The field ``ref`` of a request or response, filled by the module.

    ``source``:
      ``"element"``  element ``start`` of the Bottle (the reply, or the command's
                     arguments after its word), after the service's converters;
                     with ``stop`` (None: to the end) and ``slice``, the elements
                     ``[start, stop)`` into an array field. Into a bool field a
                     word is true when it is one of the service's ``true_words``
                     and false otherwise; a number is true when it is not 0.
      ``"text"``     the whole Bottle as text (``Bottle::toString``), into a string
      ``"literal"``  ``value``
      ``"error"``    why the call failed (only in a failure answer)
    """

    ref: FieldRef
    source: str
    start: int = 0
    stop: int | None = None
    slice: bool = False
    value: Union[str, int, float, bool, tuple, None] = None
    span: Span | None = field(default=None, compare=False, repr=False)


#: the words a reply element may say for true, when the config names none
#: (compared as they are: case counts, `OK` is not `ok`)
TRUE_WORDS = ("ok", "ack", "true", "yes", "done")
#: the seconds a call of a service may take, when the config gives no `timeout`
SERVICE_TIMEOUT = 1.0
#: the words a YARP RPC port served by a module answers by itself
RESERVED_COMMANDS = ("help",)


@dataclass(frozen=True)
class Service:
    """One command bridged between a YARP RPC port and a ROS 2 service.

    ``serves``:
      ``"ros2"``  the module serves the ROS 2 service ``service``; each request
                  becomes the Bottle ``bottle`` (from the request's fields), sent
                  to the YARP RPC port ``port``; the reply fills the response by
                  ``fills``, its elements declared by ``layout`` (None: not
                  declared, each element taken as it comes) and converted by
                  ``converters``.
      ``"yarp"``  the module serves the YARP RPC port ``port``; a command whose
                  first word is ``name`` fills the request by ``fills`` from its
                  arguments (the elements after the word, declared by ``layout``,
                  converted by ``converters``), calls the ROS 2 service
                  ``service``, and replies the Bottle ``bottle`` (from the
                  response's fields).

    A call that fails (no answer within ``timeout`` seconds, no server, a
    reply or a command that does not fit) answers ``failure_fills`` (serves
    ros2: the response's fields, the others at their defaults) or
    ``failure_bottle`` (serves yarp: the reply), which the checker makes
    from the config's ``failure.*`` / ``on_failure`` or, where the response
    has a mapped ``success``, from it: the caller can always tell a failure
    from a success.
    """

    name: str
    serves: str
    service: str
    srv_type: str
    port: str
    timeout: float = SERVICE_TIMEOUT
    layout: tuple[ElementGroup, ...] | None = None
    converters: tuple[Converter, ...] = ()
    bottle: tuple[BottleItem, ...] = ()
    fills: tuple[Fill, ...] = ()
    failure_fills: tuple[Fill, ...] = ()
    failure_bottle: tuple[BottleItem, ...] = ()
    true_words: tuple[str, ...] = TRUE_WORDS
    span: Span | None = field(default=None, compare=False, repr=False)
    type_span: Span | None = field(default=None, compare=False, repr=False)

    @property
    def width(self) -> int | None:
        """The elements the reply (serves ros2) or the arguments (serves yarp)
        are declared to hold; None: not declared."""
        return None if self.layout is None else sum(g.count for g in self.layout)

    @property
    def element_types(self) -> tuple[str, ...] | None:
        if self.layout is None:
            return None
        raw = [g.type for g in self.layout for _ in range(g.count)]
        for c in self.converters:
            stop = len(raw) if c.stop is None else c.stop
            if c.to_float:
                for k in range(c.start, min(stop, len(raw))):
                    raw[k] = "float64"
        return tuple(raw)


@dataclass(frozen=True)
class Commands:
    """A checked config of commands: its services, ready for any backend."""

    #: its kind of bridge (ybg.compiler.ir.BRIDGE_KINDS)
    kind: ClassVar[str] = "commands"

    module: str
    source: str
    services: tuple[Service, ...]
    distro: str | None = None
    ros: str = "ros2"

    @property
    def served_ports(self) -> tuple[str, ...]:
        """The YARP RPC ports the module serves, each once, in config order."""
        out: list[str] = []
        for s in self.services:
            if s.serves == "yarp" and s.port not in out:
                out.append(s.port)
        return tuple(out)

    @property
    def span(self) -> Span | None:
        """Where the config writes the bridge, for what is said of it as a
        whole (its module, its RPC port): its first command."""
        return self.services[0].span if self.services else None

    def on_port(self, port: str) -> tuple[Service, ...]:
        """The commands a served port answers, in config order."""
        return tuple(s for s in self.services if s.serves == "yarp" and s.port == port)


__all__ = [
    "FieldRef",
    "BottleItem",
    "Fill",
    "TRUE_WORDS",
    "SERVICE_TIMEOUT",
    "RESERVED_COMMANDS",
    "Service",
    "Commands",
]
