"""The ``ybgc`` command.

    ybgc CONFIG --backend NAME [-o DIR]        generate a module
    ybgc check CONFIG...                        check (pre-commit)
    ybgc fmt CONFIG... [--check] [--to named]   canonical form / conversion
    ybgc ir CONFIG                              the checked program as JSON
    ybgc graph CONFIG [--format F] [-o FILE]    the dataflow as SVG, DOT or Mermaid
    ybgc probe CONFIG... [--wait S]             against the running YARP network and ROS 2 graph

With no CONFIG named, a command takes the folder's config: ``ybgc.ini``,
else the one ybgc config among the folder's ``.ini`` files (those that are
not ybgc configs are skipped, as ``--skip-foreign`` does); ``ybgc check``
with none named checks every config of the folder. A folder named as a
CONFIG is a robot: its configs, as if each were named (``ybgc check
examples/icub_robot``, ``ybgc compose examples/icub_robot extra.ini``); a
command of one config takes the folder's one config.

The backends, their names and what each makes are those of the registry
(``ybg.backends.REGISTRY``); ``ybgc generate --help`` lists them.

Exit status: 0 clean (or warnings only), 1 problems, 2 usage or I/O error.
"""

from __future__ import annotations

import argparse
import difflib
import re
import sys
from pathlib import Path

from ybg import __version__
from ybg.backends import REGISTRY, backend_names
from ybg.graph import FORMATS, SUFFIXES

COMMANDS = ("check", "fmt", "ir", "generate", "compose", "graph", "probe", "init")
#: the config a command takes when none is named
FOLDER_CONFIG = "ybgc.ini"
EXIT_OK, EXIT_PROBLEMS, EXIT_USAGE = 0, 1, 2


class _Parser(argparse.ArgumentParser):
    def error(self, message):  # usage errors: exit 2 with a hint, no traceback
        self.print_usage(sys.stderr)
        sys.stderr.write(f"{self.prog}: error: {message}\n")
        if "--backend" in message or "backend" in message:
            sys.stderr.write(f"hint: backends are {', '.join(backend_names())}\n")
        sys.exit(EXIT_USAGE)


def _common(p: argparse.ArgumentParser) -> None:
    p.add_argument("--distro", help="ROS distro of the message definitions (noetic, humble, jazzy, kilted)")
    p.add_argument("--msg-path", action="append", default=[], metavar="DIR",
                   help="folder of user .msg files (<DIR>/<pkg>/msg/<Name>.msg); repeatable")
    p.add_argument("--yarp", metavar="VERSION",
                   help="the YARP version the module is for, e.g. 3.12 or 4.0 (default: any): "
                        "ROS 1 through YARP is an error for YARP 4, a warning for 3.10 to 3.12")


_FOLDER_HELP = f"default: the folder's config ({FOLDER_CONFIG}, or the one config there)"
_ROBOT_HELP = "a config, or a folder of them (a robot: every config there); default: every config of the folder"


def _backends_epilog() -> str:
    names = backend_names()
    width = max(map(len, names))
    return "backends:\n" + "".join(f"  {n:<{width}}  {REGISTRY[n].description}\n" for n in names)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="ybgc", description="YARP bottle generator compiler: a config file to a YARP/ROS bridge module.")
    p.add_argument("--version", action="version", version=f"ybgc {__version__}")
    sub = p.add_subparsers(dest="command", parser_class=_Parser)

    c = sub.add_parser("check", help="check configs and report problems")
    c.add_argument("files", nargs="*", metavar="CONFIG", help=_ROBOT_HELP)
    c.add_argument("--strict", action="store_true", help="warnings fail too")
    c.add_argument("--format", choices=("text", "json", "github"), default="text")
    c.add_argument("--backend", choices=backend_names(), help="also check that this backend can build it")
    c.add_argument("-v", "--verbose", action="store_true", help="also print notes")
    c.add_argument("--skip-foreign", action="store_true",
                   help="skip files that are not ybgc configs (other INI files, e.g. YARP robot configs)")
    _common(c)

    f = sub.add_parser("fmt", help="rewrite configs in canonical form")
    f.add_argument("files", nargs="*", metavar="CONFIG", help=_FOLDER_HELP)
    f.add_argument("--check", action="store_true", help="only report files that would change (exit 1)")
    f.add_argument("--diff", action="store_true", help="print the changes instead of writing")
    f.add_argument("--to", choices=("named",), help="convert a legacy config to the named form")
    f.add_argument("--ros2", action="store_true", help="with --to named: publish to ROS 2 (drops header.seq)")
    f.add_argument("-o", "--output", metavar="FILE",
                   help="write here instead of in place (one input file); an existing FILE is replaced only "
                        "with --force, and never when it is the input (that is in place)")
    f.add_argument("--force", action="store_true", help="with -o: replace FILE even though ybgc did not generate it")
    f.add_argument("--stdout", action="store_true", help="print instead of writing")
    f.add_argument("--skip-foreign", action="store_true", help="skip files that are not ybgc configs")
    _common(f)

    i = sub.add_parser("ir", help="print the checked program (IR) as JSON")
    i.add_argument("file", nargs="?", metavar="CONFIG", help=_FOLDER_HELP)
    i.add_argument("--backend", choices=backend_names(), help="also check that this backend can build it")
    _common(i)

    g = sub.add_parser("generate", help="generate a module (also: ybgc CONFIG --backend B)",
                       formatter_class=argparse.RawDescriptionHelpFormatter, epilog=_backends_epilog())
    g.add_argument("file", nargs="?", metavar="CONFIG", help=_FOLDER_HELP)
    g.add_argument("--backend", "-b", required=True, choices=backend_names(), help="what to make (backends below)")
    g.add_argument("-o", "--output", metavar="DIR", help="output folder (default: ./<module name>)")
    g.add_argument("--force", action="store_true",
                   help="replace files that ybgc did not generate (never the config itself)")
    g.add_argument("--package", action="store_true",
                   help="ros2: also an ament_python package around the node; cpp: an ament_cmake package "
                        "around the module (package.xml, a launch file; built by colcon)")
    g.add_argument("--single-file", action="store_true",
                   help="write the runtime inside the module: one file, nothing beside it; by default the "
                        "runtime files are written beside the module")
    _common(g)

    k = sub.add_parser("compose", help="compose several configs into one module: one process, one ROS 2 "
                                       "context, one node per bridge (docs/compose.md)",
                       formatter_class=argparse.RawDescriptionHelpFormatter, epilog=_backends_epilog())
    k.add_argument("files", nargs="*", metavar="CONFIG", help=_ROBOT_HELP)
    k.add_argument("--backend", "-b", required=True, choices=backend_names(), help="what to make (backends below)")
    k.add_argument("--name", help="the composed module's name: its executable, its RPC port /<name>/rpc:i "
                                  "(default: the first folder named, else the folder of the first config)")
    k.add_argument("-o", "--output", metavar="DIR", help="output folder (default: ./<name>)")
    k.add_argument("--force", action="store_true",
                   help="replace files that ybgc did not generate (never a config)")
    k.add_argument("--package", action="store_true",
                   help="one ament package with one executable and a launch file for every bridge")
    _common(k)

    d = sub.add_parser("graph", help="draw the dataflow: ports -> muxes -> converters -> fields -> output")
    d.add_argument("files", nargs="*", metavar="CONFIG",
                   help="a config, or several, or a folder of them (a robot: every bridge, side by side); "
                        f"default: the folder's config ({FOLDER_CONFIG}), else every config there")
    d.add_argument("--format", choices=tuple(FORMATS),
                   help="default: from the -o file's ending (.svg, .dot or .gv, .mmd or .mermaid), else svg")
    d.add_argument("-o", "--output", metavar="FILE",
                   help="write here ('-': print); default: svg to ./<module>.svg, dot and mermaid printed")
    d.add_argument("--force", action="store_true",
                   help="replace the file even though ybgc did not generate it (never the config itself)")
    _common(d)

    r = sub.add_parser("probe", help="before a module starts: its config against the running YARP network and "
                                     "ROS 2 graph (docs/probe.md)")
    r.add_argument("files", nargs="*", metavar="CONFIG", help=_ROBOT_HELP)
    r.add_argument("--wait", type=float, default=3.0, metavar="S",
                   help="seconds for ROS 2 discovery and for a Bottle from each input port (default 3)")
    r.add_argument("--prefix", "--name", dest="prefix", metavar="PREFIX",
                   help="the module's port prefix, as it is started (default /<module>)")
    r.add_argument("-p", "--param", action="append", default=[], metavar="NAME:=VALUE",
                   help="a parameter the module is started with; qos_overrides./TOPIC.publisher.POLICY:=VALUE "
                        "(.subscription. for a topic it reads) changes the QoS probed; repeatable")
    r.add_argument("--strict", action="store_true", help="warnings fail too")
    r.add_argument("--format", choices=("text", "json", "github"), default="text")
    r.add_argument("-v", "--verbose", action="store_true", help="also print notes")
    _common(r)

    n = sub.add_parser("init", help="from a running robot: a config for each bridge a ROS user would want, "
                                    "checked, in a new folder (docs/init.md)")
    n.add_argument("--robot", default="/", metavar="PREFIX",
                   help="the robot's port prefix, e.g. /icub (default: every port the name server lists)")
    n.add_argument("-o", "--output", metavar="DIR", help="the folder to write (default: ./<robot>); "
                                                         "no file in it is ever written over")
    n.add_argument("--seconds", type=float, default=2.0, metavar="S",
                   help="how long each port is read, to see its layout and rate (default 2)")
    n.add_argument("--dry-run", action="store_true", help="print what was found and would be written; write nothing")
    n.add_argument("--format", choices=("text", "json"), default="text",
                   help="json: what was found and made, for scripts (on the standard output)")
    return p


def _options(args):
    from ybg.compiler.options import Options
    from ybg.compiler.msgtypes import DISTROS

    if args.distro is not None and args.distro not in DISTROS:
        from ybg.compiler.diagnostics import did_you_mean
        hint = did_you_mean(args.distro, DISTROS)
        sys.stderr.write(f"ybgc: unknown distro {args.distro!r} (known: {', '.join(DISTROS)})"
                         f"{'; ' + hint if hint else ''}\n")
        sys.exit(EXIT_USAGE)
    for d in args.msg_path:
        if not Path(d).is_dir():
            sys.stderr.write(f"ybgc: --msg-path {d}: not a folder\n")
            sys.exit(EXIT_USAGE)
    yarp = getattr(args, "yarp", None)
    if yarp is not None:
        from ybg.compiler.pipeline import yarp_version
        if yarp_version(yarp) is None:
            sys.stderr.write(f"ybgc: --yarp {yarp}: not a YARP version (e.g. 3.12 or 4.0.0)\n")
            sys.exit(EXIT_USAGE)
    return Options(distro=args.distro, msg_path=tuple(args.msg_path), yarp=yarp)


_CONFIG_SECTIONS = re.compile(r"(?m)^[ \t]*\[[ \t]*(general|output)[ \t]*\]")
_MESSAGE_SECTION = re.compile(r"(?m)^[ \t]*\[[ \t]*message[ \t]*\]")
_SERVICE_SECTION = re.compile(r"(?m)^[ \t]*\[[ \t]*(?:service|action)[ \t]+[^\]\s]+[ \t]*\]")
_IMAGE_KEY = re.compile(r"(?m)^[ \t]*image[ \t]*=")


def is_config_file(path: str) -> bool:
    """Does ``path`` look like a ybgc config (a [message] section and an
    [output] or [general] one; an [output] of camera images, `image =`; or
    [service <name>] or [action <name>] sections)? Unreadable files count as configs, so that
    their error is reported."""
    try:
        text = Path(path).read_text(encoding="utf-8", errors="replace")
    except OSError:
        return True
    if _SERVICE_SECTION.search(text):
        return True
    return bool(_CONFIG_SECTIONS.search(text) and (_MESSAGE_SECTION.search(text) or _IMAGE_KEY.search(text)))


def folder_configs(folder: Path = Path(".")) -> list[str]:
    """The ybgc configs of ``folder``: its ``.ini`` files that are ybgc
    configs (:func:`is_config_file`), and ``ybgc.ini`` whatever it holds."""
    try:
        found = sorted(p for p in folder.iterdir() if p.suffix == ".ini" and p.is_file()
                       and (p.name == FOLDER_CONFIG or is_config_file(str(p))))
    except OSError as e:
        _usage_error(f"cannot read the folder {folder.resolve()}: {e.strerror or e}", "name the config")
    return [str(p) for p in found]


def expand_folders(files, command: str) -> list[str]:
    """``files`` with each folder among them replaced by its configs
    (:func:`folder_configs`: a robot's folder), in the order named, each
    config once; a folder without a config is a usage error."""
    out: list[str] = []
    for f in files:
        if Path(f).is_dir():
            found = folder_configs(Path(f))
            if not found:
                _usage_error(f"no ybgc config in the folder {f} (no .ini file there has a [message] section and "
                             "an [output] or [general] one, nor [service] or [action] sections)",
                             f"name the configs: ybgc {command} {f.rstrip('/')}/config.ini")
        else:
            found = [f]
        out += [c for c in found if c not in out]
    return out


def robot_name(files) -> str:
    """The name a robot of ``files`` goes by: the first folder named, else
    the folder of the first config."""
    first = Path(files[0])
    return (first if first.is_dir() else first.parent).resolve().name


def _usage_error(message: str, hint: str) -> None:
    sys.stderr.write(f"ybgc: error: {message}\n    hint: {hint}\n")
    sys.exit(EXIT_USAGE)


def _write_error(e) -> int:
    """A refused or failed write (:class:`ybg.writer.WriteError`): nothing
    was written; exit 2."""
    sys.stderr.write(f"ybgc: error: {e}\n" + (f"    hint: {e.hint}\n" if e.hint else ""))
    return EXIT_USAGE


def folder_config(command: str, named: str | None = None) -> str:
    """The config ``command`` takes: ``named``, or when that is a folder or
    None (the current folder), the folder's ``ybgc.ini``, else its one
    config; none or several is a usage error."""
    if named is not None and not Path(named).is_dir():
        return named
    folder = Path(named or ".")
    if (folder / FOLDER_CONFIG).is_file():
        return str(folder / FOLDER_CONFIG)
    configs = folder_configs(folder)
    if len(configs) == 1:
        return configs[0]
    said = f"the folder {named}" if named else "no config named, and"
    where = named if named else Path.cwd()
    if not configs:
        _usage_error(f"{said} no ybgc config in {where} (no {FOLDER_CONFIG}, and no .ini file "
                     "there has a [message] section and an [output] or [general] one, nor [service] or [action] sections)"
                     if not named else
                     f"{said} has no ybgc config (no {FOLDER_CONFIG}, and no .ini file there has a [message] "
                     "section and an [output] or [general] one, nor [service] or [action] sections)",
                     f"name the config: ybgc {command} path/to/config.ini")
    several = f"{said} {len(configs)} ybgc configs in {where}" if not named else \
        f"{said} has {len(configs)} ybgc configs"
    robot = f"; for all of them as one module: ybgc compose {named or '.'} {command}" \
        if command.startswith("--backend") else ""
    usage = f"ybgc {configs[0]} {command}" if command.startswith("--backend") else f"ybgc {command} {configs[0]}"
    _usage_error(f"{several}: {', '.join(configs)}",
                 f"name the one to use ({usage}), or call it {FOLDER_CONFIG}{robot}")


def _select(args) -> list[str]:
    if not args.files:  # check: every config of the folder; fmt: the folder's one
        configs = folder_configs() if args.command == "check" else []
        return configs or [folder_config(args.command)]
    files = expand_folders(args.files, args.command)
    if not getattr(args, "skip_foreign", False):
        return files
    named = set(args.files)  # a folder's configs are configs already
    return [f for f in files if f not in named or is_config_file(f)]


def _io_error(result) -> bool:
    return any(d.code in ("E001", "E002") for d in result.diagnostics)


def _print(results, fmt: str, verbose: bool = False) -> None:
    from ybg.report import report

    diags = [d for r in results for d in r.diagnostics]
    sources = {r.path: r.text for r in results if r.text is not None}
    report(fmt, diags, sources, sys.stdout if fmt != "text" else sys.stderr, notes=verbose)


def _compile(path: str, args, options):
    """The front end, then, with ``--backend``, that backend's check."""
    from ybg.compiler.pipeline import compile_path

    result = compile_path(path, options)
    if getattr(args, "backend", None) is None:
        return result
    from ybg.backends import check_result
    return check_result(result, args.backend)


def cmd_check(args) -> int:
    options = _options(args)
    results = [_compile(f, args, options) for f in _select(args)]
    if len(results) > 1:
        # what no config can be wrong about alone: topics, ports, names, services across them
        from ybg.compiler.across import check_across

        by_file: dict[str, list] = {}
        for d in check_across(results):
            by_file.setdefault(d.file, []).append(d)
        for r in results:
            if r.path in by_file:
                r.diagnostics = sorted(r.diagnostics + by_file[r.path], key=lambda d: d.sort_key())
    _print(results, args.format, args.verbose)
    if any(_io_error(r) for r in results):
        return EXIT_USAGE
    if any(r.errors for r in results) or (args.strict and any(r.warnings for r in results)):
        return EXIT_PROBLEMS
    return EXIT_OK


def _formatted(path: str, args, options) -> tuple[str | None, object]:
    from ybg.compiler.diagnostics import Sink
    from ybg.compiler.fmt import format_document, strip_positions
    from ybg.compiler.legacy import is_legacy
    from ybg.compiler.pipeline import Result, compile_text, read_source, to_named_document

    sink = Sink(path)
    text = read_source(path, sink)
    if text is None:
        return None, Result(path, diagnostics=sink.sorted())
    result = compile_text(text, path, options)
    syntax = [d for d in result.errors if d.code.startswith("E1")]
    if syntax or result.document is None:
        result.diagnostics = [d for d in result.diagnostics if d.severity.value != "note"]
        return None, result
    doc = result.document
    if args.to == "named" and is_legacy(doc):
        conv_sink = Sink(path)
        named, dropped = to_named_document(doc, path, conv_sink, options, ros2=args.ros2)
        if conv_sink.has_errors:
            result.diagnostics = conv_sink.sorted()
            return None, result
        out = format_document(strip_positions(named))
        head = f"# {Path(path).name} in the named form (ybgc fmt --to named{' --ros2' if args.ros2 else ''})\n"
        for key in dropped:
            head += f"# dropped `{key}`: ROS 2 has no such field\n"
        return head + "\n" + out, result
    if args.ros2 and args.to != "named":
        sys.stderr.write("ybgc fmt: --ros2 goes with --to named\n")
        sys.exit(EXIT_USAGE)
    return format_document(doc), result


def cmd_fmt(args) -> int:
    from ybg.writer import WriteError, same_file, write_output, write_text_atomic

    options = _options(args)
    if args.output and len(args.files) > 1:
        sys.stderr.write("ybgc fmt: -o takes one input file\n")
        return EXIT_USAGE
    status = EXIT_OK
    failed = []
    for path in _select(args):
        new, result = _formatted(path, args, options)
        if new is None:
            failed.append(result)
            continue
        old = result.text
        if args.stdout:
            sys.stdout.write(new)
            continue
        if args.check or args.diff:
            if new != old:
                status = EXIT_PROBLEMS
                if args.diff:
                    sys.stdout.writelines(difflib.unified_diff(
                        old.splitlines(keepends=True), new.splitlines(keepends=True), path, path))
                else:
                    sys.stderr.write(f"{path}: would be reformatted\n")
            continue
        target = Path(args.output) if args.output else Path(path)
        if not args.output or same_file(target, Path(path)):  # in place: fmt's purpose, the one write over an input
            if old == new:
                continue
            try:
                write_text_atomic(Path(path), new)
            except OSError as e:
                return _write_error(WriteError(f"cannot write {path}: {e.strerror or e}",
                                               "check that the file can be written, or write the result "
                                               "elsewhere with -o FILE"))
        else:
            try:
                if not write_output(target, new, force=args.force, inputs=(Path(path),),
                                    elsewhere="name a new file with -o FILE (--stdout prints it)"):
                    continue
            except WriteError as e:
                return _write_error(e)
        sys.stderr.write(f"{path}: {'converted' if args.to else 'reformatted'}"
                         f"{' -> ' + str(target) if args.output else ''}\n")
    if failed:
        _print(failed, "text")
        return EXIT_USAGE if any(_io_error(r) for r in failed) else EXIT_PROBLEMS
    return status


def cmd_ir(args) -> int:
    import json

    from ybg.compiler import ir
    from ybg.compiler.typehash import program_store, with_type_hashes

    options = _options(args)
    result = _compile(folder_config("ir", args.file), args, options)
    _print([result], "text")
    if result.program is None:
        return EXIT_USAGE if _io_error(result) else EXIT_PROBLEMS
    # the IR, and the type hash of each ROS topic and service (ybg/compiler/typehash.py)
    d = with_type_hashes(ir.to_dict(result.program), program_store(result.program, options))
    sys.stdout.write(json.dumps(d, indent=2, ensure_ascii=False) + "\n")
    return EXIT_OK


def cmd_generate(args) -> int:
    from ybg.backends import LoweringError, RenderOptions, get_backend, lowering_diagnostic
    from ybg.writer import WriteError, write_files

    result = _compile(folder_config(f"--backend {args.backend}", args.file), args, _options(args))
    _print([result], "text")
    if result.program is None:
        return EXIT_USAGE if _io_error(result) else EXIT_PROBLEMS
    backend = get_backend(args.backend)
    outdir = Path(args.output) if args.output else Path(result.program.module)
    try:
        # the folder, for what runs the module from it (the yarpmanager application)
        files = backend.render(result.program, RenderOptions(package=args.package, single_file=args.single_file,
                                                             extra={"workdir": str(outdir.resolve())}))
    except LoweringError as e:  # what `check --backend` reports too: it lowers the program the same way
        result.diagnostics = [lowering_diagnostic(e, args.backend, result)]
        _print([result], "text")
        return EXIT_PROBLEMS
    except OSError as e:  # a file of ybgc's own (a template, the runtime library) missing or unreadable
        import ybg

        sys.stderr.write(f"ybgc: error: this installation of ybgc cannot read {e.filename or e}: "
                         f"{e.strerror or e}\n    hint: reinstall ybgc (pip install --force-reinstall ybgc); "
                         f"its files are in {Path(ybg.__file__).parent}\n")
        return EXIT_USAGE
    try:
        rep = write_files(outdir, files, force=args.force, inputs=(Path(result.path),))
    except WriteError as e:
        return _write_error(e)
    for path, region in rep.lost_regions:
        sys.stderr.write(f"ybgc: warning: {path}: user code of region `{region}` has no place in the "
                         "new file; it was not kept\n")
    n = len(rep.written)
    sys.stderr.write(f"ybgc: {args.backend} module `{result.program.module}` in {outdir}/ "
                     f"({n} file{'s' if n != 1 else ''} written, {len(rep.unchanged)} unchanged)\n")
    return EXIT_OK


def cmd_compose(args) -> int:
    from ybg.backends import LoweringError, RenderOptions, get_backend, lowering_diagnostic
    from ybg.compiler.across import check_across
    from ybg.compiler.names import identifier_problem, sanitize_identifier
    from ybg.writer import WriteError, write_files

    files = expand_folders(args.files, "compose") or folder_configs()
    if not files:
        _usage_error(f"no config named, and no ybgc config in {Path.cwd()}",
                     "name the configs: ybgc compose a.ini b.ini --backend cpp")
    options = _options(args)
    results = [_compile(f, args, options) for f in files]
    by_file: dict[str, list] = {}
    for d in check_across(results):
        by_file.setdefault(d.file, []).append(d)
    for r in results:
        if r.path in by_file:
            r.diagnostics = sorted(r.diagnostics + by_file[r.path], key=lambda d: d.sort_key())
    _print(results, "text")
    if any(_io_error(r) for r in results):
        return EXIT_USAGE
    if any(r.program is None or r.errors for r in results):
        return EXIT_PROBLEMS
    name = args.name or sanitize_identifier(robot_name(args.files or files))
    problem = identifier_problem(name)
    if problem:
        _usage_error(f"the composed module's name `{name}` {problem}",
                     f"give another with --name, e.g. --name {sanitize_identifier(name)}")
    clash = next((r for r in results if r.program.module == name), None)
    if clash is not None:
        _usage_error(f"`{name}` is also the module name of {clash.path}: its RPC port /{name}/rpc:i would be "
                     "opened twice", "give the composed module another name with --name")
    backend = get_backend(args.backend)
    outdir = Path(args.output) if args.output else Path(name)
    programs = [r.program for r in results]
    try:
        out = backend.compose(programs, name, RenderOptions(package=args.package,
                                                           extra={"workdir": str(outdir.resolve())}))
    except LoweringError as e:
        # which config the refusal is about: the program the backend names (its module)
        who = getattr(e, "module", None)
        r = next((r for r in results if r.program.module == who), results[0])
        r.diagnostics = [lowering_diagnostic(e, args.backend, r)]
        _print([r], "text")
        return EXIT_PROBLEMS
    except NotImplementedError as e:
        sys.stderr.write(f"ybgc: error: the {args.backend} backend does not compose: {e}\n"
                         f"    hint: compose with {', '.join(n for n in backend_names() if n != args.backend)}, "
                         "or generate each config as a module of its own\n")
        return EXIT_PROBLEMS
    try:
        rep = write_files(outdir, out, force=args.force, inputs=tuple(Path(r.path) for r in results))
    except WriteError as e:
        return _write_error(e)
    n = len(rep.written)
    sys.stderr.write(f"ybgc: {args.backend} module `{name}` of {len(programs)} bridges in {outdir}/ "
                     f"({n} file{'s' if n != 1 else ''} written, {len(rep.unchanged)} unchanged)\n")
    return EXIT_OK


def cmd_graph(args) -> int:
    from ybg.graph import render, render_robot
    from ybg.writer import WriteError, write_output

    fmt = args.format or SUFFIXES.get(Path(args.output or "").suffix.lower(), "svg")
    options = _options(args)
    # the configs named, or the folder's; several (or a folder of several): the robot
    files = expand_folders(args.files, "graph") or folder_configs() or [folder_config("graph")]
    if not args.files and Path(FOLDER_CONFIG).is_file():
        files = [FOLDER_CONFIG]
    results = [_compile(f, args, options) for f in files]
    _print(results, "text")
    if any(r.program is None or r.errors for r in results):
        return EXIT_USAGE if any(_io_error(r) for r in results) else EXIT_PROBLEMS
    if len(results) == 1:  # one bridge's dataflow
        name = results[0].program.module
        text = render(results[0].program, fmt)
    else:  # a robot: every bridge's, side by side
        from ybg.compiler.names import sanitize_identifier
        name = sanitize_identifier(robot_name(args.files or files))
        text = render_robot(name, ", ".join(args.files or ["."]), [r.program for r in results], fmt)
    output = args.output or (f"{name}.svg" if fmt == "svg" else "-")
    if output == "-":
        sys.stdout.write(text)
        return EXIT_OK
    try:
        written = write_output(Path(output), text, force=args.force, inputs=tuple(Path(r.path) for r in results),
                               elsewhere="write the graph to another file with -o FILE (-o - prints it)")
    except WriteError as e:
        return _write_error(e)
    what = f"`{name}`" if len(results) == 1 else f"`{name}` ({len(results)} bridges)"
    sys.stderr.write(f"ybgc: {fmt} graph of {what} in {output}{'' if written else ' (unchanged)'}\n")
    return EXIT_OK


def cmd_probe(args) -> int:
    """Check each config, then probe what checks (docs/probe.md); the exit
    status of ``check``: 2 also when YARP or ROS 2 cannot be asked."""
    from ybg.probe import OverrideError, Settings, Unavailable, probe
    from ybg.probe.qos import parse_parameter
    from ybg.report import report

    if not 0 < args.wait <= 600:
        _usage_error(f"--wait {args.wait:g}: not a number of seconds in (0, 600]", "e.g. --wait 2")
    try:
        overrides = tuple(o for o in map(parse_parameter, args.param) if o is not None)
    except OverrideError as e:
        _usage_error(str(e), e.hint)
    options = _options(args)
    files = expand_folders(args.files, "probe") or folder_configs() or [folder_config("probe")]
    results = [_compile(f, args, options) for f in files]
    checked = [(r.program, r.path) for r in results if r.program is not None and not r.errors]
    if args.prefix and len(results) > 1:
        _usage_error("--prefix names the ports of one module: one config with it", "probe each config alone")
    try:
        found = probe(checked, options, Settings(args.wait, args.prefix, overrides)) if checked else {}
    except (OverrideError, Unavailable) as e:
        _usage_error(str(e), e.hint)
    for r in results:
        r.diagnostics = sorted(r.diagnostics + found.get(r.path, []), key=lambda d: d.sort_key())
    sources = {r.path: r.text for r in results if r.text is not None}
    stream = sys.stdout if args.format != "text" else sys.stderr
    report(args.format, [d for r in results for d in r.diagnostics], sources, stream, notes=args.verbose)
    if any(_io_error(r) for r in results):
        return EXIT_USAGE
    if any(r.errors for r in results) or (args.strict and any(r.warnings for r in results)):
        return EXIT_PROBLEMS
    return EXIT_OK


def cmd_init(args) -> int:
    """Configs from a running robot (ybg.init, docs/init.md)."""
    from ybg.init import run
    return run(args)


def main(argv: list[str] | None = None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    # `ybgc config.ini --backend cpp` is `ybgc generate config.ini --backend cpp`
    if argv and argv[0] not in COMMANDS and not argv[0].startswith("-"):
        argv = ["generate"] + argv
    elif argv and argv[0].startswith("-") and any(a in ("--backend", "-b") or a.startswith("--backend=") for a in argv) \
            and not any(a in COMMANDS for a in argv):
        argv = ["generate"] + argv
    parser = build_parser()
    args = parser.parse_args(argv)
    if args.command is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    handler = {"check": cmd_check, "fmt": cmd_fmt, "ir": cmd_ir, "generate": cmd_generate,
               "compose": cmd_compose, "graph": cmd_graph, "probe": cmd_probe, "init": cmd_init}[args.command]
    try:
        return handler(args)
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
