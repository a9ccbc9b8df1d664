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
    refusal says; ``commands``, whether it builds a config of commands. ``ybgc check --backend`` and generation both refuse a
    program from this declaration alone (E318, ``ybg.backends.support``),
    and the hint of a refusal names the backends whose declaration builds it."""

    outputs: frozenset[str]
    inputs: frozenset[str]
    features: Mapping[str, frozenset[str]]
    why: Mapping[tuple[str, str], str] = field(default_factory=dict)
    #: does it build a config of commands (``ir.Commands``: YARP RPC ports and
    #: ROS 2 services)? Else ``why_not_commands`` says why not.
    commands: bool = False
    why_not_commands: str = ""

    def builds_feature(self, output: str, feature: str) -> bool:
        return feature in self.features.get(output, frozenset())


class Backend:
    """Base class of a backend. Subclasses set ``name`` and implement
    :meth:`render`; what they build and their description are the
    registry's (``ybg.backends.registry.REGISTRY``), set on the subclass
    from there."""

    name: str = ""
    description: str = ""
    builds: Builds
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

    def render(self, program: "Program", options: RenderOptions = RenderOptions()) -> dict[str, str]:
        """The files of ``program``'s module: ``{relative path: text}``."""
        raise NotImplementedError

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
        --backend`` runs it, so that what checks also generates. By default
        it renders; a backend overrides it with its lowering alone."""
        self.render(program)
        self.render(program, RenderOptions(package=True))


__all__ = ["Backend", "Builds", "RenderOptions"]
