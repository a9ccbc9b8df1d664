"""Backends: lower a checked :class:`~ybg.compiler.ir.Program` to files.

Each backend is one package (``cpp/``, ``py/``, ``ros2/``) with its own
``templates/``, built on the lowering library (:mod:`ybg.lower`) and never
on another backend. A backend only reads the IR and returns ``{relative
path: text}``; writing files (atomically, only when changed) is the CLI's
job. Lowering decisions are made in Python; templates only print.

- :mod:`.base`: the interface (:class:`Backend`, :class:`RenderOptions`) and
  the declaration of what a backend builds (:class:`Builds`);
- :mod:`.registry`: the backends by name, with their declarations;
- :mod:`.features`: the message features of a program that not every
  backend builds;
- :mod:`.support`: whether a backend builds a program (E318, E321), for
  ``ybgc check --backend`` and generation alike.

This module is their public face: the names the CLI and the tests use.
"""

from __future__ import annotations

from ybg.backends.base import Backend, Builds, RenderOptions
from ybg.backends.registry import REGISTRY, backend_names, get_backend
from ybg.backends.support import check, check_result, lowering_diagnostic
from ybg.lower.errors import LoweringError

__all__ = ["Backend", "Builds", "RenderOptions", "REGISTRY", "backend_names", "get_backend", "check",
           "check_result", "lowering_diagnostic", "LoweringError"]
