"""``ybgc graph``: the dataflow of the checked program. For every example and
legacy config, the SVG is well-formed XML naming every port, mux, converter
and field, and the DOT and Mermaid texts hold every node and every edge the
IR implies (worked out here from the IR, element by element); a config with
errors gives its diagnostics, not a graph; the files are written atomically."""

from __future__ import annotations

import html
import re
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

from harness.generated import YBGC
from ybg.compiler import ir
from ybg.compiler.options import Options
from ybg.compiler.pipeline import compile_path
from ybg.graph import render

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = sorted((ROOT / "examples").glob("*.ini"))
LEGACY = sorted((ROOT.parent / "shared" / "legacy").glob("*.ini"))
FIGURE5 = ROOT.parent / "shared" / "legacy" / "thesis_figure5_rviz.ini"
DOCS_SVG = ROOT / "docs" / "graph_thesis_figure5.svg"
SVG = "{http://www.w3.org/2000/svg}"
STAGE = {"in": "input", "mux": "mux", "conv": "converter", "field": "field", "out": "output"}
#: elements of a mux of run-time width that the test looks at
UNBOUNDED = 64


def ybgc_in(folder: Path, *args) -> subprocess.CompletedProcess:
    return subprocess.run([str(YBGC), *map(str, args)], capture_output=True, text=True, cwd=folder,
                          timeout=60)


def program_of(path: Path) -> ir.Program:
    # the examples of a user's own services find them in msgpkgs/
    result = compile_path(str(path), Options(msg_path=(str(ROOT / "msgpkgs"),)))
    assert result.ok, [str(d) for d in result.diagnostics]
    return result.program


def leaves(struct: ir.Struct, prefix: str = ""):
    """(path, source) of every field the config sets."""
    for f in struct.fields:
        if isinstance(f.source, ir.Struct):
            yield from leaves(f.source, f"{prefix}{f.name}.")
        elif not isinstance(f.source, ir.Default):
            yield prefix + f.name, f.source


def elements(start: int, stop: int | None, width: int | None) -> set[int]:
    end = stop if stop is not None else (width if width is not None else UNBOUNDED)
    return set(range(start, end))


def expected_commands(program: ir.Commands):
    """The nodes and edges of a config of commands: who calls the module (a
    ROS 2 service served, or a YARP port served, once for its commands), the
    command it makes, what it calls, and the fields the answer (serves ros2)
    or the arguments (serves yarp) fill."""
    nodes, edges = set(), set()
    for svc in program.services:
        made = ("mux", f"command {svc.name}")
        caller = ("input", svc.service if svc.serves == "ros2" else svc.port)
        callee = ("output", svc.port if svc.serves == "ros2" else svc.service)
        nodes |= {made, caller, callee}
        edges |= {(caller, made), (made, callee)}
        for fill in svc.fills:
            field = ("field", ("response." if svc.serves == "ros2" else "request.") + fill.ref.dotted)
            nodes.add(field)
            edges |= {(callee, field)} if svc.serves == "ros2" else {(caller, field), (field, made)}
    return nodes, edges


def expected_actions(program: ir.Actions):
    nodes, edges = set(), set()
    for a in program.actions:
        served, state, goal = ("input", a.action), ("input", a.state), ("mux", f"action {a.name}")
        nodes |= {served, state, goal, ("output", a.command)}
        edges |= {(served, goal), (state, goal)}
        last = goal
        for c in a.converters:
            nodes.add(("converter", c.name))
            edges.add((last, ("converter", c.name)))
            last = ("converter", c.name)
        edges.add((last, ("output", a.command)))
    return nodes, edges


def expected(program: ir.Program):
    """The nodes, as (stage, name), and the edges between them that the
    IR implies."""
    if isinstance(program, ir.Commands):
        return expected_commands(program)
    if isinstance(program, ir.Actions):
        return expected_actions(program)
    nodes, edges = set(), set()
    out = ("output", program.output.name)
    nodes.add(out)
    for m in program.muxes:
        nodes.add(("mux", m.name))
        for i in m.inputs:
            nodes.add(("input", i.name))
            edges.add((("input", i.name), ("mux", m.name)))
        for c in m.converters:
            nodes.add(("converter", c.name))
            edges.add((("mux", m.name), ("converter", c.name)))
    for path, src in leaves(program.message):
        field = ("field", path)
        nodes.add(field)
        edges.add((field, out))
        if isinstance(src, ir.MuxRef):
            m = program.mux(src.mux)
            read = {src.index} if src.index is not None else elements(src.start, src.stop, m.width)
            unconverted = set(read)
            for c in m.converters:
                converted = read & elements(c.start, c.stop, m.width)
                if converted:
                    edges.add((("converter", c.name), field))
                unconverted -= converted
            if unconverted:
                edges.add((("mux", m.name), field))
        elif isinstance(src, ir.Timestamp) and src.mux:
            edges.add((("mux", src.mux), field))
    return nodes, edges


def parsed(ids: dict[str, str], edge_pairs) -> tuple[set, set]:
    """(stage, name) nodes and edges from node ids and their names."""
    def node(i):
        return STAGE[re.match(r"[a-z]+", i).group()], ids[i]
    return {node(i) for i in ids}, {(node(a), node(b)) for a, b in edge_pairs}


def parse_dot(text: str):
    ids = {}
    for i, label in re.findall(r'^  (\w+) \[label="((?:[^"\\]|\\.)*)"', text, re.M):
        ids[i] = re.sub(r"\\(.)", r"\1", label.split("\\n")[0])
    return parsed(ids, re.findall(r"^  (\w+) -> (\w+);$", text, re.M))


def parse_mermaid(text: str):
    ids = {}
    for i, label in re.findall(r'^  (\w+)[(\[{]+"(.*?)"[)\]}]+:::\w+$', text, re.M):
        name = label.split("<br/>")[0]
        ids[i] = re.sub(r"#(\w+);", lambda m: html.unescape(f"&{m.group(1)};") if not m.group(1).isdigit()
                        else chr(int(m.group(1))), name)
    return parsed(ids, re.findall(r"^  (\w+) --> (\w+)$", text, re.M))


CONFIGS = EXAMPLES + LEGACY


def test_the_corpus_is_there():
    assert len(EXAMPLES) >= 8 and len(LEGACY) == 7


@pytest.mark.parametrize("path", CONFIGS, ids=[p.name for p in CONFIGS])
def test_every_node_and_edge_of_the_ir(path):
    program = program_of(path)
    nodes, edges = expected(program)
    for fmt, parse in (("dot", parse_dot), ("mermaid", parse_mermaid)):
        got_nodes, got_edges = parse(render(program, fmt))
        assert got_nodes == nodes, fmt
        assert got_edges == edges, fmt
    svg = ET.fromstring(render(program, "svg").encode("utf-8"))
    assert svg.tag == SVG + "svg"
    boxes = svg.findall(f".//{SVG}g[@class]")
    named = {(g.get("class").split()[1], g.find(SVG + "text").text)
             for g in boxes if g.get("class").startswith("node ")}
    assert named == nodes
    assert len(svg.findall(f".//{SVG}g[@class='edges']/{SVG}path")) == len(edges)


def test_svg_text_is_escaped(tmp_path):
    cfg = tmp_path / "odd.ini"
    cfg.write_text('[output]\nport = /odd:o\n\n[mux ab]\nports = /x/y:o (float64 x2)\n\n'
                   '[message]\nlabel = "<b>&amp; \\"q\\" #1 -- \\\\"\nv = [ab]\n')
    program = program_of(cfg)
    svg = ET.fromstring(render(program, "svg").encode("utf-8"))
    texts = [t.text for t in svg.iter(SVG + "text")]
    assert '= "<b>&amp; \\"q\\" #1 -- \\\\"' in texts, texts
    for fmt, parse in (("dot", parse_dot), ("mermaid", parse_mermaid)):
        assert parse(render(program, fmt)) == expected(program), fmt


def test_the_figure_in_docs_is_the_thesis_figure5_config():
    """docs/ shows the graph of the thesis' figure-5 config as ybgc draws it
    (regenerate: ybgc graph ../shared/legacy/thesis_figure5_rviz.ini -o docs/graph_thesis_figure5.svg)."""
    assert DOCS_SVG.read_text(encoding="utf-8") == render(program_of(FIGURE5), "svg")
    assert render(program_of(FIGURE5), "mermaid") in (ROOT / "docs" / "graph.md").read_text(encoding="utf-8")


def test_cli_formats_and_outputs(tmp_path):
    cfg = tmp_path / "hand.ini"
    cfg.write_text((ROOT / "examples" / "mixed_types_yarp.ini").read_text())
    r = ybgc_in(tmp_path, "graph", cfg)  # a picture: SVG into ./<module>.svg
    assert r.returncode == 0 and r.stdout == "", r.stderr
    assert ET.parse(tmp_path / "hand_status.svg").getroot().tag == SVG + "svg"
    r = ybgc_in(tmp_path, "graph", cfg, "--format", "mermaid")  # text: printed
    assert r.returncode == 0 and r.stdout.startswith("flowchart LR\n  %% generated by ybgc from hand.ini"), r.stderr
    assert ybgc_in(tmp_path, "graph", cfg, "--format", "dot").stdout.splitlines()[1] == 'digraph "hand_status" {'
    for name, first in (("g.dot", "digraph"), ("g.gv", "digraph"), ("g.mmd", "flowchart LR"), ("g.svg", "<svg")):
        r = ybgc_in(tmp_path, "graph", cfg, "-o", name)  # the format from the file's ending
        assert r.returncode == 0, r.stderr
        assert first in (tmp_path / name).read_text(), name
    r = ybgc_in(tmp_path, "graph", cfg, "--format", "svg", "-o", "-")
    assert ET.fromstring(r.stdout.encode()).tag == SVG + "svg"
    # atomic: an existing graph is replaced whole, keeping its mode, no temporary left
    target = tmp_path / "g.dot"
    target.write_text("// generated by ybgc: an older graph\nold")
    target.chmod(0o640)
    assert ybgc_in(tmp_path, "graph", cfg, "-o", target).returncode == 0
    assert target.read_text().startswith("// generated by ybgc") and target.stat().st_mode & 0o777 == 0o640
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]
    r = ybgc_in(tmp_path, "graph", cfg, "-o", tmp_path / "missing" / "g.svg")
    assert r.returncode == 2 and "cannot write" in r.stderr and "Traceback" not in r.stderr


def test_a_config_with_errors_gives_its_diagnostics_not_a_graph(tmp_path):
    bad = ROOT / "tests" / "invalid" / "E313_unknown_converter.ini"
    for args in ([], ["-o", "g.svg"], ["--format", "dot"]):
        r = ybgc_in(tmp_path, "graph", bad, *args)
        assert r.returncode == 1, r.stderr
        assert f"{bad}:9:11: error E313 unknown converter `deg2rad`" in r.stderr
        assert "hint: did you mean `deg_to_rad`?" in r.stderr
        assert r.stdout == "" and list(tmp_path.iterdir()) == []
    r = ybgc_in(tmp_path, "graph", tmp_path / "none.ini")
    assert r.returncode == 2 and "E001" in r.stderr and list(tmp_path.iterdir()) == []
