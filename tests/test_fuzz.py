"""Property tests: configs generated from the grammar and arbitrary text never
produce a traceback, only diagnostics; formatting keeps the meaning."""

from __future__ import annotations

import re
import string
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, assume, find, given, settings
from hypothesis import strategies as st
from hypothesis.extra.lark import from_lark

from harness.properties import examples
from ybg.backends import backend_names, check_result
from ybg.compiler import ir, legacy
from ybg.compiler.diagnostics import Sink
from ybg.compiler.fmt import format_document, format_item, quote
from ybg.compiler.msgtypes import DISTROS, load_store
from ybg.compiler.names import RESERVED
from ybg.compiler.parser import lark_parser, parse_text
from ybg.compiler.passes import converters, sections
from ybg.compiler.options import Options
from ybg.compiler.pipeline import compile_text

ROOT = Path(__file__).resolve().parent.parent

# The vocabulary the mutations draw from, read from the grammar and from the
# tables of what the compiler knows, so that a keyword added there is fuzzed
# without a change here.
_TERMINALS = {t.name: t.pattern for t in lark_parser().terminals}
#: the grammar's literal tokens (brackets, `=`, `,`, `:`, `-` ...)
PUNCTUATION = sorted(p.value for p in _TERMINALS.values() if p.type == "str")
#: the words the grammar itself knows: `expr`, which opens an expression (`expr(`)
GRAMMAR_WORDS = [re.sub(r"\\\($", "", _TERMINALS["EXPR_OPEN"].value)]
CONVERTER_NAMES = sorted({*converters.CONVERTERS, *ir.GEOMETRY_WIDTHS, *GRAMMAR_WORDS})
#: every key of the named form's sections and of the legacy form's
KEYS = sorted({k for keys in sections.SECTION_KEYS.values() for k in keys}
              | {*legacy.GENERAL_KEYS, *legacy.MUX_KEYS, "num_fields"})
#: every word a value can take: choices, converters and their parameters, expression
#: functions and names, element types, legacy field types, reserved words, distros
WORDS = sorted({*(w for ws in sections.CHOICES.values() for w in ws), *CONVERTER_NAMES,
                *converters.AXES, *converters.UNITS, *converters.EXPR_NAMES, *ir.EXPR_FUNCTIONS,
                *ir.ELEMENT_TYPES, *legacy.FIELD_TYPES, *RESERVED, *DISTROS})
#: the section headers of both forms
HEADERS = sorted({f"[{name}]" for name in sections.SECTION_KEYS if name != "mux"}
                 | {"[mux m]", "[mux n]", "[general]", "[mux1]", "[header]"})
#: message types whose fields take muxes in many ways (nested numbers, quaternions, arrays)
MESSAGE_TYPES = ["sensor_msgs/Imu", "geometry_msgs/PoseStamped", "geometry_msgs/QuaternionStamped",
                 "sensor_msgs/JointState", "geometry_msgs/PointStamped", "tf2_msgs/TFMessage"]
_STORE = load_store("ros2", None, (), {})


def _field_paths(type_name: str) -> list[str]:
    """The fields of a message and of its nested messages, dotted."""
    msgdef = _STORE.resolve(type_name)
    paths = []
    for f in msgdef.fields:
        paths.append(f.name)
        sub = _STORE.resolve(f.type.base) if f.type.is_message else None
        if sub is not None:
            paths.extend(f"{f.name}{'[0]' if f.type.array else ''}.{g.name}" for g in sub.fields)
    return paths


FIELDS = {t: _field_paths(t) for t in MESSAGE_TYPES}

# terminals whose regular expressions hold look-aheads get explicit strategies
_word_chars = string.ascii_letters + string.digits + "_./:@+-~"
GRAMMAR_TEXT = from_lark(
    lark_parser(cache=False),  # built cold: strict mode (no conflicts, no collisions) checked here
    explicit={
        "KEY": st.sampled_from(KEYS + ["position", "header.frame_id", "header.stamp", "1_type", "1_msg", "x",
                                       "transforms[0].child_frame_id", "points[1].positions", "a[0]",
                                       "markers[12].pose.position", "x[0][1]", "[0].x"]),
        "WORD": st.one_of(
            st.sampled_from(WORDS + ["sensor_msgs/JointState", "arm", "mux1", "60", "-1.5e3", "/a/b:o", "x6",
                                     "header"]),
            st.text(_word_chars, min_size=1, max_size=8)),
        "_CONT": st.sampled_from([",\n  ", ",\n# c\n  ", ", ; c\n\t"]),
        "_NL": st.sampled_from(["\n", "\n\n", " ; c\n", "\r\n", "\n\t\n", " # x\n"]),
        "SIGNED_INT": st.from_regex(r"-?[0-9]{1,2}", fullmatch=True),
    },
)
SECTION_NAMES = st.sampled_from([*(h[1:-1] for h in HEADERS), "mux arm", "mux"])


def _no_traceback(text: str, backend: str | None = None) -> None:
    result = compile_text(text, "<fuzz>")
    if backend is not None and result.program is not None:
        result = check_result(result, backend)
    for d in result.diagnostics:
        assert d.code and d.message and d.span.line >= 1 and d.span.column >= 1


@settings(max_examples=examples(150), deadline=None, suppress_health_check=list(HealthCheck))
@given(GRAMMAR_TEXT)
def test_grammar_generated_configs_never_raise(text):
    _no_traceback(text)


def test_grammar_generation_covers_expressions():
    """The grammar's strategy writes expressions (`expr(...)`) too."""
    text = find(GRAMMAR_TEXT, lambda t: "expr(" in t,
                settings=settings(max_examples=5000, database=None, phases=[Phase.generate]))
    _no_traceback(text)


@settings(max_examples=examples(300), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=300))
def test_arbitrary_text_never_raises(text):
    _no_traceback(text)


@st.composite
def ini_like(draw):
    """Plausible configs: real keys and values in real sections, shuffled."""
    lines = []
    for _ in range(draw(st.integers(1, 5))):
        lines.append(f"[{draw(SECTION_NAMES)}]")
        for _ in range(draw(st.integers(0, 6))):
            key = draw(st.sampled_from(KEYS + ["position", "header.frame_id", "1_type", "1_msg", "1_mux",
                                               "velocity", "header.stamp", "transforms[0].child_frame_id",
                                               "transforms[1].header.stamp", "transforms[0]",
                                               "points[0].positions", "points[2].x", "position[0]",
                                               "header[0].frame_id"]))
            val = draw(st.sampled_from([
                "/joint_states", "ros2", "ros1", "sensor_msgs/JointState", "60", "/a:o (float64 x3)",
                "tf2_msgs/TFMessage", "trajectory_msgs/JointTrajectory",
                "deg_to_rad", "arm", "arm[0:2]", '"a", "b"', "[]", "", "true", "mux1", "mux", "msg",
                "header", "counter", "timestamp", "timestamp(arm)", "scale(2)[0:1]", '"base"', "3",
                "/a:o, /b:o,", "1, 2, 3", "/a:o (float64 x7)", "euler_to_quat(rpy, deg)[0:3]",
                "axis_angle_to_quat[3:7]", "quat_to_euler(xyz, rad)", "transform_to_pose", "quat_normalize[0:4]",
                "expr(clamp(x, -1, 1) * 0.5)[0:3]", "expr(x)", "expr(foo(x) / y)[1]", "expr(-(x - 1))",
                "deg_to_rad, expr(atan2(x, 2))[2:]", "expr(x)(2)", "[expr(x)]", *WORDS]))
            lines.append(f"{key} = {val}".rstrip())
    return "\n".join(lines) + "\n"


@settings(max_examples=examples(400), deadline=None, suppress_health_check=list(HealthCheck))
@given(ini_like())
def test_plausible_configs_never_raise(text):
    _no_traceback(text)


def _subscript():
    """`[i]`, `[a:b]`, `[a:]`, `[:b]`, or none: in and out of range, negative, empty."""
    bound = st.integers(-2, 17).map(str)
    return st.one_of(
        st.just(""), st.just(""), st.sampled_from(["[0:3]", "[3:7]", "[0:4]", "[3:6]", "[0:9]"]),
        bound.map(lambda i: f"[{i}]"),
        st.tuples(st.one_of(st.just(""), bound), st.one_of(st.just(""), bound)).map(lambda ab: f"[{ab[0]}:{ab[1]}]"))


def _expression():
    """An expression of `expr(...)`: the names and functions it knows, and others, with any number of arguments."""
    leaf = st.one_of(st.sampled_from([*converters.EXPR_NAMES, "y", "deg"]),
                     st.sampled_from(["0", "1", "0.5", "1e999", ".5", "2e-3"]))
    return st.recursive(leaf, lambda inner: st.one_of(
        st.tuples(inner, st.sampled_from(["+", "-", "*", "/"]), inner).map(lambda t: f"{t[0]} {t[1]} {t[2]}"),
        inner.map(lambda e: f"-{e}"), inner.map(lambda e: f"({e})"),
        st.tuples(st.sampled_from([*ir.EXPR_FUNCTIONS, "foo", "x"]), st.lists(inner, max_size=4))
        .map(lambda t: f"{t[0]}({', '.join(t[1])})")), max_leaves=6)


def _argument():
    """A parameter of a converter call: a known word, a number, text, a declaration, a near miss."""
    return st.one_of(st.sampled_from(WORDS), st.sampled_from(["0.5", "-2", "1e999", "nan", "3", '"deg"', "x3"]),
                     st.sampled_from(WORDS).map(str.upper), st.sampled_from(WORDS).map(lambda w: w + "s"),
                     st.tuples(st.sampled_from(sorted(ir.ELEMENT_TYPES)), st.integers(0, 9))
                     .map(lambda t: f"{t[0]} x{t[1]}"))


def _parameters(name: str) -> str:
    """The parameters a converter takes, written right."""
    if name in ("euler_to_quat", "quat_to_euler"):
        return "rpy, deg"
    return "0.5" if converters.CONVERTERS.get(name, (0,))[0] else ""


@st.composite
def converter_item(draw):
    """A converter as a config may write it: each name (and near misses) bare, called with its
    parameters or with parameters of every kind and count (with and without a space before `(`),
    called twice, or an expression, each with or without a range."""
    name = draw(st.sampled_from(CONVERTER_NAMES * 4 + [n[:-1] for n in CONVERTER_NAMES] + [n.upper() for n in CONVERTER_NAMES]))
    form = draw(st.sampled_from(["right", "right", "bare", "call", "spaced call", "expression", "twice"]))
    args = ", ".join(draw(st.lists(_argument(), max_size=3)))
    if form == "right":
        params = _parameters(name)
        text = f"expr({draw(_expression())})" if name == "expr" else f"{name}({params})" if params else name
    elif form == "bare":
        text = name
    elif form == "expression":
        text = f"expr({draw(_expression())})"
    elif form == "twice":
        text = f"{name}({args})({draw(_argument())})"
    else:
        text = f"{name}{' ' if form == 'spaced call' else ''}({args})"
    return text + draw(_subscript())


def _mux_ref(mux: str):
    return st.one_of(_subscript().map(lambda sub: mux + sub), st.just(f"timestamp({mux})"), st.just(f"[{mux}]"))


@st.composite
def converter_configs(draw):
    """A named config whose muxes convert in every way the language knows (and others), into
    a message of a known type or an untyped Bottle, its fields taking the muxes whole or in part."""
    out = draw(st.sampled_from([None, *MESSAGE_TYPES]))
    lines = ["[output]"] + ([f"topic = /out\ntype = {out}\nvia = ros2"] if out else ["port = /out:o"])
    for mux in ("m", "n")[:draw(st.integers(1, 2))]:
        decl = draw(st.sampled_from(["", " (float64 x3)", " (float64 x4)", " (float64 x7)", " (float64 x9)",
                                     " (float64 x16)", " (float64 x6, int32 x3)", " (string x1, float64 x3)"]))
        lines += ["", f"[mux {mux}]", f"ports = /{mux}:o{decl}",
                  f"convert = {', '.join(draw(st.lists(converter_item(), min_size=1, max_size=3)))}"]
    lines += ["", "[message]"]
    keys = draw(st.lists(st.sampled_from(FIELDS[out] if out else ["a", "b.c", "d[0].e"]), min_size=1, max_size=4,
                         unique=True))
    for key in keys:
        lines.append(f"{key} = {draw(st.one_of(_mux_ref('m'), _mux_ref('m'), _mux_ref('n'), st.sampled_from(WORDS)))}")
    return "\n".join(lines) + "\n"


@settings(max_examples=examples(150), deadline=None, suppress_health_check=list(HealthCheck))
@given(converter_configs(), st.sampled_from(backend_names()))
def test_converter_configs_never_raise(text, backend):
    _no_traceback(text, backend)


@pytest.mark.parametrize("name", CONVERTER_NAMES)
def test_each_converter_written_every_way_is_a_diagnostic(name):
    """Each converter bare, called with no, one or several parameters of each kind, with a space
    before `(`, called twice, with a range: checked, a program or errors with their positions."""
    for form in (name, f"{name}()", f"{name}(rpy, deg)", f"{name}(0.5)", f"{name}(x, 1, deg, 2)",
                 f'{name}("deg", float64 x3)', f"{name} (xyz, rad)", f"{name}(0.5)(2)", f"{name}[0:3]",
                 f"{name}(rpy, degrees)[0:3]", f"expr({name}(x))", f"{name}[3:7], deg_to_rad[0:2]"):
        for decl in ("(float64 x16)", "(float64 x3)", ""):
            text = f"[output]\nport = /out:o\n\n[mux m]\nports = /m:o {decl}\nconvert = {form}\n\n[message]\nv = m\n"
            result = compile_text(text, "<converter>")
            assert result.program is not None or result.errors, text
            for d in result.errors:
                assert d.span.line >= 1 and d.span.column >= 1, (text, d)


#: real configs to mutate: the examples, the canonical files, the legacy corpus, the invalid corpus
SEEDS = [p.read_text(encoding="utf-8") for p in
         sorted((ROOT / "examples").glob("*.ini")) + sorted((ROOT / "tests" / "canonical").glob("*.ini"))
         + sorted((ROOT.parent / "shared" / "legacy").glob("*.ini"))
         + sorted((ROOT / "tests" / "invalid").glob("*.ini")) if not p.name.startswith("E002")]


@st.composite
def mutated_configs(draw):
    """A real config with a few of its lines changed: a value replaced by a converter list, a
    known word or a mux reference, a key by another known key, a line by a section header, or
    a literal token of the grammar put somewhere."""
    lines = draw(st.sampled_from(SEEDS)).split("\n")
    for _ in range(draw(st.integers(1, 3))):
        k = draw(st.integers(0, len(lines) - 1))
        key, eq, value = lines[k].partition("=")
        how = draw(st.sampled_from(["convert", "value", "key", "header", "token"]))
        if how == "convert" or (how == "value" and key.strip() in ("convert", "function")):
            lines[k] = f"{key if eq else 'convert '}= {', '.join(draw(st.lists(converter_item(), min_size=1, max_size=3)))}"
        elif how == "value":
            lines[k] = f"{key if eq else lines[k] + ' '}= {draw(st.one_of(st.sampled_from(WORDS), _mux_ref('mux1'), _mux_ref('arm')))}"
        elif how == "key" and eq:
            lines[k] = f"{draw(st.sampled_from(KEYS))} ={value}"
        elif how == "header":
            lines[k] = draw(st.sampled_from(HEADERS))
        else:
            at = draw(st.integers(0, len(lines[k])))
            lines[k] = lines[k][:at] + draw(st.sampled_from(PUNCTUATION)) + lines[k][at:]
    return "\n".join(lines)


@settings(max_examples=examples(200), deadline=None, suppress_health_check=list(HealthCheck))
@given(mutated_configs(), st.sampled_from(backend_names()))
def test_mutated_configs_never_raise(text, backend):
    _no_traceback(text, backend)


def _parse_clean(text: str):
    sink = Sink()
    doc = parse_text(text, sink)
    return doc, sink


@settings(max_examples=examples(150), deadline=None, suppress_health_check=list(HealthCheck))
@given(st.one_of(GRAMMAR_TEXT, ini_like()))
def test_parse_fmt_parse_is_parse(text):
    doc, sink = _parse_clean(text)
    assume(not sink.items)
    formatted = format_document(doc)
    doc2, sink2 = _parse_clean(formatted)
    assert not sink2.items, (formatted, sink2.items)
    assert doc2 == doc
    # and canonical text is a fixed point
    assert format_document(doc2) == formatted


@settings(max_examples=examples(500), deadline=None)
@given(st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=40))
def test_string_quoting_round_trips(value):
    text = f"[message]\nx = {quote(value)}\n"
    doc, sink = _parse_clean(text)
    assert not sink.items
    (item,) = doc.sections[0].entries[0].items
    assert item.value == value
    assert format_item(item) == quote(value)


def test_canonical_files_are_fixed_points():
    """The identity corpus: fmt(s) == s for every canonical file."""
    files = sorted((ROOT / "examples").glob("*.ini")) + sorted((ROOT / "tests" / "canonical").glob("*.ini"))
    assert len(files) >= 10
    for f in files:
        text = f.read_text(encoding="utf-8")
        doc, sink = _parse_clean(text)
        assert not sink.items, f
        assert format_document(doc) == text, f.name


def test_fmt_keeps_program_of_examples():
    """Formatting a messy spelling of an example gives the same program."""
    for f in sorted((ROOT / "examples").glob("*.ini")):
        text = f.read_text(encoding="utf-8")
        messy = "\n".join(
            line if line.startswith("#") else line.replace(" = ", "=").replace(", ", " ,")
            for line in text.split("\n")
        ).replace("\n[", "\n\n\n[").replace("\n", "\r\n")
        # by its path: a calibration file is beside it; a user's own service in msgpkgs/
        options = Options(msg_path=(str(ROOT / "msgpkgs"),))
        a = compile_text(text, str(f), options)
        b = compile_text(messy, str(f), options)
        assert not b.errors, (f.name, b.errors)
        assert a.program == b.program
        doc, sink = _parse_clean(messy)
        assert format_document(doc) == text
