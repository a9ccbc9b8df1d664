"""Escaping for generated C++: the only ways a config value reaches C++ text.

- :func:`cpp_string` a narrow string literal for any Python ``str``;
- :func:`cpp_std_string` the same as a ``std::string`` expression (keeps
  embedded NUL bytes);
- :func:`cpp_comment` text safe inside a ``//`` comment;
- :func:`cpp_float`, :func:`cpp_int` exact numeric literals;
- :func:`cpp_identifier` an identifier checked against the C++ keywords,
  reserved names and the grammar of identifiers.

The literal is plain ASCII: printable characters stay as they are, except
``"`` and ``\\`` (escaped) and a ``?`` that follows another ``?`` (escaped,
so no trigraph-like ``??x`` appears); every other byte of the UTF-8 encoding
(control characters, NUL, DEL, non-ASCII text) is a three-digit octal escape.
An octal escape is at most three digits long, so a digit that follows one
can never extend it (a ``\\x`` escape would swallow any following hex
digit). Lone surrogates are encoded with ``surrogatepass``, so any ``str``
gives a literal.
"""

from __future__ import annotations

import math
import re

#: C++20 keywords and alternative tokens, plus identifiers with a special
#: meaning (``final``, ``override``, ``import``, ``module``) and the macro-like
#: names of the C library that a generated name must not shadow.
CPP_KEYWORDS = frozenset("""
alignas alignof and and_eq asm atomic_cancel atomic_commit atomic_noexcept auto bitand
bitor bool break case catch char char8_t char16_t char32_t class compl concept const
consteval constexpr constinit const_cast continue co_await co_return co_yield decltype
default delete do double dynamic_cast else enum explicit export extern false float for
friend goto if inline int long mutable namespace new noexcept not not_eq nullptr operator
or or_eq private protected public reflexpr register reinterpret_cast requires return
short signed sizeof static static_assert static_cast struct switch synchronized template
this thread_local throw true try typedef typeid typename union unsigned using virtual void
volatile wchar_t while xor xor_eq
final override import module transaction_safe transaction_safe_dynamic
assert errno NULL EOF stdin stdout stderr main
""".split())

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\Z")

_SIMPLE = {
    0x22: '\\"',
    0x5C: "\\\\",
    0x0A: "\\n",
    0x09: "\\t",
    0x0D: "\\r",
}


def _escape_bytes(data: bytes) -> str:
    out: list[str] = []
    last = ""
    for b in data:
        if b in _SIMPLE:
            piece = _SIMPLE[b]
        elif b == 0x3F:  # '?': never two in a row (trigraphs, -Wtrigraphs)
            piece = "\\?" if last.endswith("?") else "?"
        elif 0x20 <= b < 0x7F:
            piece = chr(b)
        else:
            piece = f"\\{b:03o}"
        out.append(piece)
        last = piece
    return "".join(out)


def utf8(text: str) -> bytes:
    """The bytes a literal of ``text`` holds (UTF-8; lone surrogates kept)."""
    if not isinstance(text, str):
        raise TypeError(f"expected a str, got {type(text).__name__}")
    return text.encode("utf-8", "surrogatepass")


def cpp_string(text: str) -> str:
    """A C++ narrow string literal (``"..."``, ASCII only, one line) holding
    the UTF-8 bytes of ``text``. Embedded NUL bytes are kept in the literal;
    use :func:`cpp_std_string` where the length matters."""
    return '"' + _escape_bytes(utf8(text)) + '"'


def cpp_std_string(text: str) -> str:
    """A ``std::string`` expression for ``text``: the bare literal when it has
    no NUL byte (it converts implicitly), else ``std::string("...", n)`` so
    that the bytes after a NUL are kept."""
    data = utf8(text)
    literal = '"' + _escape_bytes(data) + '"'
    if b"\0" in data:
        return f"std::string({literal}, {len(data)})"
    return literal


def cpp_comment(text: str) -> str:
    """``text`` for a ``//`` comment: as a quoted, escaped literal, so that no
    newline, trailing backslash (line splice) or ``??/`` can end the comment
    or glue the next line to it."""
    return cpp_string(text)


def cpp_float(value: float) -> str:
    """A double literal that the compiler reads back as exactly ``value``
    (``repr`` gives the shortest round-trip digits)."""
    value = float(value)
    if math.isnan(value):
        return "std::numeric_limits<double>::quiet_NaN()"
    if math.isinf(value):
        return ("" if value > 0 else "-") + "std::numeric_limits<double>::infinity()"
    text = repr(value)
    if not re.fullmatch(r"-?[0-9]+(\.[0-9]+)?(e[-+][0-9]+)?", text):
        raise ValueError(f"unexpected float repr {text!r}")
    if "." not in text and "e" not in text:
        text += ".0"
    return text


def cpp_int(value: int, bits: int = 64) -> str:
    """An integer literal of a signed type of ``bits`` bits (the value wraps
    like a cast to that type; the most negative value is written so that no
    literal overflows)."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise TypeError(f"expected an int, got {type(value).__name__}")
    if bits not in (8, 16, 32, 64):
        raise ValueError(f"no signed {bits}-bit type")
    mod = 1 << bits
    value %= mod
    if value >= mod // 2:
        value -= mod
    if value == -(mod // 2):
        return f"({value + 1} - 1)"
    return str(value)


def cpp_identifier(name: str) -> str:
    """``name`` if it is a usable C++ identifier: the identifier grammar, not
    a keyword (or a special name), not reserved (``__`` anywhere, or ``_``
    and an upper-case letter at the start). Raises ValueError otherwise."""
    if not isinstance(name, str) or not _IDENT.match(name):
        raise ValueError(f"{name!r} is not a C++ identifier")
    if name in CPP_KEYWORDS:
        raise ValueError(f"{name!r} is a C++ keyword")
    if "__" in name or re.match(r"_[A-Z]", name):
        raise ValueError(f"{name!r} is reserved in C++")
    return name


def mangle(prefix: str, name: str) -> str:
    """An identifier made of ``prefix`` (an identifier ending in ``_``) and a
    config name: characters outside ``[A-Za-z0-9_]`` become ``_``, runs of
    ``_`` collapse to one (``__`` is reserved). Callers make the results
    unique; the result is checked by :func:`cpp_identifier`."""
    body = re.sub(r"[^A-Za-z0-9_]", "_", name)
    return cpp_identifier(re.sub(r"_+", "_", prefix + body))


_SAFE_TEXT = re.compile(r"[A-Za-z0-9_/.:@+\-\[\]<=>, ]*\Z")


def comment(text: str) -> str:
    """Config text for a ``//`` comment: as it is when made only of safe
    characters (names, ports, types), else quoted and escaped."""
    if _SAFE_TEXT.match(text) and text.strip() == text and text:
        return text
    return cpp_comment(text)


__all__ = ["comment", 
    "CPP_KEYWORDS", "cpp_string", "cpp_std_string", "cpp_comment", "cpp_float", "cpp_int",
    "cpp_identifier", "mangle", "utf8",
]
