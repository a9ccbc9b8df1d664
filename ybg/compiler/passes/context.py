"""The one object the checker's passes share.

A :class:`Context` holds the document and the state the passes build from
it. Each pass reads fields set by the passes before it and sets its own; the
comment of each field names the pass that sets it. Nothing is set part-way
through another pass, and only ``converters`` changes what an earlier pass
set (it completes the muxes that ``inputs`` built).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import Edit, Fix, Sink
from ybg.compiler.msgtypes import MsgDef, TypeStore, load_store
from ybg.compiler.options import Options

#: a field of [message] as a path: ``header.frame_id`` is ``("header", "frame_id")``,
#: ``transforms[0].child_frame_id`` is ``("transforms", 0, "child_frame_id")``
FieldPath = tuple["str | int", ...]


@dataclass
class Stores:
    """The message definitions of each (ROS version, distro), loaded once."""

    options: Options
    cache: dict = field(default_factory=dict)

    def get(self, ros: str, distro: str | None) -> TypeStore:
        key = (ros, distro)
        if key not in self.cache:
            env = self.options.environ if self.options.environ is not None else os.environ
            self.cache[key] = load_store(ros, distro, self.options.msg_path, env)
        return self.cache[key]


@dataclass
class Context:
    """A named-form document under check, and what the passes found."""

    doc: ast.Document
    source: str  # the config's file name, recorded in the Program
    sink: Sink
    options: Options
    module_default: str  # the module name when [module] gives none
    # the document is the named form of a legacy config: its spans are of the
    # legacy lines, and a fix that edits the named form's text is not given
    legacy: bool = False
    stores: Stores = field(init=False)

    # sections: the sections by name, [mux <name>] by its name, entries by key
    sections: dict[str, ast.Section] = field(default_factory=dict)
    mux_sections: dict[str, ast.Section] = field(default_factory=dict)
    module_keys: dict[str, ast.Entry] = field(default_factory=dict)
    output_keys: dict[str, ast.Entry] = field(default_factory=dict)
    mux_keys: dict[str, dict[str, ast.Entry]] = field(default_factory=dict)
    # sections: the [service <name>] sections of a config of commands, and
    # the [action <name>] sections of a config of actions, by name
    service_sections: dict[str, ast.Section] = field(default_factory=dict)
    action_sections: dict[str, ast.Section] = field(default_factory=dict)

    # dialect: the module name, where the output lives (None: not said),
    # where each mux's topics live, the config's ROS version and its
    # message definitions
    module: str = ""
    output_via: str | None = None
    mux_via: dict[str, str] = field(default_factory=dict)
    ros: str = "ros1"
    store: TypeStore | None = None
    distro: str | None = None

    # inputs: the muxes that check, by name (converters adds their converters)
    muxes: dict[str, ir.Mux] = field(default_factory=dict)

    # output: the output, the definition of its message type (None when the
    # type is unknown or untyped) and whether the type is known
    output: ir.Output | None = None
    msgdef: MsgDef | None = None
    type_known: bool = False

    # message: the [message] entries by field path, and for each path prefix
    # the entries below it (None: no [message] to build)
    message_entries: dict[FieldPath, ast.Entry] | None = None
    below: dict[FieldPath, dict[FieldPath, ast.Entry]] = field(default_factory=dict)

    # typed or bottles: the message tree, and the muxes it uses
    message: ir.Struct | None = None
    used_muxes: set[str] = field(default_factory=set)
    # typed: the muxes of unknown width a nested message takes a part of
    # without a range (W511); cuts tells their inputs what is read
    silent_cuts: set[str] = field(default_factory=set)

    # program (services, for a config of commands): the checked program, None
    # when there are errors
    program: ir.Program | ir.Commands | ir.Actions | None = None

    def __post_init__(self) -> None:
        self.stores = Stores(self.options)

    def fix(self, *edits: Edit) -> Fix | None:
        """The fix that makes ``edits``; none for a legacy config, whose
        spans are of its own lines, not of the named form's."""
        return None if self.legacy else Fix(tuple(edits))
