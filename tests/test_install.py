"""ybgc installed as its users install it, away from the source tree.

A clone of the repository (the working tree's changes to its tracked files
committed on top: what the next commit holds) is built into a wheel and an
sdist, once for this module. Each is installed into a fresh virtual
environment (not editable, not the project's venv), and from there every
command runs: `check`, `fmt`, `ir`, `graph` and the three backends; what the
installed ybgc prints and writes is what the source tree's ybgc prints and
writes. The C++ module the wheel's ybgc writes is built with CMake against
YARP 3.5 and run once against a real yarpserver. `pip install git+file://`
of the clone, as pre-commit installs a hook's repository, runs the hooks of
.pre-commit-hooks.yaml and generates a C++ module.

The wheel and the sdist hold every file git tracks under ybg/ (the data
files the commands read: grammar, templates, .msg definitions, the C++
runtime), so a data file added later cannot be left out of them.
"""
from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
import tarfile
import time
import zipfile
from dataclasses import dataclass
from pathlib import Path

import pytest
import yaml

from harness.env import DEFAULT_YARP, VENV
from harness.module import EXIT_BOUND, Module
from harness.programs import config_program
from harness.reference import assert_matches, expected, mux_values, sent_values
from harness.yarp import YarpProducer, YarpReader, YarpServer, require_yarp, yarp_ports

ROOT = Path(__file__).resolve().parent.parent
EXAMPLES = ROOT / "examples"
#: YARP ports in, a YARP port out: the module built and run end to end
YARP_CONFIG = EXAMPLES / "yarp_to_yarp_end_effector.ini"
#: YARP ports in, ROS 2 out: the ros2 node, the C++ module through rcl
ROS2_CONFIG = EXAMPLES / "vizzy_rviz_joint_states.ini"
LEGACY_CONFIG = ROOT / "tests" / "canonical" / "legacy_vizzy_upper_body.ini"
#: a config of commands: the .srv definitions and the runtime of commands
SERVICES_CONFIG = EXAMPLES / "home_arm_trigger.ini"
#: a robot's own YARP .ini file, which the pre-commit hooks skip
FOREIGN_INI = "device controlboardwrapper2\nsubdevice fakeMotionControl\n\n[GENERAL]\nJoints 4\n"

#: what reaches ybgc from the environment besides its install: message
#: search paths (the venv's ROS 2 wheels would hide a .msg the install lacks)
#: and Python paths (the source tree)
_DROP = ("PYTHONPATH", "PYTHONHOME", "PYTHONSTARTUP", "VIRTUAL_ENV", "YBG_MSG_PATH", "ROS_PACKAGE_PATH",
         "AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH")

pytestmark = pytest.mark.slow


def run(argv, timeout: float = 300, **kw) -> subprocess.CompletedProcess:
    """Run ``argv``; fails the test with its output if it fails."""
    r = subprocess.run([str(a) for a in argv], capture_output=True, text=True, timeout=timeout, **kw)
    if r.returncode != 0:
        pytest.fail(f"{' '.join(map(str, argv))} exited {r.returncode}:\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}",
                    pytrace=False)
    return r


def git(*args, cwd: Path) -> str:
    return run(["git", "-C", cwd, *args], timeout=120).stdout


# --------------------------------------------------------------------------
# a clean checkout, its wheel and sdist, and installs of them


@pytest.fixture(scope="module")
def clone(tmp_path_factory) -> Path:
    """A ``git clone`` of the repository with the working tree's changes to
    tracked files (staged new files included) committed on top: no build
    folders, no egg-info, no untracked files."""
    path = tmp_path_factory.mktemp("install") / "ybgc"
    head = git("rev-parse", "HEAD", cwd=ROOT).strip()  # a commit made meanwhile is not in the diff
    run(["git", "clone", "--quiet", "--no-checkout", ROOT, path], timeout=120)
    git("checkout", "--quiet", "-B", "install", head, cwd=path)  # a branch: pip clones HEAD
    diff = subprocess.run(["git", "-C", ROOT, "diff", head, "--binary"], capture_output=True, check=True).stdout
    if diff:
        r = subprocess.run(["git", "-C", path, "apply", "--binary", "--whitespace=nowarn"], input=diff,
                           capture_output=True)
        assert r.returncode == 0, r.stderr.decode(errors="replace")
        git("add", "-A", cwd=path)
        git("-c", "user.name=ybgc tests", "-c", "user.email=tests@ybgc.invalid", "-c", "commit.gpgsign=false",
            "commit", "--quiet", "--no-verify", "-m", "the working tree's changes", cwd=path)
    return path


@dataclass(frozen=True)
class Dists:
    wheel: Path
    sdist: Path


@pytest.fixture(scope="module")
def dists(clone, tmp_path_factory) -> Dists:
    """The clone's sdist and wheel, built by setuptools' PEP 517 hooks (what
    ``pip wheel .`` and ``python -m build`` call), without build isolation:
    the project's venv has the build requirements."""
    out = tmp_path_factory.mktemp("dist")
    code = ("import sys; from setuptools import build_meta as b; "
            "out = sys.argv[1]; b.build_sdist(out); b.build_wheel(out)")  # the hooks change sys.argv
    run([sys.executable, "-c", code, out], cwd=clone, env=clean_env())
    (wheel,) = out.glob("ybgc-*.whl")
    (sdist,) = out.glob("ybgc-*.tar.gz")
    return Dists(wheel, sdist)


def clean_env(venv: Path | None = None) -> dict:
    """os.environ without what would let the source tree, or message
    definitions from elsewhere, stand in for the install; ``venv``'s bin
    first on PATH, the project's venv off it."""
    env = {k: v for k, v in os.environ.items() if k not in _DROP}
    path = [p for p in env.get("PATH", "/usr/bin:/bin").split(os.pathsep)
            if Path(p).resolve() != (VENV / "bin").resolve()]
    if venv is not None:
        env["VIRTUAL_ENV"] = str(venv)
        path.insert(0, str(venv / "bin"))
    env["PATH"] = os.pathsep.join(path)
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


@dataclass(frozen=True)
class Install:
    """ybgc installed into a virtual environment of its own."""
    venv: Path

    @property
    def ybgc(self) -> Path:
        return self.venv / "bin" / "ybgc"

    @property
    def env(self) -> dict:
        return clean_env(self.venv)


def install(requirement: str, venv: Path) -> Install:
    """A fresh venv (the interpreter's own, not the project's) and ``pip
    install requirement`` into it, with build isolation as a user's pip does
    (pip's cache and the machine's pip settings apply). The project's pip
    installs into it (``--python``): a venv of its own costs 10 s more."""
    run([sys.executable, "-m", "venv", "--without-pip", venv], env=clean_env())
    run([sys.executable, "-m", "pip", "--python", venv / "bin" / "python", "install", "--quiet", requirement],
        env=clean_env(venv), timeout=600)
    inst = Install(venv)
    where = run([venv / "bin" / "python", "-c", "import ybg; print(ybg.__file__)"], cwd=venv, env=inst.env)
    assert Path(where.stdout.strip()).is_relative_to(venv), where.stdout  # not the source tree
    assert not any(venv.glob("lib/python3*/site-packages/__editable__*")), "an editable install"
    return inst


@pytest.fixture(scope="module")
def wheel_install(dists, tmp_path_factory) -> Install:
    return install(str(dists.wheel), tmp_path_factory.mktemp("venv_wheel") / "venv")


@pytest.fixture(scope="module")
def sdist_install(dists, tmp_path_factory) -> Install:
    return install(str(dists.sdist), tmp_path_factory.mktemp("venv_sdist") / "venv")


# --------------------------------------------------------------------------
# every command, from an install and from the source tree


#: the configs the commands read, copied into the folder they run in (so
#: that the paths in what they print and write are the same for every run)
CONFIGS = {p.name: p for p in (YARP_CONFIG, ROS2_CONFIG, LEGACY_CONFIG, SERVICES_CONFIG)}

#: every command, each reading the data files of its own: the grammar and
#: the .msg definitions (all of them), the templates and runtime of each
#: backend, plain and packaged
COMMANDS = (
    ("check", *sorted(CONFIGS)),
    ("check", "--backend", "ros2", ROS2_CONFIG.name),
    ("fmt", "--check", YARP_CONFIG.name, ROS2_CONFIG.name),
    ("fmt", "--to", "named", "--ros2", LEGACY_CONFIG.name, "-o", "named.ini"),
    ("ir", YARP_CONFIG.name),
    ("graph", ROS2_CONFIG.name, "-o", "graph.svg"),
    ("graph", YARP_CONFIG.name, "--format", "mermaid"),
    (YARP_CONFIG.name, "--backend", "cpp", "-o", "cpp"),
    (YARP_CONFIG.name, "--backend", "cpp", "--single-file", "-o", "cpp_single"),
    (ROS2_CONFIG.name, "--backend", "cpp", "--package", "-o", "cpp_ros2"),
    (YARP_CONFIG.name, "--backend", "py", "-o", "py"),
    (ROS2_CONFIG.name, "--backend", "ros2", "-o", "ros2"),
    (ROS2_CONFIG.name, "--backend", "ros2", "--package", "-o", "ros2_package"),
    ("ir", SERVICES_CONFIG.name),
    (SERVICES_CONFIG.name, "--backend", "cpp", "-o", "cpp_commands"),
    (SERVICES_CONFIG.name, "--backend", "ros2", "-o", "ros2_commands"),
    ("compose", YARP_CONFIG.name, ROS2_CONFIG.name, "--backend", "cpp", "--name", "robot", "-o", "cpp_robot"),
    ("compose", YARP_CONFIG.name, ROS2_CONFIG.name, SERVICES_CONFIG.name, "--backend", "ros2", "--name", "robot",
     "-o", "ros2_robot"),
)


@dataclass(frozen=True)
class Outcome:
    runs: tuple      # (command, exit status, stdout, stderr) of each command
    files: dict      # {path: bytes} of every file the commands wrote


def run_commands(ybgc: Path, folder: Path, env: dict) -> Outcome:
    folder.mkdir(parents=True)
    for name, path in CONFIGS.items():
        shutil.copyfile(path, folder / name)
    runs = []
    for cmd in COMMANDS:
        r = subprocess.run([str(ybgc), *cmd], cwd=folder, env=env, capture_output=True, text=True, timeout=120)
        runs.append((" ".join(cmd), r.returncode, r.stdout, r.stderr))
    return Outcome(tuple(runs), written(folder, exclude=set(CONFIGS)))


def written(folder: Path, exclude=frozenset()) -> dict:
    """{path: bytes} of the files under ``folder``, the folder's own path in
    them replaced (a yarpmanager application names the folder it runs in)."""
    here = str(folder.resolve()).encode()
    return {str(p.relative_to(folder)): p.read_bytes().replace(here, b"<folder>")
            for p in sorted(folder.rglob("*")) if p.is_file() and p.name not in exclude}


@pytest.fixture(scope="module")
def source_outcome(tmp_path_factory) -> Outcome:
    """The commands run by the source tree's ybgc (the project's venv)."""
    return run_commands(VENV / "bin" / "ybgc", tmp_path_factory.mktemp("source") / "run", clean_env())


def assert_same_outcome(got: Outcome, want: Outcome) -> None:
    for (cmd, rc, out, err), (_, want_rc, want_out, want_err) in zip(got.runs, want.runs):
        assert "Traceback" not in err, f"ybgc {cmd}:\n{err}"
        assert rc == want_rc == 0, f"ybgc {cmd}: exit {rc}, source tree {want_rc}:\n{err}\n{want_err}"
        assert (out, err) == (want_out, want_err), f"ybgc {cmd}"
    assert sorted(got.files) == sorted(want.files)
    for name, data in want.files.items():
        assert got.files[name] == data, name


# --------------------------------------------------------------------------
# the tests


def test_wheel_and_sdist_hold_every_file_of_the_package(clone, dists):
    """Every file git tracks under ybg/, Python source and data files alike,
    is in the wheel and in the sdist: a data file added later is too."""
    data = git("ls-files", "ybg", cwd=clone).splitlines()
    # what the commands read, by name (each kind of data file is among them)
    for must in ("ybg/grammar/config.lark", "ybg/msgs/jazzy/sensor_msgs/JointState.msg",
                 "ybg/msgs/noetic/std_msgs/Header.msg", "ybg/backends/cpp/templates/CMakeLists.txt.j2",
                 "ybg/backends/py/templates/module.py.j2", "ybg/backends/ros2/templates/node.py.j2",
                 "ybg/runtime/cpp/ybgc_runtime.hpp", "ybg/runtime/cpp/ybgc_runtime.cpp",
                 "ybg/runtime/cpp/ybgc_ros2.hpp", "ybg/runtime/cpp/ybgc_ros2.cpp"):
        assert must in data, must
    wheel = set(zipfile.ZipFile(dists.wheel).namelist())
    assert not [p for p in data if p not in wheel], "left out of the wheel"
    assert not [p for p in wheel if "__pycache__" in p or p.endswith(".pyc")]
    with tarfile.open(dists.sdist) as tar:
        top = dists.sdist.name.removesuffix(".tar.gz")
        sdist = {m.name.removeprefix(f"{top}/") for m in tar.getmembers()}
    assert not [p for p in data if p not in sdist], "left out of the sdist"
    assert {"pyproject.toml", "MANIFEST.in", "README.md"} <= sdist


@pytest.mark.timeout(600)
@pytest.mark.parametrize("dist", ["wheel", "sdist"])
def test_every_command_from_an_install(dist, request, source_outcome, tmp_path):
    """Installed from the wheel, or from the sdist (pip builds the wheel
    itself), ybgc prints and writes what the source tree's ybgc does, for
    every command and backend."""
    inst: Install = request.getfixturevalue(f"{dist}_install")
    assert_same_outcome(run_commands(inst.ybgc, tmp_path / "run", inst.env), source_outcome)


@pytest.mark.timeout(600)
def test_cpp_module_from_the_wheel_builds_and_runs(wheel_install, tmp_path):
    """The C++ module the wheel's ybgc writes (its runtime beside it) builds
    against YARP 3.5 and relays real producers' Bottles as the reference
    says; SIGINT ends it cleanly."""
    yarp = DEFAULT_YARP
    require_yarp(yarp)
    shutil.copyfile(YARP_CONFIG, tmp_path / YARP_CONFIG.name)
    run([wheel_install.ybgc, YARP_CONFIG.name, "--backend", "cpp", "-o", "module"], cwd=tmp_path,
        env=wheel_install.env)
    src, build = tmp_path / "module", tmp_path / "module" / "build"
    # a build type of no flags: the build only has to work, not be fast
    run(["cmake", "-S", src, "-B", build, f"-DCMAKE_PREFIX_PATH={yarp.cmake_prefix_path()}",
         "-DCMAKE_BUILD_TYPE=Tests"], timeout=300)
    run(["cmake", "--build", build, "-j", str(min(2, os.cpu_count() or 1))], timeout=600)

    program = config_program(YARP_CONFIG, "cpp")
    exe = build / program.module
    sent = sent_values(program)
    want = expected(program, mux_values(program, sent), named=False)
    with YarpServer(install=yarp) as server:
        env = server.env
        peers = []
        try:
            begun = time.time()
            module = Module([exe], env=env, name=exe.name).start()
            peers.append(module)
            reader = YarpReader(env, "/test/install:i", source=program.output.name).start()
            peers.append(reader)
            for m in program.muxes:
                for inp in m.inputs:
                    peers.append(YarpProducer(env, inp.name, bottles=[sent[inp.name]], rate=20).start())
            got = reader.wait_for(3, timeout=60)
            last = got[-1]
            # a time the module stamps: its clock, after it started, before the reader had the message
            assert_matches(last.data, want, (begun, last.t))
            rc, elapsed = module.interrupt(signal.SIGINT)
            log = module.log_text()
            assert rc == 0 and elapsed < EXIT_BOUND, log[-2000:]
            assert "totals:" in log and "Traceback" not in log, log[-3000:]
            assert not any(p.startswith(f"/{program.module}") for p in yarp_ports(server))
        finally:
            for p in reversed(peers):
                p.stop()


@pytest.mark.timeout(600)
def test_pip_install_from_git_runs_the_pre_commit_hooks(clone, source_outcome, tmp_path):
    """``pip install git+file://<clone>``, as pre-commit installs a hook's
    repository (a venv of its own, the package built from a checkout): each
    hook of .pre-commit-hooks.yaml, run as pre-commit runs it (its entry and
    the staged .ini files), checks the ybgc configs and skips a robot's own
    .ini file; and that install generates the C++ module."""
    inst = install(f"git+file://{clone}", tmp_path / "venv")
    repo = tmp_path / "robot"
    repo.mkdir()
    for name in (YARP_CONFIG.name, ROS2_CONFIG.name):
        shutil.copyfile(CONFIGS[name], repo / name)
    (repo / "robot.ini").write_text(FOREIGN_INI)
    files = sorted(p.name for p in repo.iterdir())
    before = {name: (repo / name).read_bytes() for name in files}

    hooks = {h["id"]: h for h in yaml.safe_load((clone / ".pre-commit-hooks.yaml").read_text())}
    assert set(hooks) == {"ybgc-check", "ybgc-fmt"}
    for hook in hooks.values():
        assert hook["language"] == "python"  # pre-commit installs the repository with pip, as above
        entry = shlex.split(hook["entry"])
        assert entry[0] == "ybgc" and shutil.which("ybgc", path=inst.env["PATH"]) == str(inst.ybgc)
        assert all(re.search(hook["files"], f) for f in files)
        r = subprocess.run([*entry, *files], cwd=repo, env=inst.env, capture_output=True, text=True, timeout=120)
        assert r.returncode == 0 and "Traceback" not in r.stderr, f"{hook['id']}:\n{r.stdout}\n{r.stderr}"
    assert {name: (repo / name).read_bytes() for name in files} == before  # canonical: fmt left them

    # an error is an error from this install too
    (repo / "bad.ini").write_text(YARP_CONFIG.read_text().replace("[message]", "[message]\nnope = nomux"))
    r = subprocess.run([*shlex.split(hooks["ybgc-check"]["entry"]), "bad.ini"], cwd=repo, env=inst.env,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and "bad.ini:" in r.stdout + r.stderr and "Traceback" not in r.stderr, r

    run([inst.ybgc, YARP_CONFIG.name, "--backend", "cpp", "-o", "cpp"], cwd=repo, env=inst.env)
    cpp = lambda files: {k: v for k, v in files.items() if k.startswith("cpp/")}  # noqa: E731
    assert cpp(written(repo)) == cpp(source_outcome.files)
