"""The front end of one config file, stage by stage::

    text --parser--> Document --legacy (legacy form only)--> named Document
         --check--> Program (IR)

:func:`compile_path` runs it and returns a :class:`Result` holding whatever
was reached and every diagnostic; it never raises on bad input. What comes
next is the backends' (``ybg.backends``): whether one can build the program
(``check_result``), and the files.
"""

from __future__ import annotations

import contextlib
import gc
import os
from dataclasses import dataclass, field
from pathlib import Path

from ybg.compiler import ast, ir
from ybg.compiler.check import check_named
from ybg.compiler.diagnostics import Diagnostic, Severity, Sink, Span
from ybg.compiler.legacy import converted_name, is_legacy, is_named, to_named
from ybg.compiler.msgtypes import DISTROS, load_store
from ybg.compiler.names import sanitize_identifier
from ybg.compiler.options import Options
from ybg.compiler.parser import parse_text


@dataclass
class Result:
    """What the pipeline reached for one file."""

    path: str
    text: str | None = None
    document: ast.Document | None = None  # as written
    named: ast.Document | None = None  # named form (converted if legacy)
    form: str | None = None  # "legacy" | "named"
    program: ir.Program | None = None
    diagnostics: list[Diagnostic] = field(default_factory=list)

    @property
    def errors(self) -> list[Diagnostic]:
        return [d for d in self.diagnostics if d.severity is Severity.ERROR]

    @property
    def warnings(self) -> list[Diagnostic]:
        return [d for d in self.diagnostics if d.severity is Severity.WARNING]

    @property
    def ok(self) -> bool:
        return self.program is not None and not self.errors


def module_name_for(path: str) -> str:
    return sanitize_identifier(Path(path).stem) if path and not path.startswith("<") else "bridge"


def read_source(path: str, sink: Sink) -> str | None:
    try:
        data = Path(path).read_bytes()
    except OSError as e:
        sink.error("E001", f"cannot read {path}: {e.strerror or e}", None)
        return None
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data[: e.start].count(b"\n") + 1
        col = e.start - (data.rfind(b"\n", 0, e.start) + 1) + 1
        sink.error("E002", f"byte 0x{data[e.start]:02x} is not UTF-8", Span(line, col, line, col + 1),
                   "save the file as UTF-8")
        return None


def to_named_document(doc: ast.Document, path: str, sink: Sink, options: Options,
                      ros2: bool = False) -> tuple[ast.Document, list[str]]:
    """A legacy document in the named form (``ros2``: retargeted to ROS 2)."""
    ros1_distro = options.distro if options.distro and DISTROS.get(options.distro) == "ros1" else None
    env = options.environ if options.environ is not None else os.environ
    store = load_store("ros1", ros1_distro, options.msg_path, env)
    target = None
    if ros2:
        ros2_distro = options.distro if options.distro and DISTROS.get(options.distro) == "ros2" else None
        target = load_store("ros2", ros2_distro, options.msg_path, env)
    return to_named(doc, sink, store, module_name_for(path), target)


@contextlib.contextmanager
def _collector_paused():
    """The cyclic garbage collector off while a config is compiled: the
    stages make many small objects and no garbage cycles worth collecting,
    and its scans of a growing heap made large configs superlinear (a 1,000-mux
    config took twice as long). Its previous state is restored."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def compile_text(text: str, path: str = "<config>", options: Options | None = None) -> Result:
    """Run the front end over ``text`` (``path`` names it in diagnostics)."""
    with _collector_paused():
        return _compile_text(text, path, options)


def _compile_text(text: str, path: str, options: Options | None) -> Result:
    options = options or Options()
    sink = Sink(path)
    result = Result(path, text)
    doc = parse_text(text, sink)
    result.document = doc
    legacy = is_legacy(doc)
    if legacy and is_named(doc):
        first = next(s for s in doc.sections if s.name in ("output", "module") or s.label)
        sink.error("E207", "this file mixes the legacy form ([general], [muxN], num_fields) and the "
                   "named form ([output], [mux name])", first.span,
                   f"keep one form: `ybgc fmt --to named FILE -o {converted_name(path)}` converts it, "
                   "keeping the named keys")
    if legacy:
        result.form = "legacy"
        named, _ = to_named_document(doc, path, sink, options)
    else:
        result.form = "named"
        named = doc
    result.named = named
    if not (legacy and sink.has_errors and not named.sections):
        result.program = check_named(named, Path(path).name, sink, options, module_name_for(path))
    if result.program is not None and options.yarp is not None:
        check_yarp_target(result.program, options.yarp, named, sink)
        if sink.has_errors:
            result.program = None
    result.diagnostics = sink.sorted()
    return result


def yarp_version(text: str) -> tuple[int, ...] | None:
    """``"3.12"`` -> (3, 12); None for anything that is not a version."""
    parts = text.strip().split(".")
    if not 1 <= len(parts) <= 3 or not all(p.isdigit() for p in parts):
        return None
    return tuple(int(p) for p in parts)


def check_yarp_target(program: ir.Program, yarp: str, doc: ast.Document, sink: Sink) -> None:
    """Can YARP ``yarp`` carry what ``program`` needs? YARP's own ROS 1
    support (tcpros, xmlrpc, ``yarpserver --ros``) is built in up to 3.9,
    a separate plugin package (yarp-ros) in 3.10 to 3.12, gone in 4.0."""
    version = yarp_version(yarp)
    if version is None or version < (3, 10):
        return
    uses = []
    if program.output.kind == "ros1":
        uses.append(("its output", program.output.span))
    for m in program.muxes:
        if any(i.kind == "ros1" for i in m.inputs):
            sec = doc.section("mux", m.name)
            entry = sec and (sec.get("via") or sec.get("topics"))
            uses.append((f"mux `{m.name}`", entry.span if entry else sec.span if sec else None))
    for what, span in uses:
        if version >= (4,):
            sink.error("E320", f"{what} goes through YARP's ROS 1 support, which YARP {yarp} no longer has "
                       "(removed in YARP 4.0)", span,
                       "use ROS 2: `via = ros2`, and `ybgc CONFIG --backend ros2`; a legacy config converts "
                       f"with `ybgc fmt --to named --ros2 FILE -o {converted_name(sink.file)}`")
        else:
            sink.warning("W507", f"{what} goes through YARP's ROS 1 support, which YARP {yarp} has only with "
                         "its separate yarp-ros plugins (the tcpros and xmlrpc carriers)", span,
                         "install yarp-ros beside YARP, or use ROS 2 (`via = ros2`); without the plugins the "
                         "module stops at start and says so")


def compile_path(path: str | os.PathLike, options: Options | None = None) -> Result:
    """Read and compile one config file."""
    path = os.fspath(path)
    sink = Sink(path)
    text = read_source(path, sink)
    if text is None:
        return Result(path, diagnostics=sink.sorted())
    return compile_text(text, path, options)
