"""The dataflow of a checked program, as a picture: ``ybgc graph``.

    inputs (ports, topics) --> muxes --> converters --> fields --> output

:func:`build` reads the IR (never the config text) into a :class:`Graph`:
one node a port or topic read, a mux, a converter, a field the config sets,
and the output; an edge wherever data goes. :func:`to_mermaid`,
:func:`to_dot` and :func:`to_svg` print it. The SVG is laid out here, one
column a stage, so that no graph tool is needed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from xml.sax.saxutils import escape

from ybg.compiler import ir

#: the stages, left to right: a node's ``stage`` and the prefix of its id
STAGES = ("input", "mux", "converter", "field", "output")
STAGE_TITLES = {"input": "inputs", "mux": "muxes", "converter": "converters",
                "field": "fields", "output": "output"}
_PREFIX = {"input": "in", "mux": "mux", "converter": "conv", "field": "field", "output": "out"}
#: fill colours of the SVG and DOT boxes
_FILL = {"input": "#dbeafe", "mux": "#dcfce7", "converter": "#ffedd5", "field": "#fef9c3",
         "output": "#ede9fe"}
_DETAIL_MAX = 44


@dataclass(frozen=True)
class Node:
    """``name`` is what the config calls it (port, mux, converter, field
    path); ``detail`` one line about it (types, range, source)."""

    id: str
    stage: str
    name: str
    detail: str = ""


@dataclass(frozen=True)
class Graph:
    """Nodes in stage order, each stage in the config's order; edges as
    ``(from id, to id)``, each once."""

    module: str
    source: str
    nodes: tuple[Node, ...]
    edges: tuple[tuple[str, str], ...]
    #: a robot's graph (:func:`build_robot`): each bridge's module name and
    #: the ids of its nodes (not the inputs, which bridges may share)
    bridges: tuple[tuple[str, tuple[str, ...]], ...] = ()

    def stage(self, stage: str) -> tuple[Node, ...]:
        return tuple(n for n in self.nodes if n.stage == stage)


# --------------------------------------------------------------------------
# The graph of a program


def _short(text: str) -> str:
    return text if len(text) <= _DETAIL_MAX else text[: _DETAIL_MAX - 1] + "…"


def _range(start: int, stop: int | None) -> str:
    return f"[{start}:{'' if stop is None else stop}]"


def _input_detail(inp: ir.Input) -> str:
    kind = {"yarp": "YARP port", "ros1": "ROS 1 topic", "ros2": "ROS 2 topic"}[inp.kind]
    if inp.ros_type:
        kind += f" {inp.ros_type}"
    if inp.layout is None:
        return kind
    return kind + ", " + " ".join(f"{g.type} x{g.count}" for g in inp.layout)


def _value(v) -> str:
    if isinstance(v, str):  # as the config spells it
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, bool):
        return "true" if v else "false"
    return repr(v)


def _source_detail(src) -> str:
    if isinstance(src, ir.MuxRef):
        if src.index is not None:
            text = f"{src.mux}[{src.index}]"
        elif src.start == 0 and src.stop is None:
            text = src.mux
        else:
            text = src.mux + _range(src.start, src.stop)
        if src.into_fields:
            text += " -> " + ", ".join(src.into_fields)
        return "= " + text
    if isinstance(src, ir.Literal):
        values = ", ".join(_value(v) for v in src.values)
        return "= " + (f"[{values}]" if src.is_list else values)
    if isinstance(src, ir.Timestamp):
        return f"= timestamp({src.mux})" if src.mux else "= timestamp"
    if isinstance(src, ir.Counter):
        return "= counter"
    if isinstance(src, ir.Seconds):
        return "= seconds"
    return ""


def _set_fields(struct: ir.Struct, prefix: str = ""):
    """(path, source) of every leaf field the config sets, in message order."""
    for f in struct.fields:
        path = prefix + f.name
        if isinstance(f.source, ir.Struct):
            yield from _set_fields(f.source, path + ".")
        elif not isinstance(f.source, ir.Default):
            yield path, f.source


def _covered(ref: ir.MuxRef, mux: ir.Mux) -> bool:
    """Do the mux's converters cover every element ``ref`` reads?"""
    end = math.inf if mux.width is None else mux.width
    if ref.index is not None:
        start, stop = ref.index, ref.index + 1
    else:
        start, stop = ref.start, end if ref.stop is None else ref.stop
    reached = start
    for c in sorted(mux.converters, key=lambda c: c.start):
        if c.start <= reached:
            reached = max(reached, end if c.stop is None else c.stop)
    return reached >= stop


def _overlaps(ref: ir.MuxRef, conv: ir.Converter) -> bool:
    start = ref.start if ref.index is None else ref.index
    stop = (ref.index + 1) if ref.index is not None else (math.inf if ref.stop is None else ref.stop)
    return conv.start < stop and start < (math.inf if conv.stop is None else conv.stop)


def _adder(nodes: list):
    """``add(stage, name, detail)``: a node appended to ``nodes``, numbered
    by its stage; its id."""
    def add(stage: str, name: str, detail: str) -> str:
        node = Node(f"{_PREFIX[stage]}{sum(n.stage == stage for n in nodes)}", stage, name, _short(detail))
        nodes.append(node)
        return node.id
    return add


def _output_node(program: ir.Program) -> Node:
    out = program.output
    where = {"yarp": "YARP port", "ros1": "ROS 1 topic", "ros2": "ROS 2 topic"}[out.kind]
    what = out.msg_type or "Bottle"
    t = program.timing
    when = f"{t.rate:g} Hz" if t.rate else "on new data"
    return Node("out", "output", out.name, f"{where}, {what}, {when}")


def build(program: ir.Program) -> Graph:
    """The dataflow graph of ``program``."""
    nodes: list[Node] = []
    edges: list[tuple[str, str]] = []

    add = _adder(nodes)

    def edge(a: str, b: str) -> None:
        if (a, b) not in edges:
            edges.append((a, b))

    inputs: dict[tuple[str, str], str] = {}
    for m in program.muxes:
        for inp in m.inputs:
            if (inp.kind, inp.name) not in inputs:
                inputs[(inp.kind, inp.name)] = add("input", inp.name, _input_detail(inp))
    mux_ids: dict[str, str] = {}
    for m in program.muxes:
        mux_ids[m.name] = add("mux", m.name, f"{m.width} elements" if m.width is not None else "width at run time")
        for inp in m.inputs:
            edge(inputs[(inp.kind, inp.name)], mux_ids[m.name])
    conv_ids: dict[tuple[str, int], str] = {}
    for m in program.muxes:
        for k, c in enumerate(m.converters):
            whole = c.start == 0 and c.stop is None
            conv_ids[(m.name, k)] = add("converter", c.name,
                                        "on " + m.name + ("" if whole else _range(c.start, c.stop)))
            edge(mux_ids[m.name], conv_ids[(m.name, k)])
    out = _output_node(program)
    for path, src in _set_fields(program.message):
        fid = add("field", path, _source_detail(src))
        if isinstance(src, ir.MuxRef):
            mux = program.mux(src.mux)
            for k, c in enumerate(mux.converters):
                if _overlaps(src, c):
                    edge(conv_ids[(mux.name, k)], fid)
            if not _covered(src, mux):
                edge(mux_ids[mux.name], fid)
        elif isinstance(src, ir.Timestamp) and src.mux is not None:
            edge(mux_ids[src.mux], fid)
        edge(fid, out.id)
    nodes.append(out)
    return Graph(program.module, program.source, tuple(nodes), tuple(edges))


def _item_text(item: ir.BottleItem) -> str:
    if item.kind == "literal":
        return f'"{item.value}"' if item.type == "string" else f"{item.value}"
    if item.kind == "field":
        name = item.ref.dotted
        return f"{item.converter.name}({name})" if item.converter is not None else name
    if item.kind == "list":
        return "(" + " ".join(_item_text(i) for i in item.items) + ")"
    return "error"


def _fill_text(fill: ir.Fill, bottle: str) -> str:
    if fill.source == "element":
        return f"{bottle}[{fill.start}:{'' if fill.stop is None else fill.stop}]" if fill.slice \
            else f"{bottle}[{fill.start}]"
    if fill.source == "text":
        return f"{bottle} as text"
    return _value(fill.value) if fill.source == "literal" else "error"


def build_commands(program: ir.Commands) -> Graph:
    """The graph of a config of commands: for each, who calls the module, the
    message or Bottle it makes, what it calls, and what the answer fills."""
    nodes: list[Node] = []
    edges: list[tuple[str, str]] = []

    add = _adder(nodes)

    served: dict[str, str] = {}
    for svc in program.services:
        if svc.serves == "ros2":
            caller = add("input", svc.service, f"ROS 2 service served, {svc.srv_type}")
            made = add("mux", f"command {svc.name}", " ".join(_item_text(i) for i in svc.bottle))
            callee = add("output", svc.port, f"YARP RPC port called, within {svc.timeout:g} s")
            bottle = "reply"
        else:
            if svc.port not in served:
                served[svc.port] = add("input", svc.port, "YARP RPC port served")
            caller = served[svc.port]
            made = add("mux", f"command {svc.name}", "request from args")
            callee = add("output", svc.service, f"ROS 2 service called, {svc.srv_type}, within {svc.timeout:g} s")
            bottle = "args"
        edges += [(caller, made), (made, callee)]
        for fill in svc.fills:
            fid = add("field", ("response." if svc.serves == "ros2" else "request.") + fill.ref.dotted,
                      _fill_text(fill, bottle))
            edges += [(callee, fid)] if svc.serves == "ros2" else [(caller, fid), (fid, made)]
    return Graph(program.module, program.source, tuple(nodes), tuple(edges))


def build_actions(program: ir.Actions) -> Graph:
    """The graph of a config of actions: for each, the ROS 2 action served
    and the encoders' port into the goal it carries out, its converters, and
    the port its set points go to."""
    nodes: list[Node] = []
    edges: list[tuple[str, str]] = []

    add = _adder(nodes)

    for a in program.actions:
        served = add("input", a.action, f"ROS 2 action served, {a.action_type}")
        state = add("input", a.state, f"encoders, {a.width} values" if a.width is not None else "encoders")
        goal = add("mux", f"action {a.name}", f"{len(a.joints)} joints: {', '.join(a.joints)}")
        edges += [(served, goal), (state, goal)]
        last = goal
        for c in a.converters:
            conv = add("converter", c.name, "encoders to the goal's units; set points back")
            edges.append((last, conv))
            last = conv
        out = add("output", a.command, f"set points at {a.rate:g} Hz")
        edges.append((last, out))
    return Graph(program.module, program.source, tuple(nodes), tuple(edges))


def build_robot(name: str, source: str, programs) -> Graph:
    """The graph of a robot: the graphs of its bridges side by side, each
    node's id prefixed by its bridge's number, the inputs shared (one box
    for a port or topic that several bridges read), each mux named with
    its bridge's module."""
    nodes: list[Node] = []
    edges: list[tuple[str, str]] = []
    bridges: list[tuple[str, tuple[str, ...]]] = []
    inputs: dict[tuple[str, str], str] = {}  # (name, detail) -> id
    for k, program in enumerate(programs):
        g = _graph_of(program)
        ids: dict[str, str] = {}
        own: list[str] = []
        for n in g.nodes:
            if n.stage == "input":
                key = (n.name, n.detail)
                if key not in inputs:
                    inputs[key] = f"in{len(inputs)}"
                    nodes.append(Node(inputs[key], "input", n.name, n.detail))
                ids[n.id] = inputs[key]
                continue
            ids[n.id] = f"b{k}_{n.id}"
            own.append(ids[n.id])
            nodes.append(Node(ids[n.id], n.stage, f"{g.module}: {n.name}" if n.stage == "mux" else n.name,
                              n.detail))
        edges += [(ids[a], ids[b]) for a, b in g.edges if (ids[a], ids[b]) not in edges]
        bridges.append((g.module, tuple(own)))
    order = {stage: i for i, stage in enumerate(STAGES)}
    nodes.sort(key=lambda n: order[n.stage])  # stable: each stage in the bridges' order
    return Graph(name, source, tuple(nodes), tuple(edges), tuple(bridges))


def _graph_of(program: ir.Bridge) -> Graph:
    return _BUILDERS[program.kind](program)


#: kind of bridge -> its graph
_BUILDERS = {"stream": build, "commands": build_commands, "actions": build_actions}


# --------------------------------------------------------------------------
# Mermaid and DOT


def _mermaid_text(text: str) -> str:
    for ch, entity in (("#", "#35;"), ('"', "#quot;"), ("<", "#lt;"), (">", "#gt;")):
        text = text.replace(ch, entity)
    return text


_MERMAID_SHAPE = {"input": ('(["', '"])'), "mux": ('["', '"]'), "converter": ('{{"', '"}}'),
                  "field": ('["', '"]'), "output": ('[("', '")]')}


def to_mermaid(graph: Graph) -> str:
    """A Mermaid flowchart (GitHub and GitLab render it in Markdown)."""
    lines = ["flowchart LR", f"  %% generated by ybgc from {graph.source}: the dataflow of module {graph.module}"]
    def node(n: Node, indent: str = "  ") -> str:
        left, right = _MERMAID_SHAPE[n.stage]
        label = _mermaid_text(n.name) + (f"<br/><small>{_mermaid_text(n.detail)}</small>" if n.detail else "")
        return f"{indent}{n.id}{left}{label}{right}:::{n.stage}"

    grouped = {i: k for k, (_, ids) in enumerate(graph.bridges) for i in ids}
    lines += [node(n) for n in graph.nodes if n.id not in grouped]
    by_id = {n.id: n for n in graph.nodes}
    for k, (module, ids) in enumerate(graph.bridges):
        lines.append(f'  subgraph bridge{k}["{_mermaid_text(module)}"]')
        lines += [node(by_id[i], "    ") for i in ids]
        lines.append("  end")
    lines += [f"  {a} --> {b}" for a, b in graph.edges]
    lines += [f"  classDef {stage} fill:{_FILL[stage]},stroke:#555" for stage in STAGES]
    return "\n".join(lines) + "\n"


def _dot_text(text: str) -> str:
    return text.replace("\\", "\\\\").replace('"', '\\"').replace("\n", "\\n")


_DOT_SHAPE = {"input": "box", "mux": "box", "converter": "hexagon", "field": "box", "output": "box"}


def to_dot(graph: Graph) -> str:
    """Graphviz DOT text (``dot -Tpng``), one rank a stage."""
    lines = [f"// generated by ybgc from {graph.source}: the dataflow of module {graph.module}",
             f'digraph "{_dot_text(graph.module)}" {{',
             "  rankdir=LR;",
             '  node [fontname="monospace", fontsize=10, style="filled,rounded"];']
    def stages(nodes, indent: str) -> None:
        for stage in STAGES:
            here = [n for n in nodes if n.stage == stage]
            if not here:
                continue
            lines.append(f"{indent}// {STAGE_TITLES[stage]}")
            for n in here:
                label = _dot_text(n.name + ("\n" + n.detail if n.detail else ""))
                lines.append(f'{indent}{n.id} [label="{label}", shape={_DOT_SHAPE[stage]}, '
                             f'fillcolor="{_FILL[stage]}"];')
            lines.append(f"{indent}{{ rank=same; " + " ".join(f"{n.id};" for n in here) + " }")

    grouped = {i for _, ids in graph.bridges for i in ids}
    stages([n for n in graph.nodes if n.id not in grouped], "  ")
    by_id = {n.id: n for n in graph.nodes}
    for k, (module, ids) in enumerate(graph.bridges):  # a robot: a box around each bridge
        lines += [f"  subgraph cluster_bridge{k} {{", f'    label="{_dot_text(module)}";']
        stages([by_id[i] for i in ids], "    ")
        lines.append("  }")
    lines += [f"  {a} -> {b};" for a, b in graph.edges]
    lines.append("}")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------
# SVG: one column a stage, boxes top to bottom in the config's order

_CHAR, _SMALL_CHAR = 7.0, 6.1  # width of a character of the 11.5px and 10px monospace fonts
_BOX_H, _ROW_GAP, _COL_GAP, _PAD, _HEAD = 38, 12, 70, 16, 34


def _box_width(node: Node) -> float:
    return max(len(node.name) * _CHAR, len(node.detail) * _SMALL_CHAR) + 20


def _route(a, b, columns, place) -> list[tuple[float, float]]:
    """The points an edge from box ``a`` to box ``b`` goes through: across
    each column between them, along the free gap nearest its straight line."""
    ax, ay, aw = a
    bx, by, _ = b
    start, end = (ax + aw, ay + _BOX_H / 2), (bx, by + _BOX_H / 2)
    points = [start]
    for col in columns:
        x, _, w = place[col[0].id]
        if not start[0] < x < end[0]:
            continue
        tops = [place[n.id][1] for n in col]
        free = [tops[0] - _ROW_GAP / 2] + [t + _BOX_H + _ROW_GAP / 2 for t in tops]
        along = start[1] + (end[1] - start[1]) * (x + w / 2 - start[0]) / (end[0] - start[0])
        y = min(free, key=lambda f: abs(f - along))
        points += [(x - 6, y), (x + w + 6, y)]
    return points + [end]


def to_svg(graph: Graph) -> str:
    """A standalone SVG picture of ``graph``."""
    columns = [graph.stage(s) for s in STAGES if graph.stage(s)]
    widths = [max(_box_width(n) for n in col) for col in columns]
    heights = [len(col) * _BOX_H + (len(col) - 1) * _ROW_GAP for col in columns]
    inner = max(heights)
    total_w = _PAD * 2 + sum(widths) + _COL_GAP * (len(columns) - 1)
    total_h = _PAD * 2 + _HEAD + inner
    place: dict[str, tuple[float, float, float]] = {}  # id -> x, y, width
    heads = []
    x = _PAD
    for col, width, height in zip(columns, widths, heights):
        heads.append((x + width / 2, STAGE_TITLES[col[0].stage]))
        y = _PAD + _HEAD + (inner - height) / 2
        for n in col:
            place[n.id] = (x, y, width)
            y += _BOX_H + _ROW_GAP
        x += width + _COL_GAP

    out = ['<?xml version="1.0" encoding="UTF-8"?>',
           f'<!-- generated by ybgc from {escape(graph.source.replace("--", "- -"))}: '
           f'the dataflow of module {escape(graph.module)} -->',
           f'<svg xmlns="http://www.w3.org/2000/svg" width="{total_w:.0f}" height="{total_h:.0f}" '
           f'viewBox="0 0 {total_w:.0f} {total_h:.0f}" font-family="DejaVu Sans Mono, Menlo, Consolas, monospace">',
           f"<title>{escape(graph.module)}: dataflow</title>",
           '<defs><marker id="arrow" viewBox="0 0 10 10" refX="10" refY="5" markerWidth="7" '
           'markerHeight="7" orient="auto-start-reverse"><path d="M 0 0 L 10 5 L 0 10 z" fill="#555"/>'
           "</marker></defs>",
           f'<rect width="{total_w:.0f}" height="{total_h:.0f}" fill="white"/>']
    for cx, title in heads:
        out.append(f'<text class="stage" x="{cx:.1f}" y="{_PAD + 14}" text-anchor="middle" font-size="13" '
                   f'font-weight="bold" fill="#333">{escape(title)}</text>')
    out.append('<g class="edges" fill="none" stroke="#555" stroke-width="1.2">')
    for a, b in graph.edges:
        points = _route(place[a], place[b], columns, place)
        d = f"M {points[0][0]:.1f} {points[0][1]:.1f}"
        for (xa, ya), (xb, yb) in zip(points, points[1:]):
            bend = (xb - xa) / 2
            d += f" C {xa + bend:.1f} {ya:.1f}, {xb - bend:.1f} {yb:.1f}, {xb:.1f} {yb:.1f}"
        out.append(f'<path d="{d}" marker-end="url(#arrow)"/>')
    out.append("</g>")
    for n in graph.nodes:
        x, y, w = place[n.id]
        out.append(f'<g class="node {n.stage}" id="{n.id}">')
        out.append(f"<title>{escape(n.name)}{(': ' + escape(n.detail)) if n.detail else ''}</title>")
        out.append(f'<rect x="{x:.1f}" y="{y:.1f}" width="{w:.1f}" height="{_BOX_H}" rx="6" '
                   f'fill="{_FILL[n.stage]}" stroke="#555"/>')
        name_y = y + (15 if n.detail else _BOX_H / 2 + 4)
        out.append(f'<text x="{x + 10:.1f}" y="{name_y:.1f}" font-size="11.5" fill="#111">{escape(n.name)}</text>')
        if n.detail:
            out.append(f'<text class="detail" x="{x + 10:.1f}" y="{y + 30:.1f}" font-size="10" '
                       f'fill="#555">{escape(n.detail)}</text>')
        out.append("</g>")
    out.append("</svg>")
    return "\n".join(out) + "\n"


FORMATS = {"svg": to_svg, "dot": to_dot, "mermaid": to_mermaid}
#: the format a file name's ending asks for
SUFFIXES = {".svg": "svg", ".dot": "dot", ".gv": "dot", ".mmd": "mermaid", ".mermaid": "mermaid"}


def render(program: ir.Program | ir.Commands, fmt: str) -> str:
    """The picture of ``program`` in ``fmt`` (a key of :data:`FORMATS`)."""
    return FORMATS[fmt](_graph_of(program))


def render_robot(name: str, source: str, programs, fmt: str) -> str:
    """The picture of a robot's bridges ``programs`` (:func:`build_robot`)."""
    return FORMATS[fmt](build_robot(name, source, programs))
