#!/usr/bin/env python3
"""Write the ROS 2 service and action definitions shipped in ``ybg/msgs``, copied from upstream.

Each service becomes ``ybg/msgs/<distro>/<pkg>/<Name>.srv``, a byte-for-byte
copy of upstream's file: ``std_srvs``, and the services of the message
packages ybgc ships (``scripts/vendor_msgs.py``'s ``PACKAGES``). The sources:

- Kilted and Jazzy: the PyPI wheels of ros2/common_interfaces (``ros-std-srvs``,
  ``ros-sensor-msgs``...), which install ``share/<pkg>/srv/<Name>.srv``: for
  Kilted the versions that ``ros-kilted-<pkg>`` names, for Jazzy the ones that
  ``ros-jazzy-<pkg>`` pins. Downloaded with pip (``--no-deps``) into ``--wheels``.
- Humble, which has no wheels: ros2/common_interfaces at its Humble release
  tag, read from a clone of it (``--common-interfaces DIR``, a work tree or a
  bare repository).
- ``tf2_msgs/FrameGraph``, which has no wheel: ros2/geometry2 at a tag of each
  distro's release, from a clone of it (``--geometry2 DIR``). For Kilted the
  tag is Rolling's 0.39.1, from before Kilted branched off Rolling: the file
  has not changed since 2013.
- The actions: ``control_msgs/FollowJointTrajectory`` (what MoveIt sends a
  robot) and the two messages it needs (``JointTolerance``,
  ``JointComponentTolerance``), which have no wheel: ros-controls/control_msgs
  at the release each distro's rosdistro names (``CONTROL_MSGS_REFS``: Kilted
  has the feedback's ``index`` fields, Jazzy and Humble not), from a clone of
  it (``--control-msgs DIR``), written as ``<distro>/control_msgs/<Name>.action``
  and ``.msg``.

    scripts/vendor_srvs.py --common-interfaces DIR --geometry2 DIR --control-msgs DIR           write them
    scripts/vendor_srvs.py --common-interfaces DIR --geometry2 DIR --control-msgs DIR --check   exit 1 if the committed files differ

It also writes ``ybg/msgs/README.md`` (with ``scripts/vendor_msgs.py``'s text,
which counts the services): run it with the development dependencies
installed (``pip install -e .[test]``: rosbags).
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path, PurePosixPath

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "ybg" / "msgs"

WHEEL_PACKAGES = ("std_srvs", "sensor_msgs", "nav_msgs", "diagnostic_msgs", "visualization_msgs")
"""The packages of ros2/common_interfaces that have services, among those ybgc ships and std_srvs."""

WHEEL_VERSIONS = {"kilted": "5.5.1", "jazzy": "5.3.6"}
"""The version of the common_interfaces wheels of each distro (``ros-<distro>-std-srvs`` pins it)."""

WHEEL_TARGET = ["--python-version", "3.11", "--platform", "manylinux_2_28_x86_64", "--only-binary=:all:"]
"""The wheels are built per Python and platform; their ``.srv`` files are the same in each."""

COMMON_INTERFACES_REFS = {"humble": "4.2.4"}
"""ros2/common_interfaces: the release tag of each distro read from git."""

GEOMETRY2_REFS = {"humble": "0.25.8", "jazzy": "0.36.4", "kilted": "0.39.1"}
"""ros2/geometry2 (tf2_msgs): a release tag of each distro."""

CONTROL_MSGS_REFS = {"humble": "4.8.0", "jazzy": "5.8.0", "kilted": "6.8.0"}
"""ros-controls/control_msgs: the release tag of each distro."""

CONTROL_MSGS_FILES = ("action/FollowJointTrajectory.action", "msg/JointTolerance.msg", "msg/JointComponentTolerance.msg")
"""The actions shipped, and the messages of control_msgs they need."""

DISTROS = ("humble", "jazzy", "kilted")


def _vendor_msgs():
    spec = importlib.util.spec_from_file_location("vendor_msgs", Path(__file__).with_name("vendor_msgs.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def wanted_packages() -> set[str]:
    return set(_vendor_msgs().PACKAGES) | {"std_srvs"}


def from_wheels(version: str, wheels: Path, packages: set[str]) -> dict[str, bytes]:
    """``{pkg/Name: text}`` of the services in the wheels of ``version``."""
    names = [f"ros-{p.replace('_', '-')}=={version}" for p in WHEEL_PACKAGES]
    subprocess.run([sys.executable, "-m", "pip", "download", "--quiet", "--disable-pip-version-check",
                    "--no-deps", *WHEEL_TARGET, "-d", str(wheels), *names], check=True)
    out: dict[str, bytes] = {}
    for pkg in WHEEL_PACKAGES:
        found = sorted(wheels.glob(f"ros_{pkg}-{version}-*.whl"))
        if not found:
            raise SystemExit(f"no wheel of ros-{pkg}=={version} in {wheels}")
        with zipfile.ZipFile(found[0]) as whl:
            for member in whl.namelist():
                p = PurePosixPath(member)
                # ros_std_srvs-5.5.1.data/data/share/std_srvs/srv/Trigger.srv
                if p.suffix == ".srv" and p.parts[1:] == ("data", "share", pkg, "srv", p.name):
                    if pkg in packages:
                        out[f"{pkg}/{p.stem}"] = whl.read(member)
    return out


def _git(repo: Path, *args: str) -> bytes:
    return subprocess.run(["git", "-C", str(repo), *args], check=True, capture_output=True).stdout


def from_git(repo: Path, ref: str, packages: set[str]) -> dict[str, bytes]:
    """``{pkg/Name: text}`` of every ``<pkg>/srv/<Name>.srv`` of ``repo`` at ``ref``."""
    out: dict[str, bytes] = {}
    for path in _git(repo, "ls-tree", "-r", "--name-only", ref).decode().splitlines():
        p = PurePosixPath(path)
        if p.suffix == ".srv" and len(p.parts) == 3 and p.parts[1] == "srv" and p.parts[0] in packages:
            out[f"{p.parts[0]}/{p.stem}"] = _git(repo, "show", f"{ref}:{path}")
    return out


def from_control_msgs(repo: Path, ref: str) -> dict[Path, bytes]:
    """``{control_msgs/<Name>.<ext>: text}`` of :data:`CONTROL_MSGS_FILES` at ``ref``."""
    return {Path("control_msgs", PurePosixPath(f).name): _git(repo, "show", f"{ref}:control_msgs/{f}")
            for f in CONTROL_MSGS_FILES}


def generate(common_interfaces: Path, geometry2: Path, wheels: Path, control_msgs: Path) -> dict[Path, bytes]:
    """Every vendored service and action file (and the messages of
    control_msgs), relative to ``ybg/msgs``, with its bytes."""
    packages = wanted_packages()
    files: dict[Path, bytes] = {}
    for distro in DISTROS:
        if distro in WHEEL_VERSIONS:
            services = from_wheels(WHEEL_VERSIONS[distro], wheels, packages)
        else:
            services = from_git(common_interfaces, COMMON_INTERFACES_REFS[distro], packages)
        services.update(from_git(geometry2, GEOMETRY2_REFS[distro], packages))
        for name, text in services.items():
            pkg, srv = name.split("/")
            files[Path(distro, pkg, f"{srv}.srv")] = text
        for rel, text in from_control_msgs(control_msgs, CONTROL_MSGS_REFS[distro]).items():
            files[Path(distro) / rel] = text
    return files


def existing(out: Path) -> set[Path]:
    found = {p.relative_to(out) for d in DISTROS if (out / d).is_dir() for p in (out / d).rglob("*.srv")}
    found |= {p.relative_to(out) for d in DISTROS if (out / d).is_dir() for p in (out / d).rglob("*.action")}
    return found | {p.relative_to(out) for d in DISTROS for p in (out / d / "control_msgs").glob("*.msg")}


def readme(out: Path, files: dict[Path, bytes]) -> bytes:
    """``ybg/msgs/README.md`` with these services, as ``scripts/vendor_msgs.py`` writes it."""
    vendor_msgs = _vendor_msgs()
    msgs = vendor_msgs.file_counts(out, "msg")
    srvs = {d: sum(1 for p in files if p.parts[0] == d and p.suffix == ".srv") for d in msgs}
    actions = {d: sum(1 for p in files if p.parts[0] == d and p.suffix == ".action") for d in msgs}
    return vendor_msgs.readme(msgs, srvs, actions).encode("utf-8")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--common-interfaces", type=Path, required=True,
                    help="a clone of ros2/common_interfaces (for Humble)")
    ap.add_argument("--geometry2", type=Path, required=True, help="a clone of ros2/geometry2 (for tf2_msgs)")
    ap.add_argument("--control-msgs", type=Path, required=True, help="a clone of ros-controls/control_msgs")
    ap.add_argument("--wheels", type=Path, help="where the wheels are downloaded (default: a temporary folder)")
    ap.add_argument("--out", type=Path, default=OUT, help="output folder (default ybg/msgs)")
    ap.add_argument("--check", action="store_true", help="only compare with the files on disk")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        files = generate(args.common_interfaces, args.geometry2, args.wheels or Path(tmp), args.control_msgs)
    files[Path("README.md")] = readme(args.out, files)
    stale = existing(args.out) - files.keys()
    changed = [p for p, data in files.items() if not (args.out / p).exists() or (args.out / p).read_bytes() != data]
    if args.check:
        for p in sorted(changed):
            print(f"differs: {p}")
        for p in sorted(stale):
            print(f"stale: {p}")
        return 1 if changed or stale else 0
    for p in changed:
        (args.out / p).parent.mkdir(parents=True, exist_ok=True)
        (args.out / p).write_bytes(files[p])
    for p in stale:
        os.remove(args.out / p)
    counts = ", ".join(f"{d} {sum(1 for p in files if p.parts[0] == d and p.suffix == '.srv')}" for d in DISTROS)
    print(f"services: {counts}; {len(changed)} files written, {len(stale)} removed in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
