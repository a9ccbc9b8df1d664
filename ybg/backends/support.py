"""Can a backend build a program? E318 when it cannot, E321 when a ROS 2
output has no message definition to build from.

Both ``ybgc check --backend B`` and ``ybgc generate --backend B`` ask
:func:`check_result`, which refuses from B's declaration
(:class:`~ybg.backends.base.Builds`: output and input kinds, message
features), then runs B's lowering for what only lowering knows; so the two
commands agree by construction. Every refusal points at the span of the
IR element refused, and its hint names the backends that build it, from
their declarations."""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from ybg.backends import features
from ybg.backends.base import Backend
from ybg.backends.registry import REGISTRY, backend_names, get_backend
from ybg.compiler.diagnostics import Diagnostic, Sink
from ybg.compiler.names import converted_name
from ybg.lower.errors import LoweringError

if TYPE_CHECKING:
    from ybg.compiler.ir import Program, Struct
    from ybg.compiler.pipeline import Result

#: how E318 names an output of each IR kind
_OUTPUT_KINDS = {"ros2": "a ROS 2 topic", "ros1": "a ROS 1 topic", "yarp": "a YARP port"}


def _writers(kind: str) -> list[str]:
    return [n for n in backend_names() if kind in REGISTRY[n].builds.outputs]


def _readers(kind: str) -> list[str]:
    return [n for n in backend_names() if kind in REGISTRY[n].builds.inputs]


def _options(names: list[str]) -> str:
    return " or ".join(f"`--backend {n}`" for n in names)


def declared(program: "Program", backend: str) -> bool:
    """Does ``backend``'s declaration cover everything ``program`` asks for?"""
    sink = Sink()
    check(program, backend, sink)
    return not sink.has_errors


def check(program: "Program", backend: str, sink: Sink, legacy: bool = False) -> None:
    """Can ``backend`` build ``program``, by its declaration? E318 when it
    cannot, E321 when a ROS 2 output has no message definition; ``legacy``:
    the config is in the legacy form, and the hints say how to convert it."""
    builds = REGISTRY[backend].builds
    if program.kind not in builds.kinds:
        others = [n for n in backend_names() if program.kind in REGISTRY[n].builds.kinds]
        sink.error("E318", f"the {backend} backend cannot build {_KINDS[program.kind]}: "
                   f"{builds.why_not[program.kind]}", program.span, f"use {_options(others)}")
        return
    if program.kind == "stream":
        _check_stream(program, backend, builds, sink, legacy)


#: how a refusal names a kind of bridge
_KINDS = {"stream": "streams", "commands": "commands", "actions": "actions"}


def _check_stream(program: "Program", backend: str, builds, sink: Sink, legacy: bool) -> None:
    out = program.output
    span = out.span
    if out.kind not in builds.outputs:
        if out.kind == "ros1" and "ros2" in builds.outputs:
            hint = _legacy_to_ros2_hint(program, sink.file) if legacy else \
                "set `via = ros2` in [output] (and drop `header.seq`, which ROS 2 has not)"
            sink.error("E318", "this config publishes to ROS 1 through YARP (`to_ros = true` / `via = ros1`); "
                       f"the {backend} backend publishes to ROS 2", span, hint)
        else:
            sink.error("E318", f"the {backend} backend cannot write {_OUTPUT_KINDS[out.kind]}", span,
                       f"use {_options(_writers('ros2'))} for ROS 2 outputs, "
                       f"{_options(_writers('ros1'))} for YARP and ROS 1")
        return
    if out.kind == "ros2" and all(i.kind == "ros2" for m in program.muxes for i in m.inputs):
        sink.error("E318", "nothing to bridge: this config reads ROS 2 topics and publishes a ROS 2 topic, "
                   "with no YARP side", span,
                   "read YARP ports (`ports = ...`) or write a YARP port (`port = ...`)")
        return
    for m in program.muxes:
        for i in m.inputs:
            if i.kind not in builds.inputs:
                if i.kind == "ros1" and "ros2" in builds.inputs:
                    hint = (_legacy_inputs_to_ros2_hint(program, i.name, sink.file) if legacy else
                            "set `via = ros2` in the mux, with each topic's type: `/topic (pkg/Name)`")
                else:
                    hint = (f"ROS 2 topics are read by {_options(_readers('ros2'))}; "
                            f"ROS 1 topics by {' and '.join(_readers('ros1'))}")
                sink.error("E318", f"the {backend} backend cannot read {i.kind} input `{i.name}` (mux `{m.name}`)",
                           i.span, hint)
                return
    for feature, where in features.used(program).items():
        if not builds.builds_feature(out.kind, feature):
            why = builds.why.get((out.kind, feature))
            others = [n for n in backend_names() if n != backend and REGISTRY[n].builds.builds_feature(out.kind, feature)
                      and out.kind in REGISTRY[n].builds.outputs]
            hint = f"a limit of the {backend} backend: change this part of the config"
            if others:
                hint += f", or use {_options(others)}"
            sink.error("E318", f"the {backend} backend cannot build {features.FEATURES[feature]} for "
                       f"{_OUTPUT_KINDS[out.kind]}" + (f": {why}" if why else ""), where, hint)
            return
    if out.kind == "ros2" and not _typed(program.message):
        name = out.msg_type or program.message.msg_type or ""
        hint = "give the folder of its .msg files with `--msg-path DIR` (DIR/<pkg>/msg/<Name>.msg) or YBG_MSG_PATH"
        if "/" not in name:
            hint = f"write it with its package, `pkg/{name}`, and {hint}"
        sink.error("E321", f"the {backend} backend builds a ROS 2 message field by field from its definition, "
                   f"and the definition of `{name}` was not found", out.type_span, hint)


def _legacy_to_ros2_hint(program: "Program", path: str) -> str:
    """E318's hint for a config in the legacy form that publishes to ROS 1:
    the command that converts it for ROS 2, or, when the conversion needs
    what the file does not say (the message type, or its definition), that
    first."""
    command = f"ybgc fmt --to named --ros2 FILE -o {converted_name(path)}"
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
    new = converted_name(path)
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


def lowering_diagnostic(error: LoweringError, backend: str, result: "Result") -> Diagnostic:
    """``error``, raised by ``backend``'s lowering for ``result``'s program,
    as the diagnostic that ``ybgc check --backend`` and ``ybgc generate``
    report: at the span of the element refused, else at the output."""
    sink = Sink(result.path)
    program = result.program
    span = error.span
    if span is None and program is not None:
        span = program.span
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
    """Does ``backend`` take ``program``, by its declaration and its lowering?"""
    return declared(program, backend) and _lowering_error(backend, program) is None


def check_result(result: "Result", backend: str) -> "Result":
    """``result`` of the front end as ``backend`` sees it: with the
    diagnostics of :func:`check`, and of the backend's lowering when that
    refuses the program (:meth:`Backend.lower`), and without a program it
    cannot build. A result without a program is returned as it is."""
    if result.program is None:
        return result
    sink = Sink(result.path)
    check(result.program, backend, sink, result.form == "legacy")
    if not sink.has_errors:
        error = _lowering_error(backend, result.program)
        if error is not None:
            sink.items.append(lowering_diagnostic(error, backend, result))
    if not sink.items:
        return result
    return dataclasses.replace(result, program=None if sink.has_errors else result.program,
                               diagnostics=sorted(result.diagnostics + sink.items, key=Diagnostic.sort_key))


__all__ = ["check", "check_result", "declared", "lowering_diagnostic"]
