"""Backends: lower a checked :class:`~ybg.compiler.ir.Program` to files.

Each backend is one package (``cpp/``, ``py/``, ``ros2/``) with its own
``templates/``. A backend only reads the IR and returns ``{relative path:
text}``; writing files (atomically, only when changed) is the CLI's job.
Lowering decisions are made in Python; templates only print.
"""

from __future__ import annotations

import dataclasses
import importlib
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from ybg.compiler.diagnostics import Diagnostic, Sink

if TYPE_CHECKING:
    import jinja2

    from ybg.compiler.ast import Document
    from ybg.compiler.diagnostics import Span
    from ybg.compiler.ir import Program, Struct
    from ybg.compiler.pipeline import Result


class LoweringError(ValueError):
    """A program that a backend cannot build; the message says why, and
    ``where`` which part of the program: ``("field", "header.stamp")``,
    ``("input", mux, name)``, ``("type",)`` (the output's message type), or
    None for the output or the program as a whole. ``ybgc check --backend`` and ``ybgc generate`` report it as E318
    at that part's line (:func:`lowering_diagnostic`), never as a traceback."""

    def __init__(self, message: str, where: tuple[str, ...] | None = None):
        super().__init__(message)
        self.where = where

    def at(self, *where: str) -> "LoweringError":
        """Say where the error is, unless a deeper part of the program said it already."""
        if self.where is None:
            self.where = where
        return self


@dataclass(frozen=True)
class Line:
    """One line of generated code, already made of escaped parts."""

    indent: int
    text: str


def nest_fields(leaves: list) -> list:
    """Leaves ``(dotted path, payload)`` of a nested message, in order, as its
    tree: each item ``(name, payload)`` for a leaf or ``(name, [items])`` for
    a sub-message (``position.x``, ``position.y`` -> ``("position", [("x", ..),
    ("y", ..)])``), as a Bottle of the ROS 1 layout nests them."""
    out: list = []
    for path, payload in leaves:
        head, _, rest = path.partition(".")
        if not rest:
            out.append((head, payload))
        elif out and out[-1][0] == head and isinstance(out[-1][1], list):
            out[-1][1].append((rest, payload))
        else:
            out.append((head, [(rest, payload)]))
    return [(name, nest_fields(sub) if isinstance(sub, list) else sub) for name, sub in out]


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
    """Template filter: a one-line fragment of code that lowering already built
    from escaped parts (anything else is a bug, not something to print)."""
    if not isinstance(text, str):
        raise TypeError(f"expected lowered code, got {type(text).__name__}")
    if "\n" in text or "\r" in text:
        raise ValueError("lowered code must be one line")
    return text


def indent_line_filter(line: Line) -> str:
    """Template filter: a :class:`Line` at its indentation (4 spaces a level)."""
    if not isinstance(line, Line):
        raise TypeError(f"expected a Line, got {type(line).__name__}")
    return "    " * line.indent + code_filter(line.text)


def template_environment(folders, filters: dict) -> "jinja2.Environment":
    """The Jinja environment of a backend: templates only print (autoescape
    off, undefined names are errors, whitespace as written), and every value
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


@dataclass(frozen=True)
class RenderOptions:
    """Options every backend accepts. ``package``: also emit the packaging
    around the module (ament_python package for ``ros2``). ``single_file``:
    the runtime inlined into the module, one file with no runtime beside it."""

    package: bool = False
    single_file: bool = False
    extra: dict = field(default_factory=dict)


class Backend:
    """Base class of a backend. Subclasses set ``name`` and implement
    :meth:`render`; what they build and their description are the
    registry's (:data:`REGISTRY`), set on the subclass from there."""

    name: str = ""
    description: str = ""
    #: the IR ``output.kind`` values and input kinds this backend can build
    output_kinds: frozenset[str] = frozenset()
    input_kinds: frozenset[str] = frozenset()

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        info = REGISTRY[cls.name]
        cls.description = info.description
        cls.output_kinds = info.output_kinds
        cls.input_kinds = info.input_kinds

    def render(self, program: "Program", options: RenderOptions = RenderOptions()) -> dict[str, str]:
        raise NotImplementedError

    def lower(self, program: "Program") -> None:
        """Make every decision :meth:`render` makes, without printing: raises
        the :class:`LoweringError` that :meth:`render` would. ``ybgc check
        --backend`` runs it, so that what checks also generates. By default
        it renders; a backend overrides it with its lowering alone."""
        self.render(program)
        self.render(program, RenderOptions(package=True))


@dataclass(frozen=True)
class BackendInfo:
    """What the registry knows of a backend without importing it: where it
    is, what it makes (the command's help) and which IR output and input
    kinds it builds (:func:`check`)."""

    target: str  # "module:Class"
    description: str
    output_kinds: frozenset[str]
    input_kinds: frozenset[str]


_YARP = frozenset({"yarp", "ros1"})

#: name -> backend, imported on first use so ``ybgc check`` stays quick
REGISTRY: dict[str, BackendInfo] = {
    "cpp": BackendInfo("ybg.backends.cpp:CppBackend",
                       "a C++17 YARP module and its CMakeLists.txt, on ybgc's C++ runtime library "
                       "(ROS 2 outputs and inputs through rcl)", _YARP | {"ros2"}, _YARP | {"ros2"}),
    "py": BackendInfo("ybg.backends.py:PyBackend",
                      "a Python module on YARP's Python bindings and ybgc's Python runtime library", _YARP, _YARP),
    "ros2": BackendInfo("ybg.backends.ros2:Ros2Backend",
                        "an rclpy node between YARP ports and ROS 2 topics (optionally an ament_python package)",
                        frozenset({"ros2", "yarp"}), frozenset({"yarp", "ros2"})),
}


def get_backend(name: str) -> Backend:
    """The backend registered as ``name`` (KeyError if there is none)."""
    target = REGISTRY[name].target
    module_name, cls_name = target.split(":")
    module = importlib.import_module(module_name)
    return getattr(module, cls_name)()


def backend_names() -> list[str]:
    return sorted(REGISTRY)


#: how E318 names an output of each IR kind
_OUTPUT_KINDS = {"ros2": "a ROS 2 topic", "ros1": "a ROS 1 topic", "yarp": "a YARP port"}


def _writers(kind: str) -> list[str]:
    return [n for n in backend_names() if kind in REGISTRY[n].output_kinds]


def _readers(kind: str) -> list[str]:
    return [n for n in backend_names() if kind in REGISTRY[n].input_kinds]


def _options(names: list[str]) -> str:
    return " or ".join(f"`--backend {n}`" for n in names)


def check(program: "Program", backend: str, sink: Sink, legacy: bool = False,
          doc: "Document | None" = None) -> None:
    """Can ``backend`` build ``program``? E318 when it cannot, E321 when a
    ROS 2 output has no message definition to build from; ``legacy``: the
    config is in the legacy form, and the hints say how to convert it;
    ``doc``: the config in the named form, for the positions."""
    from ybg.compiler.pipeline import output_span

    info = REGISTRY[backend]
    span = output_span(doc) if doc is not None else None
    if program.output.kind not in info.output_kinds:
        if program.output.kind == "ros1" and "ros2" in info.output_kinds:
            hint = _legacy_to_ros2_hint(program, sink.file) if legacy else \
                "set `via = ros2` in [output] (and drop `header.seq`, which ROS 2 has not)"
            sink.error("E318", "this config publishes to ROS 1 through YARP (`to_ros = true` / `via = ros1`); "
                       f"the {backend} backend publishes to ROS 2", span, hint)
        else:
            sink.error("E318", f"the {backend} backend cannot write {_OUTPUT_KINDS[program.output.kind]}", span,
                       f"use {_options(_writers('ros2'))} for ROS 2 outputs, "
                       f"{_options(_writers('ros1'))} for YARP and ROS 1")
        return
    if program.output.kind == "ros2" and all(i.kind == "ros2" for m in program.muxes for i in m.inputs):
        sink.error("E318", "nothing to bridge: this config reads ROS 2 topics and publishes a ROS 2 topic, "
                   "with no YARP side", span,
                   "read YARP ports (`ports = ...`) or write a YARP port (`port = ...`)")
        return
    for m in program.muxes:
        for i in m.inputs:
            if i.kind not in info.input_kinds:
                if i.kind == "ros1" and "ros2" in info.input_kinds:
                    hint = (_legacy_inputs_to_ros2_hint(program, i.name, sink.file) if legacy else
                            "set `via = ros2` in the mux, with each topic's type: `/topic (pkg/Name)`")
                else:
                    hint = (f"ROS 2 topics are read by {_options(_readers('ros2'))}; "
                            f"ROS 1 topics by {' and '.join(_readers('ros1'))}")
                sink.error("E318", f"the {backend} backend cannot read {i.kind} input `{i.name}` (mux `{m.name}`)",
                           input_span(doc, m.name, i.name) if doc is not None else None, hint)
                return
    if program.output.kind == "ros2" and not _typed(program.message):
        name = program.output.msg_type or program.message.msg_type or ""
        hint = "give the folder of its .msg files with `--msg-path DIR` (DIR/<pkg>/msg/<Name>.msg) or YBG_MSG_PATH"
        if "/" not in name:
            hint = f"write it with its package, `pkg/{name}`, and {hint}"
        sink.error("E321", f"the {backend} backend builds a ROS 2 message field by field from its definition, "
                   f"and the definition of `{name}` was not found", type_span(doc) if doc is not None else None,
                   hint)


def _converted_name(path: str) -> str:
    from ybg.compiler.legacy import converted_name

    return converted_name(path)


def _legacy_to_ros2_hint(program: "Program", path: str) -> str:
    """E318's hint for a config in the legacy form that publishes to ROS 1:
    the command that converts it for ROS 2, or, when the conversion needs
    what the file does not say (the message type, or its definition), that
    first."""
    command = f"ybgc fmt --to named --ros2 FILE -o {_converted_name(path)}"
    if program.output.msg_type is None:
        return ("ROS 2 needs the message type, which this file neither gives nor lets ybgc infer: add "
                f"`ros_msg_name = pkg/Name` to [general]; then {command} converts it for ROS 2")
    if not _typed(program.message):
        return (f"a ROS 2 message is built field by field from its definition, and that of "
                f"`{program.output.msg_type}` was not found: give the folder of its .msg files to the "
                f"conversion, {command.replace(' FILE', ' --msg-path DIR FILE')}")
    return f"convert it for ROS 2 in one command: `{command}`"


def _legacy_inputs_to_ros2_hint(program: "Program", topic: str, path: str) -> str:
    """E318's hint for a config in the legacy form that reads ROS 1 topics,
    for a backend that reads ROS 2 ones: the one command that converts it,
    when the file declares the type of every topic it reads; else the
    conversion, then the types to declare in the file it writes."""
    new = _converted_name(path)
    if all(i.ros_type is not None for m in program.muxes for i in m.inputs if i.kind == "ros1"):
        return f"convert it for ROS 2 in one command: `ybgc fmt --to named --ros2 FILE -o {new}`"
    return (f"a ROS 2 topic needs its message type, which the legacy form does not give: convert with "
            f"`ybgc fmt --to named FILE -o {new}`, then in {new} declare each topic's type, "
            f"`{topic} (pkg/Name)`, and set `via = ros2`")


def _typed(struct: "Struct") -> bool:
    """Does every field of ``struct``, nested ones too, have its ROS type?"""
    from ybg.compiler.ir import Struct

    return all(f.type is not None and (not isinstance(f.source, Struct) or _typed(f.source))
               for f in struct.fields)


def type_span(doc: "Document") -> "Span | None":
    """Where the output's message type is written, else the output's line."""
    from ybg.compiler.pipeline import output_span

    sec = doc.section("output")
    e = sec.get("type") if sec is not None else None
    if e is not None:
        return e.items[0].span if e.items else e.span
    return output_span(doc)


def input_span(doc: "Document", mux: str, name: str) -> "Span | None":
    """Where input ``name`` of ``mux`` is written, else its mux's line."""
    from ybg.compiler import ast

    sec = doc.section("mux", mux)
    if sec is None:
        return None
    e = sec.get("topics") or sec.get("ports")
    if e is None:
        return sec.span
    for item in e.items:
        head = item.func if isinstance(item, ast.Call) else item
        if isinstance(head, ast.Word) and head.text == name or isinstance(head, ast.Str) and head.value == name:
            return item.span
    return e.span


def field_span(doc: "Document", path: str) -> "Span | None":
    """Where the message field ``path`` (dotted) is set: its entry in
    [message], or the entry of the nearest enclosing field, or the first
    entry of a field inside it; else the [message] line."""
    sec = doc.section("message")
    if sec is None:
        return None
    entries = {e.key: e for e in sec.entries}
    parts = path.split(".")
    for k in range(len(parts), 0, -1):
        e = entries.get(".".join(parts[:k]))
        if e is not None:
            return e.span
    inside = [e for key, e in entries.items() if key.startswith((path + ".", path + "["))]
    return inside[0].span if inside else sec.span


def lowering_span(doc: "Document", error: LoweringError) -> "Span | None":
    """The best position for ``error`` in the config ``doc``."""
    from ybg.compiler.pipeline import output_span

    where = error.where or ()
    if where[:1] == ("field",):
        return field_span(doc, where[1])
    if where[:1] == ("input",):
        return input_span(doc, where[1], where[2])
    if where[:1] == ("type",):
        return type_span(doc)
    return output_span(doc)


def lowering_diagnostic(error: LoweringError, backend: str, result: "Result") -> Diagnostic:
    """``error``, raised by ``backend`` for ``result``'s program, as the
    diagnostic that ``ybgc check --backend`` and ``ybgc generate`` report."""
    sink = Sink(result.path)
    span = lowering_span(result.named, error) if result.named is not None else None
    program = result.program
    others = [n for n in backend_names() if n != backend and program is not None and _builds(n, program)]
    hint = f"a limit of the {backend} backend: change this part of the config"
    if others:
        hint += f", or use {_options(others)}"
    sink.error("E318", f"the {backend} backend cannot build this: {error}", span, hint)
    return sink.items[0]


def _lowering_error(backend: str, program: "Program") -> LoweringError | None:
    """What ``backend``'s lowering refuses in ``program`` (None: nothing).
    An object that is no :class:`Backend` has no lowering apart from its
    rendering, which generation runs anyway."""
    impl = get_backend(backend)
    if not isinstance(impl, Backend):
        return None
    try:
        impl.lower(program)
    except LoweringError as e:
        return e
    return None


def _builds(backend: str, program: "Program") -> bool:
    """Does ``backend`` take ``program``, by :func:`check` and its lowering?"""
    sink = Sink()
    check(program, backend, sink)
    return not sink.has_errors and _lowering_error(backend, program) is None


def check_result(result: "Result", backend: str) -> "Result":
    """``result`` of the front end as ``backend`` sees it: with the
    diagnostics of :func:`check`, and of the backend's lowering when that
    refuses the program (:meth:`Backend.lower`), and without a program it
    cannot build. A result without a program is returned as it is."""
    if result.program is None:
        return result
    sink = Sink(result.path)
    check(result.program, backend, sink, result.form == "legacy", result.named)
    if not sink.has_errors:
        error = _lowering_error(backend, result.program)
        if error is not None:
            sink.items.append(lowering_diagnostic(error, backend, result))
    if not sink.items:
        return result
    return dataclasses.replace(result, program=None if sink.has_errors else result.program,
                               diagnostics=sorted(result.diagnostics + sink.items, key=Diagnostic.sort_key))
