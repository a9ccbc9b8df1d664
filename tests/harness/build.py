"""Building generated C++ for the tests.

    use_ccache()        the tests' cmake runs compile through ccache (when installed)
    run_folder(tmp_path_factory, name) -> Path   a folder every pytest-xdist worker of the run sees
    held(path)          with: an exclusive lock on a file across processes (build once per run)
    configure(src, install), build_cpp(src, install) -> the executable, cmake_build(...)
                        one CMake project (a module's folder), against a YARP install
    find_once_option()  the -D option of the tests' configures: each of YARP's packages
                        found once (find_once.cmake), not hundreds of times
    Builds(root, install, ros2_env=VENV)   many modules in one CMake project, built on first use
                        (``.add(key, program)``, ``.exe(key)``): the modules of a session
                        (``session_builds``, the ``builds`` fixture of conftest.py), or of
                        one test file; their ROS 2 from the wheels of ``ros2_env``;
                        ybgc_runtime.hpp precompiled once for them all
"""
from __future__ import annotations

import dataclasses
import fcntl
import hashlib
import os
import shutil
import subprocess
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

import pytest

from harness.env import VENV, YARP_CACHE

if TYPE_CHECKING:
    from ybg.compiler.ir import Program


def use_ccache() -> None:
    """The tests build many small CMake projects, each compiling a module and
    the runtime library beside it: ccache (when installed, as the setup
    does) compiles each distinct source once, in ~/.cache/ybgc/ccache (its
    paths made relative to the temp folder, where the builds are, so that
    one runtime library beside two modules is one entry). Set in the
    environment, so every cmake the tests run (and the processes they
    start) configures with it."""
    if os.environ.get("YBG_NO_CCACHE") or not shutil.which("ccache"):
        return
    os.environ.setdefault("CMAKE_CXX_COMPILER_LAUNCHER", "ccache")
    os.environ.setdefault("CMAKE_C_COMPILER_LAUNCHER", "ccache")
    os.environ.setdefault("CCACHE_DIR", str(YARP_CACHE / "ccache"))
    os.environ.setdefault("CCACHE_BASEDIR", os.path.realpath(tempfile.gettempdir()))
    os.environ.setdefault("CCACHE_NOHASHDIR", "1")
    # the sources are written just before they are compiled
    os.environ.setdefault("CCACHE_SLOPPINESS", "include_file_mtime,include_file_ctime,time_macros")
    os.environ.setdefault("CCACHE_MAXSIZE", "3G")


def run_folder(tmp_path_factory, name: str) -> Path:
    """A folder of this test run that every pytest-xdist worker sees (the
    run's base folder, of which each worker's is a subfolder; without
    xdist, the session's), for what is built once per run."""
    base = tmp_path_factory.getbasetemp()
    if os.environ.get("PYTEST_XDIST_WORKER"):
        base = base.parent
    folder = base / name
    folder.mkdir(parents=True, exist_ok=True)
    return folder


class held:
    """``with held(path):`` an exclusive lock on the file ``path`` (created),
    across processes: the pytest-xdist workers building one thing take
    turns, and the later ones find it built."""

    def __init__(self, path: Path):
        self.path = path

    def __enter__(self):
        self.fd = os.open(self.path, os.O_CREAT | os.O_RDWR, 0o644)
        fcntl.flock(self.fd, fcntl.LOCK_EX)
        return self

    def __exit__(self, *exc):
        fcntl.flock(self.fd, fcntl.LOCK_UN)
        os.close(self.fd)


def configure(src: Path, install) -> subprocess.CompletedProcess:
    """CMake configures the project of ``src`` in ``src/build`` against ``install``."""
    return subprocess.run(["cmake", "-S", str(src), "-B", str(src / "build"),
                           f"-DCMAKE_PREFIX_PATH={install.cmake_prefix_path()}", find_once_option()],
                          capture_output=True, text=True, timeout=300)


def build_cpp(src: Path, install) -> Path:
    """The project of ``src`` configured and built against ``install``
    (failing the test if it does not build); its one executable."""
    r = configure(src, install)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    b = subprocess.run(["cmake", "--build", str(src / "build"), "-j2"], capture_output=True, text=True,
                       timeout=600)
    assert b.returncode == 0, b.stdout[-3000:] + b.stderr[-3000:]
    exe = [p for p in (src / "build").iterdir() if p.is_file() and os.access(p, os.X_OK)]
    assert len(exe) == 1, exe
    return exe[0]


def cmake_build(src: Path, build: Path, install, target: str | None = None,
                options: tuple = ()) -> subprocess.CompletedProcess:
    """The project of ``src`` configured in ``build`` against ``install``
    (with ``options``) and built (its ``target``): the first step that failed,
    or the build."""
    r = subprocess.run(["cmake", "-S", str(src), "-B", str(build),
                        f"-DCMAKE_PREFIX_PATH={install.cmake_prefix_path()}", find_once_option(), *options],
                       capture_output=True, text=True, timeout=300)
    if r.returncode != 0:
        return r
    cmd = ["cmake", "--build", str(build), "-j2"] + (["--target", target] if target else [])
    return subprocess.run(cmd, capture_output=True, text=True, timeout=900)


# --------------------------------------------------------------------------
# every module of the session in one CMake project


#: the folder of a project of many modules that holds the runtime's libraries
RUNTIME_FOLDER = "ybgc_runtime_libraries"


#: the source of the target that precompiles ybgc_runtime.hpp, in RUNTIME_FOLDER
PCH_SOURCE = "ybgc_tests_pch.cpp"


def precompiled_runtime_header(targets: list[str]) -> str:
    """CMake that compiles ybgc_runtime.hpp once for ``targets`` (modules of
    one project, with a module's flags): most of a module's compile at -O0 is
    that header (YARP's and the standard library's), 1.2 s a module, 0.5 s
    with it precompiled. A test project's saving: a user's project builds one
    module. The target's flags are a module's (CMakeLists.txt.j2); GCC
    refuses a precompiled header of other flags (-Winvalid-pch, an error with
    -Werror), so a module built otherwise (optimized) is left out."""
    from ybg.backends.cpp import runtime_library

    if not targets:
        return ""
    return (f"add_library(ybgc_tests_pch STATIC {RUNTIME_FOLDER}/{PCH_SOURCE})\n"
            "target_compile_features(ybgc_tests_pch PRIVATE cxx_std_17)\n"
            "set_target_properties(ybgc_tests_pch PROPERTIES CXX_EXTENSIONS OFF)\n"
            "target_compile_options(ybgc_tests_pch PRIVATE -Wall -Wextra -ffp-contract=off)\n"
            f"target_link_libraries(ybgc_tests_pch PRIVATE {runtime_library()})\n"
            "target_precompile_headers(ybgc_tests_pch PRIVATE "
            f"${{CMAKE_CURRENT_SOURCE_DIR}}/{RUNTIME_FOLDER}/ybgc_runtime.hpp)\n"
            + "".join(f"target_precompile_headers({t} REUSE_FROM ybgc_tests_pch)\n" for t in targets))


#: the dependency provider that finds each of YARP's packages once a configure
FIND_ONCE = Path(__file__).resolve().with_name("find_once.cmake")


def find_once_option() -> str:
    """The CMake option that makes a configure find each of YARP's component
    packages once (harness/find_once.cmake: 3.3 s -> 1 s a configure against
    YARP 3.5 from PyPI); the same targets, flags and link lines. Not for a
    test of what a user types."""
    return f"-DCMAKE_PROJECT_TOP_LEVEL_INCLUDES={FIND_ONCE}"


def ros2_wheels_option(ros2_env: Path = VENV) -> str:
    """The CMake option that builds a module publishing to ROS 2 against the
    ROS 2 wheels of a Python environment (docs/ros2-native.md): the test
    environment's (Kilted), or another distro's (.venv-jazzy)."""
    return f"-DYBGC_ROS2_PYTHON_ENV={ros2_env}"


class Builds:
    """Modules in one CMake project (the session's, or a test file's), generated
    and built on first use."""

    def __init__(self, root: Path, install, ros2_env: Path = VENV):
        self.root = root
        self.install = install
        self.ros2_env = ros2_env
        self.programs: dict[str, Program] = {}
        self.optimized: set[str] = set()
        self.built = False
        self.log = ""
        self.alone: dict[str, subprocess.CompletedProcess] = {}  # configure_alone's, by key

    def add(self, key: str, program: Program, optimize: bool = False) -> None:
        # one CMake project holds every module: a module named as one added
        # before (examples/ros2_to_yarp_gaze.ini and the legacy config it
        # comes from) gets a name, and a target, of its own
        if any(p.module == program.module for p in self.programs.values()):
            program = dataclasses.replace(program, module=f"{program.module}_{key}")
        self.programs[key] = program
        if optimize:
            self.optimized.add(key)

    def refused(self, key: str) -> bool:
        """Its generated CMakeLists refuses this YARP (ROS 1 on YARP 4): it is
        left out of the one build and configured alone by the tests."""
        from harness.programs import needs_ros1

        return needs_ros1(self.programs[key]) and self.install.key >= (4,)

    def configure_alone(self, key: str) -> subprocess.CompletedProcess:
        """Configures the module's own folder by itself, as its user would
        (once a process: what it answered is kept for the next test that asks)."""
        if key not in self.alone:
            self.build()
            folder = self.root / "src" / key
            self.alone[key] = subprocess.run(
                ["cmake", "-S", str(folder), "-B", str(self.root / f"alone_{key}_{os.getpid()}"),
                 f"-DCMAKE_PREFIX_PATH={self.install.cmake_prefix_path()}", find_once_option()],
                capture_output=True, text=True)
        return self.alone[key]

    def build(self) -> None:
        if self.built:
            return
        self.built = True
        # the pytest-xdist workers of a run share one build (run_folder): the
        # first builds it, the others wait for it and read its log
        self.root.mkdir(parents=True, exist_ok=True)
        with held(self.root / ".build.lock"):
            done = self.root / ".build.log"
            if done.exists():
                self.log = done.read_text(encoding="utf-8")
                return
            self._build()
            done.write_text(self.log, encoding="utf-8")

    def _build(self) -> None:
        from ybg.backends.cpp import CppBackend, runtime_folder, runtime_library

        src = self.root / "src"
        src.mkdir(parents=True, exist_ok=True)
        backend = CppBackend()
        # the runtime's libraries from a folder of their own, added first: the
        # same paths in every such project, so that ccache compiles them once a
        # YARP release (each module's folder would be another path)
        shared = src / RUNTIME_FOLDER
        shared.mkdir(exist_ok=True)
        for name, text in runtime_folder().items():
            (shared / name).write_text(text, encoding="utf-8")
        subdirs = []
        for key, program in sorted(self.programs.items()):
            folder = src / key
            folder.mkdir(exist_ok=True)
            for name, text in backend.render(program).items():
                (folder / name).write_text(text, encoding="utf-8")
            if not self.refused(key):
                subdirs.append(key)
        (shared / PCH_SOURCE).write_text("// the precompiled ybgc_runtime.hpp of the project's modules\n")
        # YARP found once up front: each module's own find_package() then
        # costs nothing (found per folder, it takes 2 s each)
        (src / "CMakeLists.txt").write_text(
            "cmake_minimum_required(VERSION 3.16)\nproject(ybgc_cpp_tests CXX)\n"
            "find_package(YARP REQUIRED COMPONENTS os sig)\nfind_package(Threads REQUIRED)\n"
            f"add_subdirectory({RUNTIME_FOLDER} EXCLUDE_FROM_ALL)\n"
            + "".join(f"add_subdirectory({k})\n" for k in subdirs)
            + "".join(f"target_compile_options({self.programs[k].module} PRIVATE -O2)\n"
                      for k in sorted(self.optimized) if k in subdirs)
            # the runtime library all of them share (built once), optimized in every
            # such project (one compile a release for all), as a timed module is
            + f"target_compile_options({runtime_library()} PRIVATE -O2)\n"
            + precompiled_runtime_header([self.programs[k].module for k in subdirs if k not in self.optimized]))
        build = self.root / "build"
        env = dict(os.environ)
        # a build type of no flags at all (the modules default to Release only when none is given)
        cfg = subprocess.run(["cmake", "-S", str(src), "-B", str(build),
                              f"-DCMAKE_PREFIX_PATH={self.install.cmake_prefix_path()}", find_once_option(),
                              "-DCMAKE_CXX_FLAGS=-Werror", "-DCMAKE_BUILD_TYPE=Tests",
                              ros2_wheels_option(self.ros2_env)],
                             capture_output=True, text=True, env=env)
        self.log = cfg.stdout + cfg.stderr
        if cfg.returncode != 0:
            return
        jobs = str(min(2, os.cpu_count() or 1))
        b = subprocess.run(["cmake", "--build", str(build), "-j", jobs, "--", "-k"],
                           capture_output=True, text=True, env=env)
        self.log += b.stdout + b.stderr

    def exe(self, key: str) -> Path:
        """The built executable of ``key`` (fails the test with the compiler's
        output if it did not build)."""
        self.build()
        program = self.programs[key]
        path = self.root / "build" / key / program.module
        if not path.exists():
            errors = [line for line in self.log.splitlines() if key in line or "error" in line]
            pytest.fail(f"{key} did not build:\n" + "\n".join(errors[-60:]), pytrace=False)
        return path


def session_builds(tmp_path_factory, yarp) -> Builds:
    """Every module of these tests, built against the matrix version ``yarp``:
    once for the run, shared by the pytest-xdist workers whose programs are
    the same (the folder is named by their digest: a worker that drew other
    programs, hypothesis' strings say, builds its own)."""
    from harness.programs import TIMED, build_programs

    b = Builds(Path(), yarp)
    for key, make in build_programs().items():
        b.add(key, make(), optimize=key == TIMED)
    digest = hashlib.sha256(repr(sorted(b.programs.items())).encode()).hexdigest()[:16]
    b.root = run_folder(tmp_path_factory, f"cpp_modules_{yarp.version}_{digest}")
    return b
