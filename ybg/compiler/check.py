"""Stage 3: named-form :class:`~ybg.compiler.ast.Document` -> checked
:class:`~ybg.compiler.ir.Program`.

Every problem becomes a diagnostic with its own code, span and hint; the
check goes on after a problem, so one run reports all of them. A legacy file
reaches this stage already converted to the named form (``legacy.py``), with
the spans of its own lines. The language is described in ``docs/config.md``.

The check is a sequence of passes over one shared context (``passes/``),
one concern a module; each says what it checks, reads and sets.
"""

from __future__ import annotations

from ybg.compiler import ast, ir
from ybg.compiler.diagnostics import Sink
from ybg.compiler.options import Options
from ybg.compiler.passes import (actions, bottles, converters, cuts, dialect, inputs, message, output, program,
                                 images, sections, services, spans, typed)
from ybg.compiler.passes.context import Context

#: the passes, in the order they run
PASSES = (
    sections.run, dialect.run, inputs.run, converters.run, output.run,
    message.run, typed.run, bottles.run, images.run, cuts.run, program.run, spans.run,
)
#: the passes of a config of commands ([service] sections), after ``sections``
COMMAND_PASSES = (dialect.run, services.run)
#: the passes of a config of actions ([action] sections), after ``sections``
ACTION_PASSES = (dialect.run, actions.run)


def check_named(doc: ast.Document, source: str, sink: Sink, options: Options,
                module_default: str, legacy: bool | None = None) -> ir.Program | None:
    """Check a named-form document; the Program, or None when there are errors.
    ``legacy``: ``doc`` is the conversion of a legacy config (None: it is when
    the conversion noted the legacy form in ``sink``, N601)."""
    if legacy is None:
        legacy = any(d.code == "N601" for d in sink.items)
    ctx = Context(doc, source, sink, options, module_default, legacy)
    sections.run(ctx)
    kind = COMMAND_PASSES if ctx.service_sections else ACTION_PASSES if ctx.action_sections else PASSES[1:]
    for run in kind:
        run(ctx)
    return ctx.program
