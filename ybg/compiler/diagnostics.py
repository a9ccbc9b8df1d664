"""Diagnostics are data: every stage appends :class:`Diagnostic` objects to a
list and goes on; reporters (``ybg/report.py``) print them.

Codes are stable and documented in ``docs/diagnostics.md`` (a test checks the
two agree): ``E1xx`` syntax, ``E2xx`` structure of the config, ``E3xx`` types
against the ROS message definitions, ``E4xx`` names, ``W5xx`` warnings,
``N6xx`` notes.
"""

from __future__ import annotations

import difflib
import re
from dataclasses import dataclass, field
from enum import Enum
from typing import Iterable


@dataclass(frozen=True, order=True)
class Span:
    """A range in a source file: 1-based lines and columns, end exclusive."""

    line: int
    column: int
    end_line: int = 0
    end_column: int = 0

    @staticmethod
    def point(line: int, column: int) -> "Span":
        return Span(line, column, line, column + 1)


NOWHERE = Span(1, 1, 1, 1)


class Severity(str, Enum):
    ERROR = "error"
    WARNING = "warning"
    NOTE = "note"


@dataclass(frozen=True)
class Edit:
    """Replace the text of ``span`` (end exclusive) with ``text``; an empty
    span inserts ``text`` there."""

    span: Span
    text: str


@dataclass(frozen=True)
class Fix:
    """What a hint says to do, literally, as data: ``edits`` of the config's
    text, or a ``command`` (a ``ybgc fmt`` command line in which ``FILE``
    stands for the config). Applied, it removes the diagnostic without
    losing anything the config says (docs/diagnostics.md, "Fixes")."""

    edits: tuple[Edit, ...] = ()
    command: str | None = None


@dataclass(frozen=True)
class Diagnostic:
    severity: Severity
    code: str
    message: str
    span: Span
    hint: str | None = None
    file: str = ""
    fix: Fix | None = None  # the hint's literal fix, when it gives one

    def sort_key(self):
        return (self.file, self.span.line, self.span.column, self.code)


#: code -> one-line title. docs/diagnostics.md lists every code of this table.
CODES: dict[str, str] = {
    # I/O
    "E001": "file cannot be read",
    "E002": "file is not UTF-8 text",
    # syntax
    "E101": "unexpected character",
    "E102": "unterminated string",
    "E103": "line is not `key = value` or a `[section]`",
    "E104": "malformed section header",
    "E105": "unexpected item in value",
    "E106": "invalid escape sequence in a string",
    "E107": "entry before any section",
    "E108": "unbalanced bracket or parenthesis",
    # structure
    "E201": "unknown section",
    "E202": "unknown key",
    "E203": "missing section",
    "E204": "missing key",
    "E205": "duplicate section",
    "E206": "duplicate key",
    "E207": "legacy and named forms mixed in one file",
    "E208": "invalid value",
    "E209": "count does not match what is there",
    "E210": "malformed legacy field",
    "E211": "nested message section missing",
    "E212": "unknown mux",
    "E213": "invalid port declaration",
    "E214": "invalid module or mux name",
    "E215": "field given more than once",
    "E217": "legacy layout of the original's earliest versions",
    "E216": "no input and no rate",
    # types
    "E301": "unknown message type",
    "E302": "unknown field",
    "E303": "field count or order does not match the message",
    "E304": "value does not fit the field type",
    "E305": "mux element type does not fit the field",
    "E306": "counter into a non-integer field",
    "E307": "timestamp into a field that is not a time",
    "E308": "nested message expected",
    "E309": "mux does not fit the nested message",
    "E310": "fixed-size array length mismatch",
    "E311": "field exists only in the other ROS version",
    "E312": "array lengths disagree",
    "E313": "unknown converter",
    "E314": "converter applied to non-numeric data",
    "E315": "element range out of bounds",
    "E316": "index out of range",
    "E317": "integer out of range for the field type",
    "E318": "backend cannot build this config",
    "E319": "ROS topic input needs a message type",
    "E320": "the target YARP version has no ROS 1 support",
    "E321": "ROS 2 output without its message definition",
    # geometry converters and expressions (E322-E329)
    "E322": "wrong number of elements into a geometry converter",
    "E323": "geometry converter on a mux of unknown width",
    "E324": "unknown name or function in an expression",
    "E325": "wrong number of arguments to an expression function",
    # arrays of messages (E330-E339)
    "E330": "index on a field that is not an array of messages",
    "E331": "index beyond a fixed-size or bounded array",
    "E332": "gap in the indices of an array",
    "E333": "array of messages given a value",
    # camera images (E340-E349)
    "E340": "image where it cannot go",
    "E341": "image input badly declared",
    "E342": "encoding other than the frame's",
    "E343": "image mixed with what its frame gives",
    "E344": "camera calibration file cannot be read",

    "E350": "unknown service type",
    "E351": "no answer for a failed call",
    "E352": "a service bridges a ROS 2 service and a YARP port",
    "E353": "command or service given twice, or a command the port answers itself",
    "E354": "two kinds of bridge in one config",
    # actions (E380-E389)
    "E380": "unknown action type",
    "E381": "an action type no module carries out",
    "E382": "joints the state port cannot give",
    "E383": "converter with no inverse for set points",
    "E384": "tolerance not a number, or negative",
    "E385": "action or set-point port given twice",

    "E360": "one topic with two message types across configs",
    "E361": "one YARP port opened by two configs",
    "E362": "two configs with one module name",
    "E363": "one ROS 2 service served twice or with two types across configs",
    "W364": "a topic read with a QoS another config's publisher does not offer",
    # names
    "E401": "invalid YARP port name",
    "E402": "invalid ROS topic name",
    # warnings
    "W501": "unused mux",
    "W502": "message type given without its package",
    "W503": "message type not found: fields are not checked",
    "W504": "no rate: the module is event-driven",
    "W505": "message type missing: inferred",
    "W506": "key has no effect",
    "W507": "ROS 1 through YARP needs YARP's yarp-ros plugins on this YARP version",
    "W508": "legacy config without `to_ros`: the output is a YARP port",
    "W509": "legacy `ports` ends with a comma, which the original read as part of a name",
    "W512": "legacy layout of the original's first versions: read as its later layout",
    # notes
    "N601": "legacy form",
    "N602": "a fixed rate that publishes new data only",
    "W510": "`publish` without a rate",
    "W511": "a nested message takes part of an undeclared port: the rest is dropped",
    "W520": "a quaternion filled with data not known to be one",
}

#: the codes of ``ybgc probe`` (ybg/probe/): what the running YARP network and
#: ROS 2 graph say of a config, code -> title. Documented in their own table of
#: docs/diagnostics.md; shown by tests/test_probe.py (live peers), not by a
#: config of tests/invalid/, since no config alone gives them.
PROBE_CODES: dict[str, str] = {
    "E370": "a YARP port the module reads or calls does not answer",
    "E371": "an input port sends another layout than the config declares",
    "E372": "a YARP port the module opens is taken",
    "E373": "an endpoint of the topic or service has another type",
    "E374": "an endpoint of the topic has another type hash",
    "E375": "QoS incompatible with an endpoint of the topic",
    "E376": "the ROS 2 service the module serves has a server already",
    "W570": "no Bottle from an input port within the wait",
    "W571": "QoS compatibility with an endpoint not certain",
    "W572": "the ROS 2 service the module calls has no server yet",
    "N670": "what the probe saw",
}


def title(code: str) -> str:
    """The title of any code, of ``check`` or of ``probe``."""
    return CODES.get(code) or PROBE_CODES[code]


@dataclass
class Sink:
    """Collects diagnostics for one file."""

    file: str = ""
    items: list[Diagnostic] = field(default_factory=list)

    def add(self, severity: Severity, code: str, message: str, span: Span | None,
            hint: str | None = None, fix: Fix | None = None) -> None:
        assert code in CODES or code in PROBE_CODES, code
        self.items.append(Diagnostic(severity, code, message, span or NOWHERE, hint, self.file, fix))

    def error(self, code: str, message: str, span: Span | None, hint: str | None = None,
              fix: Fix | None = None) -> None:
        self.add(Severity.ERROR, code, message, span, hint, fix)

    def warning(self, code: str, message: str, span: Span | None, hint: str | None = None,
                fix: Fix | None = None) -> None:
        self.add(Severity.WARNING, code, message, span, hint, fix)

    def note(self, code: str, message: str, span: Span | None, hint: str | None = None,
             fix: Fix | None = None) -> None:
        self.add(Severity.NOTE, code, message, span, hint, fix)

    @property
    def has_errors(self) -> bool:
        return any(d.severity is Severity.ERROR for d in self.items)

    @property
    def error_count(self) -> int:
        return sum(d.severity is Severity.ERROR for d in self.items)

    def sorted(self) -> list[Diagnostic]:
        return sorted(self.items, key=Diagnostic.sort_key)


def closest(word: str, candidates: Iterable[str]) -> str | None:
    """The candidate closest to ``word``, or None when none is close."""
    cands = list(dict.fromkeys(candidates))
    low = {c.lower(): c for c in cands}
    close = difflib.get_close_matches(word.lower(), list(low), n=1, cutoff=0.6)
    if close:
        return low[close[0]]
    # a bare type name against `pkg/Name` candidates
    tails = {c.rsplit("/", 1)[-1].lower(): c for c in cands}
    close = difflib.get_close_matches(word.rsplit("/", 1)[-1].lower(), list(tails), n=1, cutoff=0.75)
    return tails[close[0]] if close else None


def did_you_mean(word: str, candidates: Iterable[str], n: int = 1) -> str | None:
    """``"did you mean `x`?"`` for the closest candidate, or None."""
    guess = closest(word, candidates)
    return f"did you mean `{guess}`?" if guess else None


#: a `ybgc fmt ...` command quoted in a hint
_HINT_COMMAND = re.compile(r"`(ybgc fmt(?: [^`]*)?)`")


def fix_of(d: Diagnostic, legacy: bool) -> Fix | None:
    """The fix the hint of ``d`` carries: its ``fix``; else the ``ybgc fmt``
    command its text quotes, ``--to named`` only for a config in the
    legacy form (``legacy``), which it converts (for a config in the named
    form such a command is advice for legacy files: it only reformats)."""
    if d.fix is not None:
        return d.fix
    for command in _HINT_COMMAND.findall(d.hint or ""):
        if "--to named" in command and not legacy:
            continue
        return Fix(command=command)
    return None


def apply_edits(text: str, edits: Iterable[Edit]) -> str:
    """``text`` with ``edits`` made (their spans are of ``text``, 1-based;
    the spans of two edits do not overlap)."""
    starts = [0] + [m.end() for m in re.finditer("\n", text)]  # where each line begins (lines end at \n)
    ends = starts[1:] + [len(text)]

    def offset(line: int, column: int) -> int:
        if line > len(starts):
            return len(text)
        return min(starts[line - 1] + column - 1, ends[line - 1])

    out = text
    for e in sorted(edits, key=lambda e: (e.span.line, e.span.column), reverse=True):
        a = offset(e.span.line, e.span.column)
        b = offset(e.span.end_line or e.span.line, e.span.end_column or e.span.column)
        out = out[:a] + e.text + out[max(a, b):]
    return out
