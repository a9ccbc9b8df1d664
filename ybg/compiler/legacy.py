"""Stage 2 (legacy form): the original tool's ``[general]``/``[muxN]``/
``num_fields`` document -> the equivalent named-form document.

What each legacy key meant is in ``docs/config.md`` ("The legacy form"). The
checks that only make sense in the legacy form (``num_mux``, ``num_ports``,
``num_fields``, ``N_type`` keys, nested sections) are made here; everything
else (types, names, widths) is left to the checker of the named form
(``check.py``), which sees the spans of the legacy lines. The same conversion prints ``ybgc fmt --to
named``.
"""

from __future__ import annotations

import re

from ybg.compiler import ast
from ybg.compiler.diagnostics import Sink, Span, did_you_mean
from ybg.compiler.ir import INTEGER_TYPES
from ybg.compiler.msgtypes import MsgDef, TypeStore
from ybg.compiler.names import converted_name
from ybg.compiler.values import check_keys

GENERAL_KEYS = ("output_name", "to_ros", "num_mux", "rate", "ros_msg_name", "from_ros_topics")
MUX_KEYS = ("num_ports", "ports", "function", "verbose")
FIELD_TYPES = ("single_value", "list", "mux", "counter", "timestamp", "msg")
_FIELD_KEY = re.compile(r"([0-9]+)_(type|msg|mux)\Z")
_MUX_SECTION = re.compile(r"mux([0-9]+)\Z")
_CONVERTER_SECTION = re.compile(r"converter([0-9]*)\Z")
_MUX_REF = re.compile(r"[0-9]+_mux\Z")


def is_legacy(doc: ast.Document) -> bool:
    """A legacy document has `[general]` or `[muxN]` sections or `num_fields`,
    or is in one of the original's first layouts (:func:`early_layout`)."""
    for s in doc.sections:
        if s.label is None and (s.name == "general" or _MUX_SECTION.match(s.name)):
            return True
        if s.name == "message" and s.get("num_fields") is not None:
            return True
    return early_layout(doc) is not None


def is_named(doc: ast.Document) -> bool:
    return any(s.name in ("output", "module") or (s.name == "mux" and s.label) for s in doc.sections)


def early_layout(doc: ast.Document) -> ast.Section | None:
    """The first section that puts ``doc`` in one of the original tool's
    first layouts (February to May 2015): `[mux_general]`, a
    `[converterN]` beside each `[muxN]`, or one unnumbered `[mux]` (with
    its `[converter]`); None for any other document. A document with a
    section of the named form is not one (an unnumbered `[mux]` there is a
    named mux without its name)."""
    if is_named(doc):
        return None
    for sec in doc.sections:
        if sec.label is None and (sec.name in ("mux_general", "mux") or _CONVERTER_SECTION.match(sec.name)):
            return sec
    return None


def _int(e: ast.Entry | None, sink: Sink) -> int | None:
    if e is None:
        return None
    if len(e.items) == 1 and isinstance(e.items[0], ast.Word):
        n = e.items[0].number()
        if isinstance(n, int) and n >= 0:
            return n
    sink.error("E208", f"`{e.key}` takes a whole number", e.span)
    return None


def _bool(e: ast.Entry | None, sink: Sink, default: bool = False) -> bool:
    if e is None:
        return default
    if len(e.items) == 1 and isinstance(e.items[0], ast.Word):
        b = e.items[0].boolean()
        if b is not None:
            return b
    sink.error("E208", f"`{e.key}` takes true or false", e.span)
    return default


def _name(e: ast.Entry, sink: Sink) -> str | None:
    if len(e.items) == 1 and isinstance(e.items[0], (ast.Word, ast.Str)):
        it = e.items[0]
        return it.text if isinstance(it, ast.Word) else it.value
    sink.error("E208", f"`{e.key}` takes one name", e.span)
    return None


def _entry(key: str, items, span: Span, key_span: Span | None = None) -> ast.Entry:
    return ast.Entry(key, tuple(items), span, key_span or span)


def _word(text: str, span: Span) -> ast.Word:
    return ast.Word(text, span)


class LegacyConverter:
    """Converts one legacy document. ``store`` is the ROS 1 type store (the
    original tool targeted YARP's ROS 1 bridge). ``target`` ``"ros2"``
    rewrites the output for ROS 2 (dropping ``header.seq``)."""

    def __init__(self, doc: ast.Document, sink: Sink, store: TypeStore, module: str,
                 target_store: TypeStore | None = None):
        self.doc = doc
        self.sink = sink
        self.store = store
        self.module = module
        self.target_store = target_store
        self.dropped: list[str] = []
        self.general_made = False  # [general] made from an early layout's sections
        self.general_title = "general"  # the section that holds [general]'s keys, as the file names it
        self.early_read: tuple[str, Span] | None = None  # W512, said once the conversion is done

    def convert(self) -> ast.Document:
        s = self.sink
        doc = self.doc
        for e in doc.loose:
            s.error("E107", f"`{e.key}` is not inside a section", e.key_span, "put it under `[general]`")
        by_name: dict[str, ast.Section] = {}
        named: list[ast.Section] = []  # sections of the named form, mixed in (E207): carried over
        for sec in doc.sections:
            if sec.label is not None or sec.name in ("output", "module"):
                named.append(sec)
                continue
            if sec.name in by_name:
                s.error("E205", f"[{sec.name}] is given twice", sec.span,
                        f"first given on line {by_name[sec.name].span.line}")
                continue
            by_name[sec.name] = sec
        early = early_layout(doc)
        if early is not None:
            errors = sum(d.severity.value == "error" for d in s.items)
            by_name = self.from_early(by_name, early)
            if by_name is None:
                return ast.Document(())
            named_doc = self.convert_lasting(by_name, named, early)
            message, span = self.early_read
            command = f"`ybgc fmt --to named FILE -o {converted_name(s.file)}`"
            if sum(d.severity.value == "error" for d in s.items) > errors:
                hint = f"once the errors of its conversion are fixed, {command} converts it to the named form"
            else:
                hint = f"{command} converts it to the named form"
            s.warning("W512", message, span, hint)
            return named_doc
        return self.convert_lasting(by_name, named, None)

    def convert_lasting(self, by_name: dict[str, ast.Section], named: list[ast.Section],
                        early: ast.Section | None) -> ast.Document:
        """The named form of the sections of a file in the original's lasting
        layout (``early``: the first section of the early layout they were
        read from), and the ``named`` sections mixed in, carried over."""
        s = self.sink
        gen = by_name.get("general")
        if gen is None:
            s.error("E203", "missing section [general]", None,
                    "a legacy file starts with [general]: output_name, to_ros, num_mux, rate")
            return ast.Document(())
        if early is None:
            s.note("N601", "legacy form", gen.span,
                   f"`ybgc fmt --to named FILE -o {converted_name(s.file)}` converts it to the named form")
        g = check_keys(gen, GENERAL_KEYS, s)
        for req in ("output_name", "num_mux"):
            if req not in g and not _misspelt(gen, req, GENERAL_KEYS):
                s.error("E204", f"[{self.general_title}] needs `{req}`", gen.span)
        to_ros = _bool(g.get("to_ros"), s)
        from_ros = _bool(g.get("from_ros_topics"), s)
        num_mux = _int(g.get("num_mux"), s)

        # muxes
        mux_secs = {int(m.group(1)): sec for sec in by_name.values() if (m := _MUX_SECTION.match(sec.name))}
        if num_mux is not None:
            present = sorted(mux_secs)
            if present != list(range(1, num_mux + 1)):
                extra = [k for k in present if k > num_mux or k < 1]
                missing = [k for k in range(1, num_mux + 1) if k not in mux_secs]
                if missing:
                    s.error("E209", f"num_mux = {num_mux}, but [{', '.join(f'mux{k}' for k in missing)}] "
                            f"{'is' if len(missing) == 1 else 'are'} missing", g["num_mux"].span,
                            f"sections present: {', '.join(f'mux{k}' for k in present) or 'none'}")
                if extra:
                    s.error("E209", f"num_mux = {num_mux}, but there is also "
                            f"[{', '.join(f'mux{k}' for k in extra)}]", g["num_mux"].span,
                            f"set `num_mux = {max(present)}`" if present else None)
        out_sections: list[ast.Section] = []
        given_module = next((sec for sec in named if sec.name == "module" and sec.label is None), None)
        module_entries = [] if given_module is not None and given_module.get("name") is not None \
            else [_entry("name", [_word(self.module, gen.span)], gen.span)]
        if given_module is not None:
            module_entries += given_module.entries
        out_sections.append(ast.Section("module", None, tuple(module_entries), gen.span))

        # output
        out: list[ast.Entry] = []
        oname = g.get("output_name")
        msgdef: MsgDef | None = None
        type_name: str | None = None
        if oname is not None:
            name = _name(oname, s)
            if to_ros:
                out.append(_entry("topic", [_word(name or "", oname.items[0].span if oname.items else oname.span)], oname.span, oname.key_span))
                out.append(_entry("via", [_word("ros1", g["to_ros"].span)], g["to_ros"].span, g["to_ros"].key_span))
            elif from_ros:
                port = f"/{self.module}/out:o"
                out.append(_entry("port", [_word(port, oname.span)], oname.span, oname.key_span))
                out.append(_entry("connect", [_word(name or "", oname.items[0].span if oname.items else oname.span)], oname.span, oname.key_span))
            else:
                out.append(_entry("port", [_word(name or "", oname.items[0].span if oname.items else oname.span)], oname.span, oname.key_span))
                if "to_ros" not in g:
                    s.warning("W508", f"no `to_ros` in [general]: `{name}` is taken as a YARP port, written with "
                              "Bottles; the first versions of the original tool, which had no `to_ros`, always "
                              "published it as a ROS topic", oname.key_span,
                              "add `to_ros = true` (and `ros_msg_name = pkg/Name`) to publish the ROS topic as "
                              "they did, or `to_ros = false` to keep the YARP port")
            if to_ros:
                type_name, msgdef = self.message_type(g, name or "", by_name.get("message"), by_name)
                if type_name is not None:
                    te = g.get("ros_msg_name")
                    span = te.span if te else gen.span
                    out.append(_entry("type", [_word(type_name, te.items[0].span if te and te.items else span)], span,
                                      te.key_span if te else span))
                if self.target_store is not None:
                    self.ros2_needs_type(name or "", oname, type_name, msgdef, g.get("ros_msg_name"))
            elif "ros_msg_name" in g:
                s.warning("W506", "`ros_msg_name` has no effect with `to_ros = false`", g["ros_msg_name"].key_span,
                          "remove it, or set `to_ros = true`")
        else:  # reported (E204, or E202 for a misspelling); the rest is still checked, without a follow-on
            out.append(_entry("port", [_word(f"/{self.module}/out:o", gen.span)], gen.span))
        if "rate" in g:
            out.append(_entry("rate", g["rate"].items, g["rate"].span, g["rate"].key_span))
        elif early is None:  # the first layouts had no `rate`: W512 says so
            s.warning("W504", "no `rate` in [general]: the module publishes whenever new data arrives", gen.span,
                      "add `rate = 30` (Hz) for a fixed rate")
        # the keys of an [output] of the named form mixed in are kept, after those converted: one given
        # both ways is then given twice (E206), for the user to choose, never dropped
        for sec in named:
            if sec.name == "output" and sec.label is None:
                out.extend(sec.entries)
        out_sections.append(ast.Section("output", None, tuple(out), gen.span))

        used_sections = {"general", "message"} | {f"mux{k}" for k in mux_secs}
        for k in sorted(mux_secs):
            sec = mux_secs[k]
            conv = self.mux(sec, from_ros)
            if conv is not None:
                out_sections.append(conv)
        out_sections += [sec for sec in named if sec.name not in ("output", "module") or sec.label is not None]

        # message
        msg = by_name.get("message")
        if msg is None:
            s.error("E203", "missing section [message]", None, "it lists the fields: `num_fields = N`, `1_type = ...`")
        else:
            entries = self.fields(msg, msgdef, (), by_name, used_sections, set(), typed=to_ros)
            if self.target_store is not None:
                entries = self.retarget(entries, type_name)
            out_sections.append(ast.Section("message", None, tuple(entries), msg.span))
        for sec in by_name.values():
            if sec.name not in used_sections:
                if _MUX_SECTION.match(sec.name):
                    continue  # reported with num_mux
                s.error("E201", f"section [{sec.name}] is not used", sec.span,
                        "a legacy file has [general], [mux1]..[muxN], [message] and the sections "
                        "named by `N_msg` of `msg` fields")
        return ast.Document(tuple(out_sections))

    def from_early(self, by_name: dict[str, ast.Section], first: ast.Section) -> dict[str, ast.Section] | None:
        """The sections of a document in one of the original's first layouts
        (``first`` is its first section of that layout), as its later
        layout has them: the keys of [mux_general] (`num_mux`,
        `output_name`) in [general], the `function` and `verbose` of
        [converterN] in [muxN], the unnumbered [mux] as [mux1] (its
        `output_name` in [general], `N_mux = mux` as `mux1`), and
        `to_ros = true`, since those versions always published a ROS topic;
        W512 says so once the conversion is done. None, with E217, when the
        file has no [message] that the original read (`num_fields` and its
        fields): in its first weeks it wrote no message, and [message] and
        [type] were notes in a notation it never read."""
        s = self.sink
        one = by_name.get("mux")  # the first layout's one mux
        what = _EARLY_LAYOUTS["mux" if one is not None else "mux_general" if "mux_general" in by_name else "converter"]
        msg = by_name.get("message")
        if msg is None or msg.get("num_fields") is None:
            notes = "type" in by_name or (msg is not None and any(re.fullmatch(r"[0-9]+_message", e.key)
                                                                  for e in msg.entries))
            if msg is None:
                problem = "this file has none: the original wrote no message yet"
            elif notes:
                problem = ("this one is in the notation of those weeks (`N_message`, `single`, `mutex`, the "
                           "count in [type]), which the original never read: it wrote no message yet")
            else:
                problem = "this one has no `num_fields`"
            steps = ["write [message] as the original's later versions read it: `num_fields = N`, then for each "
                     "field `N_type = single_value|list|mux|counter|timestamp|msg` with its `N_msg` (or `N_mux`)"]
            if notes:
                steps.append("from the notes: `num_fields` from [type] (then remove [type]), `N_msg` for `N_message`, "
                             "`single_value` for `single`, `mux` with `N_mux` naming the mux for `mutex`, `list` with "
                             "an empty `N_msg =` for `empty_list`")
            where = [sec for sec in (one, by_name.get("mux_general"), by_name.get("general")) if sec is not None]
            if not any(sec.get("output_name") is not None for sec in where):
                steps.append(f"give the topic it publishes, `output_name = /topic` in [{where[0].name}]"
                             if where else "give the topic it publishes, `output_name = /topic` in [general]")
            s.error("E217", f"{what}, which ybgc reads only with a [message] that the original read "
                    f"(`num_fields` and its fields), and {problem}", first.span,
                    "; ".join(steps) + "; ybgc then reads the file")
            return None

        general = by_name.get("general")
        mux_general = by_name.get("mux_general")
        if general is None and mux_general is None and one is None:
            s.error("E203", "missing section [general]", None,
                    "a legacy file starts with [general]: output_name, to_ros, num_mux, rate")
            return None
        self.general_made = general is None
        self.general_title = "general" if general is not None else "mux_general" if mux_general is not None else "mux"
        gen_entries: list[ast.Entry] = list(general.entries) if general is not None else []

        def to_general(e: ast.Entry, where: str) -> None:
            given = next((g for g in gen_entries if g.key == e.key), None)
            if given is not None:
                s.error("E206", f"`{e.key}` is given twice, in [{where}] and on line {given.span.line}", e.key_span,
                        "keep one of them")
            else:
                gen_entries.append(e)

        moved = []
        if mux_general is not None:
            moved.append("[mux_general]'s keys in [general]")
            for e in mux_general.entries:
                if e.key in GENERAL_KEYS:
                    to_general(e, "mux_general")
                else:
                    s.error("E202", f"unknown key `{e.key}` in [mux_general]", e.key_span,
                            did_you_mean(e.key, GENERAL_KEYS) or f"keys of [mux_general]: {', '.join(GENERAL_KEYS)}")
        muxes = {int(m.group(1)): list(sec.entries) for sec in by_name.values() if (m := _MUX_SECTION.match(sec.name))}
        if one is not None:
            moved.append("[mux] as [mux1]" + (", with its [converter]" if "converter" in by_name else ""))
            if 1 in muxes:
                s.error("E205", "[mux] and [mux1] are both given: the one mux of the first layout is [mux1]",
                        one.span, "remove one of them, or number [mux] as the next free [muxN]")
            else:
                muxes[1] = []
                for e in one.entries:
                    if e.key in GENERAL_KEYS:  # the first layout's [mux] held `output_name` too
                        to_general(e, "mux")
                    else:
                        muxes[1].append(e)
                if not any(g.key == "num_mux" for g in gen_entries):
                    gen_entries.append(_entry("num_mux", [_word("1", one.span)], one.span))
        converters = [(sec, m.group(1)) for sec in by_name.values() if (m := _CONVERTER_SECTION.match(sec.name))]
        if any(number for _, number in converters):
            moved.append("each [converterN]'s `function` and `verbose` in [muxN]")
        for sec, number in converters:
            k = int(number) if number else 1 if one is not None else None
            if k not in muxes:
                s.error("E201", f"[{sec.name}] is not used: it converts [mux{number}], which is not there"
                        if number else "[converter] is not used: it converts the one unnumbered [mux], which is "
                        "not there", sec.span, "remove it, or give the mux it converts")
                continue
            for e in sec.entries:
                if e.key not in ("function", "verbose"):
                    s.error("E202", f"unknown key `{e.key}` in [{sec.name}]", e.key_span,
                            did_you_mean(e.key, ("function", "verbose")) or f"[{sec.name}] holds `function` and "
                            "`verbose`")
                elif any(x.key == e.key for x in muxes[k]):
                    s.error("E206", f"`{e.key}` is given twice, in [{sec.name}] and in [mux{k}]", e.key_span,
                            "keep one of them")
                else:
                    muxes[k].append(e)
        output = next((g for g in gen_entries if g.key == "output_name"), None)
        topic = ros = None
        if not any(g.key in ("to_ros", "from_ros_topics") for g in gen_entries):
            span = output.span if output is not None else first.span
            gen_entries.append(_entry("to_ros", [_word("true", span)], span, output.key_span if output else span))
            topic = f"the ROS 1 topic `{_plain(output)}`" if output is not None and _plain(output) else "a ROS 1 topic"
        if not any(g.key == "rate" for g in gen_entries):
            ros = "whenever its inputs deliver"
        missing = " nor ".join(f"`{k}`" for k, made in (("to_ros", topic), ("rate", ros)) if made)
        said = f"; the module publishes {' '.join(x for x in (topic, ros) if x)}, as those versions did " \
               f"(they had {'neither ' if topic and ros else 'no '}{missing})" if missing else ""
        self.early_read = (f"{what}: read as its later layout ({'; '.join(moved)}){said}", first.span)

        out: dict[str, ast.Section] = {}
        gen_span = general.span if general is not None else first.span
        out["general"] = ast.Section("general", None, tuple(gen_entries), gen_span)
        for name, sec in by_name.items():
            if name in ("general", "mux_general", "mux") or _CONVERTER_SECTION.match(name):
                if name == "mux" and 1 in muxes:
                    out["mux1"] = ast.Section("mux1", None, tuple(muxes[1]), sec.span)
                continue
            if (m := _MUX_SECTION.match(name)) is not None:
                out[name] = ast.Section(name, None, tuple(muxes[int(m.group(1))]), sec.span)
            elif one is not None:  # fields name the one mux `mux`: now `mux1`
                out[name] = ast.Section(name, None, tuple(
                    _entry(e.key, [_word("mux1", e.items[0].span)], e.span, e.key_span)
                    if _MUX_REF.match(e.key) and _plain(e) == "mux" else e for e in sec.entries), sec.span)
            else:
                out[name] = sec
        return out

    def message_type(self, g, topic: str, msg_sec: ast.Section | None, by_name: dict[str, ast.Section]):
        s = self.sink
        te = g.get("ros_msg_name")
        if te is None:
            # the thesis' own figure 5 and the first versions' configs have none: infer it from the
            # topic name (`/yarp/joint_states`, `/head_joint_states`) when the fields agree with it
            fitting = self.inferred_types(topic, msg_sec, by_name)
            n = _int(msg_sec.get("num_fields"), Sink()) if fitting else None
            if len(fitting) == 1:
                s.warning("W505", f"no `ros_msg_name`: taken as `{fitting[0]}` from the topic name "
                          f"and the {n} fields", g["output_name"].span,
                          f"add `ros_msg_name = {fitting[0]}` to [{self.general_title}]")
                return fitting[0], self.store.resolve(fitting[0])
            s.warning("W503", "no `ros_msg_name`: the message fields are not checked", g["output_name"].span,
                      f"add `ros_msg_name = pkg/Name` to [{self.general_title}], e.g. `sensor_msgs/JointState`")
            return None, None
        text = _name(te, s)
        if text is None:
            return None, None
        if "/" not in text:
            cands = self.store.candidates(text)
            if len(cands) == 1:
                s.warning("W502", f"message type `{text}` given without its package: taken as `{cands[0]}`",
                          te.items[0].span, f"write `ros_msg_name = {cands[0]}`")
                return cands[0], self.store.resolve(cands[0])
            return text, None
        d = self.store.resolve(text)
        return text, d

    def ros2_needs_type(self, topic: str, oname: ast.Entry, type_name: str | None, msgdef: MsgDef | None,
                        te: ast.Entry | None) -> None:
        """Retargeted to ROS 2, the output is built field by field, named from
        its definition, while the legacy fields are matched by position: the
        conversion needs the type and its definition. E204 when the file
        gives no type (and none is inferred), E321 when its definition is not
        found; nothing is written."""
        if type_name is None:
            self.sink.error("E204", f"the ROS 1 topic `{topic}` would be published on ROS 2, which needs its message "
                            "type: this file gives none, and its topic name and fields do not tell it", oname.span,
                            f"add `ros_msg_name = pkg/Name` to [{self.general_title}] (e.g. `sensor_msgs/JointState`), "
                            "then convert it again")
        elif msgdef is None:
            self.sink.error("E321", f"the definition of `{type_name}` was not found: on ROS 2 the message is built "
                            "field by field, named from its definition, and the legacy fields are matched to them "
                            "by position", te.items[0].span if te is not None and te.items else oname.span,
                            "give the folder of its .msg files (DIR/<pkg>/msg/<Name>.msg) to the conversion with "
                            "`--msg-path DIR`, or write the type with its package")

    def inferred_types(self, topic: str, msg_sec: ast.Section | None,
                       by_name: dict[str, ast.Section]) -> list[str]:
        """The message types that the last part of ``topic`` names
        (`joint_states`: `JointStates`, `JointState`), or a tail of it
        (`head_joint_states`: `HeadJointStates`, then `JointStates`, ...),
        whose fields the legacy fields of ``msg_sec`` fit; those of the
        longest tail that names any such type."""
        if msg_sec is None or msg_sec.get("num_fields") is None:
            return []
        words = [w for w in re.split(r"[_\W]+", topic.rstrip("/").rsplit("/", 1)[-1]) if w]
        for i in range(len(words)):
            guess = "".join(w[:1].upper() + w[1:] for w in words[i:])
            cands = self.store.candidates(guess) + (self.store.candidates(guess[:-1]) if guess.endswith("s") else [])
            fitting = [c for c in dict.fromkeys(cands)
                       if (d := self.store.resolve(c)) is not None and self.fits(d, msg_sec, by_name, set())]
            if fitting:
                return fitting
        return []

    def fits(self, d: MsgDef, sec: ast.Section, by_name: dict[str, ast.Section], seen: set[str]) -> bool:
        """Do the legacy fields of ``sec`` fit message ``d``: as many, each of
        a kind its field can take (a `msg` a nested message whose own fields
        fit, a `list` an array, a `counter` an integer, a `timestamp` a
        time, a `single_value` one value)?"""
        n = sec.get("num_fields")
        if n is None or _int(n, Sink()) != len(d.fields):
            return False
        for i, f in enumerate(d.fields, 1):
            te = sec.get(f"{i}_type")
            kind = _plain(te) if te is not None else None
            t = f.type
            if kind == "msg":
                if not t.is_message or t.array is not None:
                    return False
                target = _plain(sec.get(f"{i}_msg")) if sec.get(f"{i}_msg") is not None else None
                sub, sub_def = by_name.get(target or ""), self.store.resolve(t.base)
                if sub is not None and sub_def is not None and target not in seen \
                        and not self.fits(sub_def, sub, by_name, seen | {target}):
                    return False
            elif kind == "list" and t.array is None:
                return False
            elif kind == "counter" and (t.array is not None or t.base not in INTEGER_TYPES):
                return False
            elif kind == "timestamp" and (t.array is not None or t.base != "time"):
                return False
            elif kind == "single_value" and (t.array is not None or t.is_message):
                return False
        return True

    def mux(self, sec: ast.Section, from_ros: bool) -> ast.Section | None:
        s = self.sink
        keys = check_keys(sec, MUX_KEYS, s)
        name = sec.name
        if "ports" not in keys:
            if not _misspelt(sec, "ports", MUX_KEYS):
                s.error("E204", f"[{name}] needs `ports`", sec.span)
            return None
        ports = keys["ports"]
        if ports.trailing_comma is not None and ports.items:
            last = ports.items[-1]
            port = last.text if isinstance(last, ast.Word) else getattr(last, "value", "")
            s.warning("W509", f"a comma after the last port: the original tool read `{port},`, comma included, "
                      "as the name of a port, and waited for it forever; ybgc reads the port "
                      f"`{port}`", ports.trailing_comma,
                      "remove the comma (`ybgc fmt` does), so that the original and ybgc read the same port")
        n = _int(keys.get("num_ports"), s)
        if "num_ports" not in keys:
            if not _misspelt(sec, "num_ports", MUX_KEYS):
                s.error("E204", f"[{name}] needs `num_ports`", sec.span)
        elif n is not None and n != len(ports.items):
            s.error("E209", f"num_ports = {n}, but `ports` lists {len(ports.items)}", keys["num_ports"].span,
                    f"set `num_ports = {len(ports.items)}`")
        entries = [_entry("topics" if from_ros else "ports", ports.items, ports.span, ports.key_span)]
        if from_ros:
            entries.append(_entry("via", [_word("ros1", ports.span)], ports.span))
        if "function" in keys:
            f = keys["function"]
            entries.append(_entry("convert", f.items, f.span, f.key_span))
        if "verbose" in keys:
            v = keys["verbose"]
            entries.append(_entry("verbose", v.items, v.span, v.key_span))
        return ast.Section("mux", name, tuple(entries), sec.span)

    def fields(self, sec: ast.Section, msgdef: MsgDef | None, prefix: tuple[str, ...],
               by_name, used: set[str], stack: set[str], typed: bool) -> list[ast.Entry]:
        s = self.sink
        keys = check_keys(sec, ("num_fields",), s, extra=lambda k: bool(_FIELD_KEY.match(k)))
        if "num_fields" not in keys:
            if not _misspelt(sec, "num_fields", ("num_fields",)):
                s.error("E204", f"[{sec.name}] needs `num_fields`", sec.span)
            _mark_nested(keys, by_name, used)
            return []
        n = _int(keys["num_fields"], s)
        if n is None:
            _mark_nested(keys, by_name, used)
            return []
        numbers = {int(m.group(1)) for k in keys if (m := _FIELD_KEY.match(k))}
        for k in sorted(numbers):
            if k < 1 or k > n:
                key = next(e for kk, e in keys.items() if (m := _FIELD_KEY.match(kk)) and int(m.group(1)) == k)
                s.error("E209", f"field {k} is beyond num_fields = {n}", key.key_span,
                        f"set `num_fields = {max(numbers)}`, or remove the field")
        if msgdef is not None and len(msgdef.fields) != n:
            names = ", ".join(f.name for f in msgdef.fields)
            s.error("E303", f"`{msgdef.name}` has {len(msgdef.fields)} fields ({names}), "
                    f"[{sec.name}] declares {n}", keys["num_fields"].span,
                    "fields are matched to the message by position: one `N_type` per field, in order")
            _mark_nested(keys, by_name, used)
            return []
        out: list[ast.Entry] = []
        for i in range(1, n + 1):
            te = keys.get(f"{i}_type")
            if te is None:
                if not _misspelt(sec, f"{i}_type", ()):
                    s.error("E210", f"field {i} has no `{i}_type`", keys["num_fields"].span,
                            f"add `{i}_type = single_value|list|mux|counter|timestamp|msg`")
                _mark_nested({k: e for k, e in keys.items() if k == f"{i}_msg"}, by_name, used)
                continue
            kind = _name(te, s)
            if kind not in FIELD_TYPES:
                s.error("E210", f"unknown field type `{kind}`", te.items[0].span if te.items else te.span,
                        did_you_mean(kind or "", FIELD_TYPES) or f"types: {', '.join(FIELD_TYPES)}")
                _mark_nested({k: e for k, e in keys.items() if k == f"{i}_msg"}, by_name, used)
                continue
            fdef = msgdef.fields[i - 1] if msgdef is not None else None
            label = fdef.name if fdef is not None else f"field{i}"
            key = ".".join(prefix + (label,))
            extra_key = f"{i}_mux" if kind == "mux" else f"{i}_msg"
            xe = keys.get(extra_key)
            for other in ("msg", "mux"):
                oe = keys.get(f"{i}_{other}")
                if oe is not None and (kind in ("counter", "timestamp") or f"{i}_{other}" != extra_key):
                    s.warning("W506", f"`{i}_{other}` has no effect on a `{kind}` field", oe.key_span)
            span = te.span if xe is None else Span(te.span.line, te.span.column, xe.span.end_line, xe.span.end_column)
            kspan = te.key_span
            if kind in ("single_value", "list", "mux", "msg") and xe is None:
                s.error("E210", f"field {i} is `{kind}` but has no `{extra_key}`", te.span,
                        f"add `{extra_key} = ...`")
                continue
            if kind == "counter":
                out.append(_entry(key, [_word("counter", te.items[0].span)], span, kspan))
            elif kind == "timestamp":
                if typed:
                    out.append(_entry(key, [_word("timestamp", te.items[0].span)], span, kspan))
                else:  # the original wrote (counter time) into YARP Bottles
                    sp = te.items[0].span
                    out.append(_entry(key, [ast.Bracket((_word("counter", sp), _word("time", sp)), sp)], span, kspan))
            elif kind == "single_value":
                if len(xe.items) != 1:
                    s.error("E210", f"`{extra_key}` of a single_value holds one value, not {len(xe.items) or 'none'}",
                            xe.span, f"use `{i}_type = list` for a list")
                    continue
                out.append(_entry(key, xe.items, span, kspan))
            elif kind == "list":
                items = xe.items
                if typed:
                    value = (ast.Bracket(items, xe.span),) if len(items) <= 1 else items
                else:
                    value = (ast.Bracket(items, xe.span),)
                out.append(_entry(key, value, span, kspan))
            elif kind == "mux":
                mname = _name(xe, s)
                if mname is None:
                    continue
                out.append(_entry(key, [_word(mname, xe.items[0].span)], span, kspan))
            elif kind == "msg":
                target = _name(xe, s)
                if target is None:
                    continue
                sub = by_name.get(target)
                if sub is None:
                    s.error("E211", f"field {i} is a nested message from section [{target}], which is missing",
                            xe.items[0].span, did_you_mean(target, by_name) or f"add `[{target}]` with `num_fields`")
                    continue
                if target in stack or target in ("general", "message"):
                    s.error("E211", f"section [{target}] cannot nest itself", xe.items[0].span)
                    continue
                used.add(target)
                sub_def = None
                if fdef is not None:
                    if not fdef.type.is_message or fdef.type.array is not None:
                        s.error("E308", f"field {i} is a nested message, but `{msgdef.name}.{fdef.name}` "
                                f"is {fdef.type}", te.items[0].span)
                        continue
                    sub_def = self.store.resolve(fdef.type.base)
                sublabel = label if fdef is not None else target
                out.extend(self.fields(sub, sub_def, prefix + (sublabel,), by_name, used, stack | {target}, typed))
        return out

    def retarget(self, entries: list[ast.Entry], type_name: str | None) -> list[ast.Entry]:
        """Drop the fields that ROS 2 does not have (the header's seq)."""
        out = []
        store = self.target_store
        assert store is not None
        name = type_name
        if name and "/" not in name:
            c = store.candidates(name)
            name = c[0] if len(c) == 1 else name
        d = store.resolve(name) if name else None
        for e in entries:
            if d is not None and not _path_exists(store, d, e.key.split(".")):
                self.dropped.append(e.key)
                continue
            out.append(e)
        return out


#: how W512 and E217 name each of the original's first layouts
_EARLY_LAYOUTS = {
    "mux": "one unnumbered [mux] is the original tool's first layout (February to March 2015)",
    "mux_general": "[mux_general] is from the original tool's layout of March to May 2015",
    "converter": "[converterN] beside [muxN] is from the original tool's layout of March to May 2015",
}


def _plain(e: ast.Entry) -> str | None:
    """The one word or string of ``e``, or None."""
    if len(e.items) == 1 and isinstance(e.items[0], (ast.Word, ast.Str)):
        it = e.items[0]
        return it.text if isinstance(it, ast.Word) else it.value
    return None


def _misspelt(sec: ast.Section, key: str, allowed: tuple[str, ...]) -> bool:
    """Does ``sec`` hold a misspelling of ``key``, a key of none of the
    ``allowed`` or field keys, already reported by check_keys (E202)? Then
    the missing ``key`` is not reported again."""
    return any(e.key != key and e.key not in allowed and not _FIELD_KEY.match(e.key)
               and did_you_mean(e.key, (key,)) for e in sec.entries)


def _mark_nested(keys: dict[str, ast.Entry], by_name: dict[str, ast.Section], used: set[str]) -> None:
    """The sections that the `N_msg` keys of a section whose fields are not
    read name, and theirs: still in use, so not reported as unused (E201)."""
    for k, e in keys.items():
        if not k.endswith("_msg") or len(e.items) != 1 or not isinstance(e.items[0], ast.Word):
            continue
        name = e.items[0].text
        sub = by_name.get(name)
        if name in used or sub is None or name in ("general", "message"):
            continue
        used.add(name)
        _mark_nested({x.key: x for x in sub.entries}, by_name, used)


def _path_exists(store: TypeStore, d: MsgDef, path: list[str]) -> bool:
    cur: MsgDef | None = d
    for p in path:
        if cur is None:
            return True  # cannot tell: keep it
        f = cur.field(p)
        if f is None:
            return False
        cur = store.resolve(f.type.base) if f.type.is_message else None
    return True


def to_named(doc: ast.Document, sink: Sink, store: TypeStore, module: str,
             target_store: TypeStore | None = None) -> tuple[ast.Document, list[str]]:
    """The named-form equivalent of a legacy document, and the keys dropped
    when retargeting to ROS 2 (``target_store``)."""
    conv = LegacyConverter(doc, sink, store, module, target_store)
    named = conv.convert()
    if target_store is not None:
        named = _retarget(named, sink)
    return named, conv.dropped


def _is_ros1(e: ast.Entry) -> bool:
    return e.key == "via" and len(e.items) == 1 and isinstance(e.items[0], ast.Word) and e.items[0].text == "ros1"


def _retarget(doc: ast.Document, sink: Sink) -> ast.Document:
    """``doc`` on ROS 2: its output, and the topics its muxes read. A ROS 2
    topic needs its message type, which a ROS 1 topic of the legacy form
    does not give (the original read any message as a Bottle): E319 for
    each such topic, with the way to give it."""
    secs = []
    for sec in doc.sections:
        ros1 = next((e for e in sec.entries if _is_ros1(e)), None)
        if sec.name in ("output", "mux") and ros1 is not None:
            topics = sec.get("topics")
            for item in topics.items if topics is not None and sec.name == "mux" else ():
                if isinstance(item, ast.Call):
                    continue  # declared: `/topic (pkg/Name [field])`
                name = item.text if isinstance(item, ast.Word) else getattr(item, "value", "")
                new = converted_name(sink.file)
                sink.error("E319", f"ROS 1 topic `{name}` of [{sec.label}] would be read from ROS 2, which needs its "
                           "message type, and the legacy form gives none", item.span,
                           f"convert without --ros2 (`ybgc fmt --to named FILE -o {new}`), then in {new} give "
                           f"the type, `topics = {name} (pkg/Name)`, and set `via = ros2` in [mux {sec.label}]")
            entries = tuple(ast.Entry("via", (ast.Word("ros2", e.items[0].span),), e.span, e.key_span)
                            if e is ros1 else e for e in sec.entries)
            sec = ast.Section(sec.name, sec.label, entries, sec.span)
        secs.append(sec)
    return ast.Document(tuple(secs))
