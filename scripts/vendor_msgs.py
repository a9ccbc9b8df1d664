#!/usr/bin/env python3
"""Write the standard ROS message definitions shipped in ``ybg/msgs``.

The definitions come from the PyPI package ``rosbags``, which bundles the
standard message sets of ROS 1 Noetic and the ROS 2 distributions. Each
message becomes ``ybg/msgs/<distro>/<pkg>/<Name>.msg`` in the spelling of its
ROS version: ROS 1 files say ``time``, ``duration`` and ``Header``; ROS 2
files say ``builtin_interfaces/Time`` and ``std_msgs/Header``.

    scripts/vendor_msgs.py            regenerate every distro
    scripts/vendor_msgs.py --check    exit 1 if the committed files differ

rosbags is a development dependency only: ybg never imports it at run time.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
from importlib.metadata import version
from pathlib import Path

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_typestore

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "ybg" / "msgs"

# distro -> (dialect, rosbags store). Rolling has no store of its own in rosbags.
DISTRO_STORES = {
    "noetic": ("ros1", Stores.ROS1_NOETIC),
    "humble": ("ros2", Stores.ROS2_HUMBLE),
    "jazzy": ("ros2", Stores.ROS2_JAZZY),
    "kilted": ("ros2", Stores.ROS2_KILTED),
}

PACKAGES = (
    "std_msgs", "builtin_interfaces", "sensor_msgs", "geometry_msgs", "nav_msgs",
    "trajectory_msgs", "shape_msgs", "diagnostic_msgs", "visualization_msgs",
    "stereo_msgs", "actionlib_msgs", "unique_identifier_msgs", "tf2_msgs",
)

# ROS 1 messages that rosbags' Noetic store lacks: the frames on /tf, as
# tf2_msgs (Debian's ros-tf2-msgs) and the older tf package define them.
ROS1_EXTRA = {
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms\n",
    "tf/tfMessage": "geometry_msgs/TransformStamped[] transforms\n",
}

# rosbags gives ROS 1 stores the ROS 2 builtin types in place of time/duration;
# ROS 1 has no builtin_interfaces package.
ROS1_BUILTINS = {"builtin_interfaces/msg/Time": "time", "builtin_interfaces/msg/Duration": "duration"}

# rosbags adds this member to empty structures (an IDL requirement); .msg files have none.
PLACEHOLDER = "structure_needs_at_least_one_member"


def short(name: str) -> str:
    """``pkg/msg/Name`` -> ``pkg/Name``."""
    pkg, _, typ = name.split("/")
    return f"{pkg}/{typ}"


def render_type(desc, dialect: str, pkg: str) -> str:
    kind, rest = desc
    if kind == Nodetype.BASE:
        base, bound = rest
        return f"{base}<={bound}" if bound else base
    if kind == Nodetype.NAME:
        if dialect == "ros1":
            if rest in ROS1_BUILTINS:
                return ROS1_BUILTINS[rest]
            if rest == "std_msgs/msg/Header":
                return "Header"
        ref_pkg, _, typ = rest.split("/")
        return typ if ref_pkg == pkg else f"{ref_pkg}/{typ}"
    elem, size = rest
    inner = render_type(elem, dialect, pkg)
    if kind == Nodetype.ARRAY:
        return f"{inner}[{size}]"
    if kind == Nodetype.SEQUENCE:
        return f"{inner}[<={size}]" if size else f"{inner}[]"
    raise ValueError(f"unexpected node type {kind!r}")


def render_constant(name: str, typ: str, value, dialect: str) -> str:
    if typ in ("string", "wstring"):
        text = value if dialect == "ros1" else json.dumps(value, ensure_ascii=False)
    elif isinstance(value, bool) or typ == "bool":
        text = ("true" if value else "false") if dialect == "ros2" else str(int(value))
    else:
        text = repr(value)
    return f"{typ} {name}={text}"


def render(name: str, constants, fields, dialect: str) -> str:
    pkg = name.split("/")[0]
    lines = [render_constant(n, t, v, dialect) for n, t, v in constants]
    if constants and fields:
        lines.append("")
    for fname, desc in fields:
        if fname == PLACEHOLDER and len(fields) == 1:
            continue
        lines.append(f"{render_type(desc, dialect, pkg)} {fname}")
    return "\n".join(lines) + "\n" if lines else ""


def generate(out: Path = OUT) -> dict[Path, str]:
    """Every vendored message file, relative to ``ybg/msgs``, with its text;
    and the README, which counts the services in ``out`` too."""
    files: dict[Path, str] = {}
    for distro, (dialect, store) in DISTRO_STORES.items():
        ts = get_typestore(store)
        for name, (constants, fields) in sorted(ts.fielddefs.items()):
            pkg, _, typ = name.split("/")
            if pkg not in PACKAGES:
                continue
            if dialect == "ros1" and pkg == "builtin_interfaces":
                continue
            files[Path(distro, pkg, f"{typ}.msg")] = render(name, constants, fields, dialect)
        if dialect == "ros1":
            for name, text in ROS1_EXTRA.items():
                pkg, typ = name.split("/")
                files[Path(distro, pkg, f"{typ}.msg")] = text
    counts = {d: sum(1 for p in files if p.parts[0] == d) for d in DISTRO_STORES}
    files[Path("README.md")] = readme(counts, file_counts(out, "srv"), file_counts(out, "action"))
    return files


COPIED = ("control_msgs",)
"""Packages whose files ``scripts/vendor_srvs.py`` copies from upstream, messages and all."""


def file_counts(out: Path, ext: str) -> dict[str, int]:
    """How many ``*.<ext>`` files each distro's folder of ``out`` holds (of
    messages, those this script writes: not the :data:`COPIED` packages')."""
    return {d: sum(1 for p in (out / d).rglob(f"*.{ext}") if ext != "msg" or p.parent.name not in COPIED)
            for d in DISTRO_STORES}


def readme(msg_counts: dict[str, int], srv_counts: dict[str, int], action_counts: dict[str, int] = {}) -> str:
    """The text of ``ybg/msgs/README.md``: ``srv_counts`` and ``action_counts``
    are the services and actions that ``scripts/vendor_srvs.py`` writes (both
    scripts write this file)."""
    lines = [
        "# Vendored ROS message definitions",
        "",
        f"Generated by `scripts/vendor_msgs.py` from rosbags {version('rosbags')}; do not edit.",
        "Layout: `<distro>/<pkg>/<Name>.msg`, in the spelling of the distro's ROS version.",
        "Services: `<distro>/<pkg>/<Name>.srv`, exact copies of upstream's files, written by",
        "`scripts/vendor_srvs.py` (its docstring names their sources).",
        "Actions: `<distro>/<pkg>/<Name>.action`, and the messages of `control_msgs` they need,",
        "exact copies of upstream's files, written by `scripts/vendor_srvs.py` too.",
        "",
    ]
    for d, n in msg_counts.items():
        services = f", {srv_counts[d]} services" if srv_counts.get(d) else ""
        n_act = action_counts.get(d, 0)
        actions = f", {n_act} action{'s' if n_act > 1 else ''}" if n_act else ""
        lines.append(f"- {d} ({DISTRO_STORES[d][0]}): {n} messages{services}{actions}")
    return "\n".join(lines) + "\n"


def existing(out: Path) -> set[Path]:
    found = {Path("README.md")} if (out / "README.md").exists() else set()
    for distro in DISTRO_STORES:
        base = out / distro
        if base.is_dir():
            found |= {p.relative_to(out) for p in base.rglob("*.msg") if p.parent.name not in COPIED}
    return found


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=OUT, help="output folder (default ybg/msgs)")
    ap.add_argument("--check", action="store_true", help="only compare with the files on disk")
    args = ap.parse_args(argv)
    files = generate(args.out)
    stale = existing(args.out) - files.keys()
    changed = [p for p, text in files.items()
               if not (args.out / p).exists() or (args.out / p).read_text(encoding="utf-8") != text]
    if args.check:
        for p in sorted(changed):
            print(f"differs: {p}")
        for p in sorted(stale):
            print(f"stale: {p}")
        return 1 if changed or stale else 0
    for p in changed:
        (args.out / p).parent.mkdir(parents=True, exist_ok=True)
        (args.out / p).write_text(files[p], encoding="utf-8")
    for p in stale:
        os.remove(args.out / p)
    print(f"{len(files)} files, {len(changed)} written, {len(stale)} removed in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
