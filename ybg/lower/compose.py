"""What the backends' composed modules share (docs/compose.md): where each
bridge's config is, for the texts that name it (a single module's too), the folder of the bridges'
modules, and the refusal of one bridge of a composition."""

from __future__ import annotations

import os

from ybg.lower.errors import LoweringError

#: the folder of the bridges' modules, beside the composed module
BRIDGES = "bridges"


def config_file(program) -> str:
    """The config's file name (the module's name for a program of no file)."""
    return os.path.basename(program.source) if program.source else program.module


def config_at(program) -> str:
    """Where the config writes the bridge's output (a config of commands: its
    first service): ``file:line:column``, or the file alone."""
    span = program.span
    name = config_file(program)
    return f"{name}:{span.line}:{span.column}" if span is not None else name


def refusal(program, message: str, span=None) -> LoweringError:
    """A LoweringError of one bridge of a composition (reported with its config)."""
    e = LoweringError(message, span)
    e.module = program.module
    return e


__all__ = ["BRIDGES", "config_file", "config_at", "refusal"]
