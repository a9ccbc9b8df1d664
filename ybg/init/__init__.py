"""``ybgc init``: from a running robot to checked configs (docs/init.md).

    survey (ybg.init.survey: the name server, each port's Bottles, the RPC
    ports' answers) -> plan (ybg.init.plan: which ports make which bridge,
    each config's text, what is reported instead) -> every config checked
    (the compiler's own front end and its checks across configs) -> written
    together, never over an existing file, or printed (--dry-run).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from ybg.init.plan import Plan, make


def checked(plan: Plan, options=None) -> list:
    """The errors and warnings of the plan's configs (diagnostics; none: each
    checks clean, alone and with the others)."""
    from ybg.compiler.across import check_across
    from ybg.compiler.diagnostics import Severity
    from ybg.compiler.pipeline import compile_text

    results = [compile_text(b.text, b.file, options) for b in plan.bridges if not b.draft]
    problems = [d for r in results for d in r.diagnostics]
    if not any(d.severity in (Severity.ERROR, Severity.WARNING) for d in problems):
        problems = check_across([r for r in results if r.program is not None])
    return [d for d in problems if d.severity in (Severity.ERROR, Severity.WARNING)]


def as_json(survey, plan: Plan) -> str:
    ports = []
    for name in survey.ports:
        s = survey.sampled.get(name)
        a = survey.answers.get(name)
        entry = {"port": name}
        if s is not None:
            entry.update(bottles=s.bottles, rate=round(s.rate(), 2) if s.rate() else None,
                         layouts=sorted(s.layouts), refused=s.refused,
                         image=dict(zip(("pixel_code", "width", "height"), s.image)) if s.image else None)
        if a is not None:
            entry.update(help=a.help, axes=a.axes, names=a.names)
        ports.append(entry)
    return json.dumps({
        "robot": plan.robot, "prefix": survey.prefix, "name_server": survey.server, "seconds": survey.seconds,
        "ports": ports,
        "configs": [{"file": b.file, "kind": b.kind, "module": b.module, "ports": b.ports, "draft": b.draft}
                    for b in plan.bridges],
        "reported": [{"port": r.port, "why": r.why} for r in plan.reported],
    }, indent=2) + "\n"


def as_table(survey, plan: Plan, outdir: Path, dry_run: bool) -> str:
    """What was found and what becomes of it, one line a port."""
    rows = [("port", "seen", "becomes")]
    made = {p: b for b in plan.bridges for p in b.ports}
    why = {r.port: r.why for r in plan.reported}
    for name in survey.ports:
        s = survey.sampled.get(name)
        a = survey.answers.get(name)
        if s is not None and s.bottles:
            rate = s.rate()
            seen = (f"image {s.image[0]} {s.image[1]}x{s.image[2]}" if s.image else "; ".join(sorted(s.layouts)))
            seen += f", {rate:.0f} Hz" if rate else f", {s.bottles} message(s)"
        elif a is not None:
            seen = (f"{a.axes} axes" + (", named" if a.names else "") if a.axes is not None
                    else "answers help" if a.help else "no answer")
        else:
            seen = "-"
        if name in made:
            b = made[name]
            becomes = f"{outdir / b.file} ({b.kind}{', a draft' if b.draft else ''})"
        elif name in why:
            becomes = "nothing: " + why[name]
        else:
            becomes = "(its joint names)"
        rows.append((name, seen, becomes))
    widths = [max(len(r[k]) for r in rows) for k in range(2)]
    lines = [f"{r[0]:<{widths[0]}}  {r[1]:<{widths[1]}}  {r[2]}" for r in rows]
    head = (f"ybgc init: {len(survey.ports)} port(s) under {survey.prefix or '/'} "
            f"(name server {survey.server}, {survey.seconds:g} s of sampling)")
    verb = "would write" if dry_run else "wrote"
    n = len(plan.bridges)
    tail = f"{verb} {n} file(s) in {outdir}/" if n else "no bridge found to write"
    return "\n".join([head, *lines, tail]) + "\n"


def write(plan: Plan, outdir: Path) -> list[str]:
    """Every file of the plan into ``outdir``, all or none, none over an
    existing file (:class:`ybg.writer.WriteError` says which)."""
    from ybg.writer import WriteError, write_files

    taken = [outdir / b.file for b in plan.bridges if (outdir / b.file).exists()]
    if taken:
        raise WriteError(f"{taken[0]} exists: ybgc init never writes over a file"
                         + (f" ({len(taken)} of its files exist)" if len(taken) > 1 else ""),
                         "name a new folder with -o DIR, or move the existing configs away")
    report = write_files(outdir, {b.file: b.text for b in plan.bridges})
    return report.written


#: the exit statuses of every ybgc command (ybg.cli)
EXIT_OK, EXIT_PROBLEMS, EXIT_USAGE = 0, 1, 2


def _usage(message: str, hint: str | None) -> int:
    sys.stderr.write(f"ybgc: error: {message}\n" + (f"    hint: {hint}\n" if hint else ""))
    return EXIT_USAGE


def run(args) -> int:
    """``ybgc init`` with the parsed ``args`` (ybg.cli): its exit status."""
    from ybg.init.survey import survey as ask
    from ybg.probe.plan import Unavailable
    from ybg.writer import WriteError

    if not 0 < args.seconds <= 60:
        return _usage(f"--seconds {args.seconds:g}: not a number of seconds in (0, 60]", "e.g. --seconds 2")
    prefix = args.robot.rstrip("/")
    if prefix and not prefix.startswith("/"):
        return _usage(f"--robot {args.robot}: a port prefix starts with /", f"e.g. --robot /{args.robot}")
    try:
        found = ask(prefix, args.seconds)
    except Unavailable as e:
        return _usage(str(e), e.hint)
    plan = make(found)
    outdir = Path(args.output or plan.robot)
    problems = checked(plan)
    if problems:  # a config init wrote that does not check: never written
        from ybg.report import report_text
        report_text(problems, {b.file: b.text for b in plan.bridges}, sys.stderr)
        sys.stderr.write("ybgc: error: a config ybgc init made does not check clean (above)\n"
                         "    hint: report this with the --format json output of --dry-run\n")
        return EXIT_PROBLEMS
    if args.format == "json":
        sys.stdout.write(as_json(found, plan))
    if not found.ports:
        return _usage(f"the name server lists no port under {prefix or '/'}",
                      "name the robot's prefix with --robot (yarp name list shows the ports)")
    if not args.dry_run and plan.bridges:
        try:
            write(plan, outdir)
        except WriteError as e:
            return _usage(str(e), e.hint)
    if args.format != "json":
        sys.stdout.write(as_table(found, plan, outdir, args.dry_run))
        if plan.bridges and not args.dry_run:
            sys.stdout.write(f"next: ybgc check {outdir}; ybgc compose {outdir} --backend ros2\n")
    return EXIT_OK
