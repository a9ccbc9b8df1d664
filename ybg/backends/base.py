"""The interface of a backend: what it declares it builds, and how it is
asked for files."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Mapping

if TYPE_CHECKING:
    from ybg.compiler.ir import Program


@dataclass(frozen=True)
class RenderOptions:
    """Options every backend accepts. ``package``: also emit the packaging
    around the module (ament_python package for ``ros2``). ``single_file``:
    the runtime inlined into the module, one file with no runtime beside it."""

    package: bool = False
    single_file: bool = False
    extra: dict = field(default_factory=dict)


@dataclass(frozen=True)
class Builds:
    """What a backend builds, declared once (``ybg.backends.registry``):
    ``outputs`` and ``inputs``, the IR kinds of output and input it builds
    (``"yarp"``, ``"ros1"``, ``"ros2"``); ``features``, for each output kind,
    the message features it builds (``ybg.backends.features.FEATURES``:
    ``"fixed_array"``, ``"message_array"``, ``"rows"``), and ``why``, for a
    feature it does not build for an output kind, the reason, which the
    refusal says; ``kinds``, the kinds of bridge it builds
    (``ir.BRIDGE_KINDS``: ``"stream"``, ``"commands"``), and ``why_not``, for
    a kind it does not build, the reason; ``composes``, the kinds it puts
    into a composed module, and ``why_not_composed`` why not another it
    builds. ``ybgc check --backend`` and generation both
    refuse a program from this declaration alone (E318,
    ``ybg.backends.support``), and the hint of a refusal names the backends
    whose declaration builds it."""

    outputs: frozenset[str]
    inputs: frozenset[str]
    features: Mapping[str, frozenset[str]]
    why: Mapping[tuple[str, str], str] = field(default_factory=dict)
    kinds: frozenset[str] = frozenset({"stream"})
    why_not: Mapping[str, str] = field(default_factory=dict)
    composes: frozenset[str] = frozenset()
    why_not_composed: Mapping[str, str] = field(default_factory=dict)

    def builds_feature(self, output: str, feature: str) -> bool:
        return feature in self.features.get(output, frozenset())


class BridgeKind:
    """How a backend builds one kind of bridge (``ir.BRIDGE_KINDS``): a
    backend's :attr:`Backend.bridge_kinds` holds one for each kind its
    declaration builds."""

    def render(self, bridge, options: RenderOptions) -> dict[str, str]:
        """The files of ``bridge``'s module: ``{relative path: text}``."""
        raise NotImplementedError

    def lower(self, bridge) -> None:
        """Every decision :meth:`render` makes, without printing: raises the
        ``LoweringError`` it would."""
        self.render(bridge, RenderOptions())
        self.render(bridge, RenderOptions(package=True))


class Backend:
    """Base class of a backend. Subclasses set ``name`` and
    :attr:`bridge_kinds`, the lowering of each kind of bridge they build;
    what they build and their description are the registry's
    (``ybg.backends.registry.REGISTRY``), set on the subclass from there.
    :meth:`kind` is the one place that chooses the lowering of a bridge."""

    name: str = ""
    description: str = ""
    builds: Builds
    #: kind of bridge -> how it is built here
    bridge_kinds: Mapping[str, BridgeKind] = {}
    #: the IR output and input kinds it builds (its declaration's)
    output_kinds: frozenset[str] = frozenset()
    input_kinds: frozenset[str] = frozenset()

    def __init_subclass__(cls, **kwargs) -> None:
        super().__init_subclass__(**kwargs)
        from ybg.backends.registry import REGISTRY

        info = REGISTRY[cls.name]
        cls.description = info.description
        cls.builds = info.builds
        cls.output_kinds = info.builds.outputs
        cls.input_kinds = info.builds.inputs

    def kind(self, bridge) -> BridgeKind:
        """How this backend builds ``bridge``, by its kind; a kind it does
        not build is a ``LoweringError`` saying why (its declaration's
        reason, which ``ybgc check --backend`` gives first)."""
        found = self.bridge_kinds.get(bridge.kind)
        if found is None:
            from ybg.lower.errors import LoweringError

            raise LoweringError(self.builds.why_not.get(bridge.kind, f"it builds no {bridge.kind} bridge"),
                                bridge.span)
        return found

    def render(self, program: "Program", options: RenderOptions = RenderOptions()) -> dict[str, str]:
        """The files of ``program``'s module: ``{relative path: text}``."""
        return self.kind(program).render(program, options)

    def check_composed(self, bridges) -> None:
        """Refuse the first of ``bridges`` whose kind this backend does not
        compose, by its declaration (a ``LoweringError`` naming its module)."""
        from ybg.lower.compose import refusal

        for b in bridges:
            if b.kind not in self.builds.kinds:  # not built at all: why
                raise refusal(b, self.builds.why_not.get(b.kind, f"it builds no {b.kind} bridge"), b.span)
            if b.kind not in self.builds.composes:
                why = self.builds.why_not_composed.get(b.kind)
                raise refusal(b, f"a config of {b.kind} is not composed by the {self.name} backend (yet)"
                                 + (f": {why}" if why else ""), b.span)

    def compose(self, programs: "list[Program]", name: str,
                options: RenderOptions = RenderOptions()) -> dict[str, str]:
        """The files of one module ``name`` that runs every program of
        ``programs`` (each checked, together too) in one process
        (docs/compose.md): ``{relative path: text}``. A refusal is a
        ``LoweringError`` whose ``module`` attribute names the program it
        refuses. A backend that does not compose raises
        ``NotImplementedError`` with the reason."""
        raise NotImplementedError("it builds one config a module")

    def lower(self, program: "Program") -> None:
        """Make every decision :meth:`render` makes, without printing: raises
        the ``LoweringError`` that :meth:`render` would. ``ybgc check
        --backend`` runs it, so that what checks also generates."""
        self.kind(program).lower(program)


__all__ = ["Backend", "BridgeKind", "Builds", "RenderOptions"]
