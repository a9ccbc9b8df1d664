"""The INI dialect users write: each feature of the grammar, with positions."""

from __future__ import annotations

from ybg.compiler import ast
from ybg.compiler.diagnostics import Sink
from ybg.compiler.fmt import format_document
from ybg.compiler.parser import parse_text


def parse(text: str):
    sink = Sink("t.ini")
    doc = parse_text(text, sink)
    return doc, sink.items


def entry(doc, section, key):
    return next(s for s in doc.sections if s.title == section).get(key)


def test_sections_entries_and_labels():
    doc, problems = parse("[output]\nport = /a:o\n\n[mux arm]\nports = /b:o\n")
    assert not problems
    assert [s.title for s in doc.sections] == ["output", "mux arm"]
    e = entry(doc, "mux arm", "ports")
    assert e.items == (ast.Word("/b:o"),)
    assert (e.key_span.line, e.key_span.column) == (5, 1)
    assert (e.items[0].span.line, e.items[0].span.column) == (5, 9)


def test_comments_hash_and_semicolon_not_inside_quotes():
    doc, problems = parse('[m]\na = "x # y ; z"  ; trailing\n# own line\nb = 1 # trailing too\n')
    assert not problems
    assert entry(doc, "m", "a").items == (ast.Str("x # y ; z"),)
    assert entry(doc, "m", "b").items == (ast.Word("1"),)
    assert [(c.text, c.line, c.own_line) for c in doc.comments] == [
        ("; trailing", 2, False), ("# own line", 3, True), ("# trailing too", 4, False)]


def test_string_escapes():
    doc, problems = parse(r'[m]' "\n" r'a = "q\" b\\ n\n t\t u\u00e9 x\x41 U\U0001F600"' "\n")
    assert not problems
    assert entry(doc, "m", "a").items[0].value == 'q" b\\ n\n t\t u\u00e9 xA U\U0001F600'


def test_numbers_words_and_booleans():
    doc, _ = parse("[m]\na = 60, -1.5e3, .5, nan, true, sensor_msgs/JointState, /p:o\n")
    items = entry(doc, "m", "a").items
    assert [i.number() for i in items[:4]][:3] == [60, -1500.0, 0.5]
    assert items[3].number() != items[3].number()  # nan
    assert items[4].boolean() is True
    assert items[5].text == "sensor_msgs/JointState" and items[6].text == "/p:o"


def test_list_continued_after_trailing_comma():
    """Figure 5 of the thesis continues `2_msg` on the next line."""
    doc, problems = parse('[message]\n2_msg = "a", "b",\n"c", "d"\n3_type = mux\n')
    assert not problems
    assert [i.value for i in entry(doc, "message", "2_msg").items] == ["a", "b", "c", "d"]
    assert entry(doc, "message", "3_type").items == (ast.Word("mux"),)


def test_trailing_comma_before_next_key_ends_the_list():
    doc, problems = parse("[mux1]\nports = /dummy_head/state:o,\nfunction = deg_to_rad\n")
    assert not problems
    assert entry(doc, "mux1", "ports").items == (ast.Word("/dummy_head/state:o"),)
    assert entry(doc, "mux1", "function").items == (ast.Word("deg_to_rad"),)


def test_trailing_comma_before_section_and_blank_lines():
    doc, problems = parse("[a]\nx = 1,\n\n[b]\ny = 2,\n")
    assert not problems
    assert entry(doc, "a", "x").items == (ast.Word("1"),)
    assert entry(doc, "b", "y").items == (ast.Word("2"),)


def test_continuation_across_a_comment_line():
    doc, problems = parse("[a]\nx = 1,\n  # the rest\n  2\n")
    assert not problems
    assert entry(doc, "a", "x").items == (ast.Word("1"), ast.Word("2"))


def test_empty_values():
    doc, problems = parse('[message]\n4_msg =\n5_msg = \n3_msg = ""\nv = []\n')
    assert not problems
    assert entry(doc, "message", "4_msg").items == ()
    assert entry(doc, "message", "5_msg").items == ()
    assert entry(doc, "message", "3_msg").items == (ast.Str(""),)
    assert entry(doc, "message", "v").items == (ast.Bracket(()),)


def test_tabs_crlf_and_bom():
    text = "\ufeff[general]\r\noutput_name\t=\t/x\r\n\t\r\n[mux1]\r\nports = /a:o\r\n"
    doc, problems = parse(text)
    assert not problems
    assert entry(doc, "general", "output_name").items == (ast.Word("/x"),)
    assert entry(doc, "mux1", "ports").items[0].span.line == 5


def test_no_final_newline():
    doc, problems = parse("[a]\nx = 1")
    assert not problems and entry(doc, "a", "x").items == (ast.Word("1"),)


def test_calls_subscripts_and_brackets():
    doc, problems = parse("[m]\nports = /a:o (float64 x6, int32 x3)\nc = scale(0.5)[6:9], deg_to_rad[0:]\n"
                          "x = arm[3], [arm[0:2]], timestamp(arm)\n")
    assert not problems
    (port,) = entry(doc, "m", "ports").items
    assert isinstance(port, ast.Call) and port.func == ast.Word("/a:o")
    assert port.args == ((ast.Word("float64"), ast.Word("x6")), (ast.Word("int32"), ast.Word("x3")))
    scale, d2r = entry(doc, "m", "c").items
    assert scale == ast.Subscript(ast.Call(ast.Word("scale"), ((ast.Word("0.5"),),)), 6, 9, True)
    assert d2r == ast.Subscript(ast.Word("deg_to_rad"), 0, None, True)
    at, br, ts = entry(doc, "m", "x").items
    assert at == ast.Subscript(ast.Word("arm"), 3, None, False)
    assert br == ast.Bracket((ast.Subscript(ast.Word("arm"), 0, 2, True),))
    assert ts == ast.Call(ast.Word("timestamp"), ((ast.Word("arm"),),))


def test_every_broken_line_is_reported_in_one_run():
    doc, problems = parse('[a]\nx 1\ny = "open\nz = 2\nw = (3\n')
    assert [(p.code, p.span.line) for p in problems] == [("E103", 2), ("E102", 3), ("E105", 5)]
    assert entry(doc, "a", "z").items == (ast.Word("2"),)  # the good lines are kept


def test_fmt_canonical_output():
    doc, _ = parse("[output]  ; out\nport=/o:o\n\n\n\n[message]\n# c\nx=1,2 ,3,\n")
    assert format_document(doc) == "[output]  ; out\nport = /o:o\n\n[message]\n# c\nx = 1, 2, 3\n"


def test_indexed_keys_end_a_continued_list():
    """A key may index an element of an array (`transforms[0].child_frame_id`);
    after a comma that ends a line, such a key starts a new entry, as any
    key does, rather than continuing the list."""
    sink = Sink()
    doc = parse_text('[message]\nname = "a",\ntransforms[0].child_frame_id = "x"\n'
                     'transforms[12].transform.rotation.w = 1\n', sink)
    assert sink.items == []
    (sec,) = doc.sections
    assert [e.key for e in sec.entries] == ["name", "transforms[0].child_frame_id",
                                            "transforms[12].transform.rotation.w"]
    assert [i.value for i in sec.entries[0].items] == ["a"]


def test_field_paths_with_indices():
    from ybg.compiler.passes.message import field_path, written

    assert field_path("transforms[0].child_frame_id") == ("transforms", 0, "child_frame_id")
    assert field_path("points[12]") == ("points", 12)
    assert field_path("header.frame_id") == ("header", "frame_id")
    for bad in ("a[0][1]", "a..b", "[0].x", "a[x]", "a.", "a[0]b"):
        assert field_path(bad) is None, bad
    assert written(("transforms", 0, "child_frame_id")) == "transforms[0].child_frame_id"
