"""Property tests: configs generated from the grammar and arbitrary text never
produce a traceback, only diagnostics; formatting keeps the meaning."""

from __future__ import annotations

import string
from pathlib import Path

from hypothesis import HealthCheck, Phase, assume, find, given, settings
from hypothesis import strategies as st
from hypothesis.extra.lark import from_lark

from ybg.compiler.diagnostics import Sink
from ybg.compiler.fmt import format_document, format_item, quote
from ybg.compiler.parser import lark_parser, parse_text
from ybg.compiler.pipeline import compile_text

ROOT = Path(__file__).resolve().parent.parent

# terminals whose regular expressions hold look-aheads get explicit strategies
_word_chars = string.ascii_letters + string.digits + "_./:@+-~"
GRAMMAR_TEXT = from_lark(
    lark_parser(cache=False),  # built cold: strict mode (no conflicts, no collisions) checked here
    explicit={
        "KEY": st.sampled_from(["topic", "port", "type", "via", "rate", "ports", "convert", "name",
                                "position", "header.frame_id", "header.stamp", "num_fields", "1_type",
                                "1_msg", "output_name", "to_ros", "num_mux", "verbose", "x",
                                "transforms[0].child_frame_id", "points[1].positions", "a[0]",
                                "markers[12].pose.position", "x[0][1]", "[0].x"]),
        "WORD": st.one_of(
            st.sampled_from(["ros2", "ros1", "yarp", "sensor_msgs/JointState", "deg_to_rad", "scale",
                             "arm", "mux1", "60", "-1.5e3", "true", "/a/b:o", "float64", "x6",
                             "counter", "timestamp", "msg", "list", "header", "nan", "inf"]),
            st.text(_word_chars, min_size=1, max_size=8)),
        "_CONT": st.sampled_from([",\n  ", ",\n# c\n  ", ", ; c\n\t"]),
        "_NL": st.sampled_from(["\n", "\n\n", " ; c\n", "\r\n", "\n\t\n", " # x\n"]),
        "SIGNED_INT": st.from_regex(r"-?[0-9]{1,2}", fullmatch=True),
    },
)
SECTION_NAMES = st.sampled_from(["general", "mux1", "mux arm", "message", "header", "output", "module", "mux"])


def _no_traceback(text: str) -> None:
    result = compile_text(text, "<fuzz>")
    for d in result.diagnostics:
        assert d.code and d.message and d.span.line >= 1 and d.span.column >= 1


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
@given(GRAMMAR_TEXT)
def test_grammar_generated_configs_never_raise(text):
    _no_traceback(text)


def test_grammar_generation_covers_expressions():
    """The grammar's strategy writes expressions (`expr(...)`) too."""
    text = find(GRAMMAR_TEXT, lambda t: "expr(" in t,
                settings=settings(max_examples=5000, database=None, phases=[Phase.generate]))
    _no_traceback(text)


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
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
            key = draw(st.sampled_from(["topic", "port", "type", "via", "rate", "ports", "convert",
                                        "position", "name", "header.frame_id", "num_fields", "1_type",
                                        "1_msg", "1_mux", "output_name", "to_ros", "num_mux", "num_ports",
                                        "function", "velocity", "timeout", "header.stamp",
                                        "transforms[0].child_frame_id", "transforms[1].header.stamp",
                                        "transforms[0]", "points[0].positions", "points[2].x",
                                        "position[0]", "header[0].frame_id"]))
            val = draw(st.sampled_from([
                "/joint_states", "ros2", "ros1", "sensor_msgs/JointState", "60", "/a:o (float64 x3)",
                "tf2_msgs/TFMessage", "trajectory_msgs/JointTrajectory",
                "deg_to_rad", "arm", "arm[0:2]", '"a", "b"', "[]", "", "true", "mux1", "mux", "msg",
                "header", "counter", "timestamp", "timestamp(arm)", "scale(2)[0:1]", '"base"', "3",
                "/a:o, /b:o,", "1, 2, 3", "/a:o (float64 x7)", "euler_to_quat(rpy, deg)[0:3]",
                "axis_angle_to_quat[3:7]", "quat_to_euler(xyz, rad)", "transform_to_pose", "quat_normalize[0:4]",
                "expr(clamp(x, -1, 1) * 0.5)[0:3]", "expr(x)", "expr(foo(x) / y)[1]", "expr(-(x - 1))",
                "deg_to_rad, expr(atan2(x, 2))[2:]", "expr(x)(2)", "[expr(x)]"]))
            lines.append(f"{key} = {val}".rstrip())
    return "\n".join(lines) + "\n"


@settings(max_examples=400, deadline=None, suppress_health_check=list(HealthCheck))
@given(ini_like())
def test_plausible_configs_never_raise(text):
    _no_traceback(text)


def _parse_clean(text: str):
    sink = Sink()
    doc = parse_text(text, sink)
    return doc, sink


@settings(max_examples=300, deadline=None, suppress_health_check=list(HealthCheck))
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


@settings(max_examples=500, deadline=None)
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
        a = compile_text(text, f.name)
        b = compile_text(messy, f.name)
        assert not b.errors, (f.name, b.errors)
        assert a.program == b.program
        doc, sink = _parse_clean(messy)
        assert format_document(doc) == text
