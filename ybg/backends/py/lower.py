"""Lowering of a checked :class:`~ybg.compiler.ir.Program` to the view-model
that the ``py`` backend's template prints: a YARP module in Python.

Every decision is taken here or in the lowering library
(:mod:`ybg.lower.python`: the specs of inputs, muxes and converters, and the
Bottle builder); every value taken from the config reaches the generated
source through :func:`~ybg.lower.python.py_literal`, and the template only
prints what this module hands it.
"""

from __future__ import annotations

from dataclasses import dataclass

from ybg.compiler import ir
from ybg.lower.errors import Line, LoweringError
from ybg.lower.python import (BottleBuilder, InputView, MuxView, OutputView, RuntimeImport, bottle_output,
                              converter_views, py_literal, py_types, runtime_imports, timing_summary)
from ybg.lower.wire import WIRE_ROS1, WIRE_YARP
from ybg.lower.compose import config_file


@dataclass(frozen=True)
class ModuleView:
    filename: str
    config: str
    module: str
    default_prefix: str
    summary: tuple[str, ...]
    muxes: tuple[MuxView, ...]
    needed: str
    rate: str
    trigger: str
    queue: str
    on_stale: str
    on_nan: str
    publish: str
    output: OutputView
    wire: tuple[tuple[str, str], ...]
    builder: tuple[Line, ...]
    runtime_imports: tuple[RuntimeImport, ...] = ()


def lower(program: ir.Program) -> ModuleView:
    """The view-model of the module generated for ``program``."""
    output = bottle_output(program, "py")
    muxes = []
    used: set[str] = set()
    for m in program.muxes:
        inputs = []
        for k, i in enumerate(m.inputs):
            if i.kind not in ("yarp", "ros1"):
                raise LoweringError(f"the py backend cannot read a {i.kind!r} input ({i.name})", i.span)
            types = i.element_types
            width = "any number of numbers" if types is None else f"{len(types)} elements"
            if i.reads is not None:
                width += f"; the message reads the first {i.reads} (W511)"
            if i.accepts:
                width += f"; also from {', '.join(i.accepts)}"
            inputs.append(InputView(
                mux=py_literal(m.name),
                index=k,
                source=py_literal(i.name),
                kind=py_literal(i.kind),
                types=py_types(types),
                timeout=py_literal(float(i.timeout)),
                description=py_literal(f"{i.kind} {i.name}: {width}"),
                positions=py_literal(i.positions),
                reads=py_literal(i.reads),
                accepts=py_literal(tuple(i.accepts)),
            ))
        convs = converter_views(m, used)
        muxes.append(MuxView(
            name=py_literal(m.name),
            inputs=tuple(inputs),
            converters=convs,
            verbose=py_literal(bool(m.verbose)),
            types=py_types(m.element_types),
        ))

    b = BottleBuilder(program)
    top_type = program.message.msg_type or program.output.msg_type
    b.struct(program.message, top_type, 1, "return ", "")
    needed = tuple(b.muxes)

    wire_map = WIRE_ROS1 if program.output.kind == "ros1" else WIRE_YARP
    wire = tuple((py_literal(k), py_literal(v)) for k, v in sorted(wire_map.items()))

    n_in = sum(len(m.inputs) for m in program.muxes)
    summary = (
        py_literal(f"module {program.module}: {n_in} input(s) in {len(program.muxes)} mux(es)"),
        output.description,
        py_literal(timing_summary(program)),
    )
    config_name = config_file(program)
    rate = program.timing.rate
    return ModuleView(
        filename=f"{program.module}.py",
        config=py_literal(config_name),
        module=py_literal(program.module),
        default_prefix=py_literal("/" + program.module),
        summary=summary,
        muxes=tuple(muxes),
        needed=py_literal(needed),
        rate=py_literal(None if rate is None else float(rate)),
        trigger=py_literal(program.timing.trigger),
        queue=py_literal(int(program.timing.queue)),
        on_stale=py_literal(program.policy.on_stale),
        on_nan=py_literal(program.policy.on_nan),
        publish=py_literal(program.timing.publish),
        output=output,
        wire=wire,
        builder=tuple(b.lines),
        runtime_imports=runtime_imports(used),
    )
