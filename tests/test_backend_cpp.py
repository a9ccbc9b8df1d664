"""The ``cpp`` backend: generated C++ modules, built with CMake against YARP
3.5 (``-Wall -Wextra -Werror``) and run against real YARP (and ROS 1), with
real producer and reader processes.

Every module the tests run is generated into one temporary folder and built
once per session (one CMake project that adds each module's own folder, so
each module's generated CMakeLists.txt is the one used). To keep the session
short, only the module whose timing is measured is optimized like a user's
default build (-O2, which also checks the warnings GCC finds only when it
optimizes); the others are built without optimization; all with -Wall -Wextra
-Werror. Hand-built programs
exercise every kind of source and every fault; every example and legacy
config that this backend supports is generated from the real file, built,
run and checked against what the IR says the message must hold.
"""
from __future__ import annotations

import json
import math
import os
import re
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import strategies as st

import middleware
from generated import without_runtime
from middleware import ROS1_PYTHON, Proc, RospySubscriber, YarpProducer, YarpReader
from ybg.backends import check_result, get_backend
from ybg.backends.cpp import CppBackend
from ybg.backends.cpp.escape import (CPP_KEYWORDS, cpp_comment, cpp_float, cpp_identifier, cpp_int,
                                     cpp_std_string, cpp_string, mangle)
from ybg.backends.cpp.lower import WIRE_ROS1, WIRE_YARP, LoweringError
from ybg.compiler import ir
from ybg.compiler.ir import (Converter, Counter, Default, ElementGroup, Field, Input, Literal, Mux,
                             MuxRef, Output, Policy, Program, Seconds, Struct, Timestamp, Timing,
                             TypeRef)

ROOT = Path(__file__).resolve().parents[1]
GOLDEN = Path(__file__).resolve().parent / "golden" / "cpp"
LEGACY_DIR = Path("/work/shared/legacy")
DEG = math.pi / 180.0

#: a string that breaks naive code generation in every way we know of
EVIL = ("q\"uo'te \\back\\slash\\\nnew line */ /* ''' \"\"\" # ; ??= ??/ ??' {{ x }} {% raw %} "
        "\t tab \0 nul ünïcødé 日本語 \u2028 \u202e bidi end\\")
FIXED_STRINGS = (
    EVIL, "", "'", '"', "\\", "*/", "/*", "//", "'''", "#", ";", "??", "???", "??/", "a\\\n",
    "\\x41g", "\\101", "é9", "\x01\x02", "\x7f", "tab\there", "\r\n", "trailing\\",
    "€ünï 日本", "\U0001F600", "0", "\x00", "a\x00b",
)


# --------------------------------------------------------------------------
# programs built by hand


def values_program() -> Program:
    """Two muxes into an untyped Bottle that uses every kind of source: an
    undeclared mux in degrees and a declared one (int32 x2, float64, string,
    bool) whose producer stamps its envelope. NaN is dropped."""
    return Program(
        module="values_bridge", source="values_bridge.ini",
        muxes=(
            Mux("arm", (Input("/t/arm:o"),), (Converter("deg_to_rad", scale=DEG),)),
            Mux("sens", (Input("/t/sens:o", layout=(ElementGroup("int32", 2), ElementGroup("float64", 1),
                                                    ElementGroup("string", 1), ElementGroup("bool", 1))),),
                (Converter("scale", scale=2.0, offset=1.0, start=2, stop=3),
                 Converter("half", scale=0.5, to_float=False, start=1, stop=2))),
        ),
        message=Struct((
            Field("label", Literal(("hello",), "string")),
            Field("count", Counter("int32")),
            Field("seconds", Seconds()),
            Field("stamp", Timestamp()),
            Field("envelope", Timestamp(clock="envelope", mux="sens")),
            Field("arm", MuxRef("arm")),
            Field("first", MuxRef("arm", index=0)),
            Field("ints", MuxRef("sens", 0, 2, splice=True, element_type="int32")),
            Field("ratio", MuxRef("sens", index=2)),
            Field("name", MuxRef("sens", index=3, element_type="string")),
            Field("flag", MuxRef("sens", index=4, element_type="bool")),
            Field("nested", Struct((
                Field("x", Literal((1.5,), "float64")),
                Field("k", Literal((1, 2, 3), "int64", True)),
                Field("none", Literal((), "float64", True)),
                Field("pt", MuxRef("arm", 0, 3, into_fields=("x", "y", "z"), into_types=("float64",) * 3)),
            ))),
            Field("big", Literal((2 ** 40,), "int64")),
            Field("u32", Literal((4000000000,), "uint32")),
            Field("f32", Literal((0.1,), "float32")),
            Field("none_seq", Default(), TypeRef("float64", "sequence")),
            Field("none_time", Default(), TypeRef("time")),
            Field("none_fixed", Default(), TypeRef("int32", "fixed", 3)),
        )),
        output=Output("yarp", "/values_bridge/out:o"),
        policy=Policy(on_nan="drop"))


def relay_program() -> Program:
    """The least a bridge does: one undeclared input, its elements out."""
    return Program(
        module="relay_bridge", source="relay_bridge.ini",
        muxes=(Mux("data", (Input("/t/src:o"),)),),
        message=Struct((Field("count", Counter("int32")), Field("values", MuxRef("data", splice=True)))),
        output=Output("yarp", "/relay_bridge/out:o"))


def newest_only_program() -> Program:
    """Two inputs, trigger = all, `queue = 1`: each input keeps only its newest Bottle."""
    return Program(
        module="newest_bridge", source="newest_bridge.ini",
        muxes=(Mux("data", (Input("/t/a:o"), Input("/t/b:o"))),),
        message=Struct((Field("count", Counter("int32")), Field("values", MuxRef("data", splice=True)))),
        output=Output("yarp", "/newest_bridge/out:o"),
        timing=Timing(queue=1))


def escape_program(strings=FIXED_STRINGS, module="escape_bridge") -> Program:
    """Every string as a literal field whose name is the string too (so it
    reaches comments), muxes named like keywords and reserved names, a config
    file name that needs escaping. Publishes on every tick."""
    return Program(
        module=module, source="we'ird \"name\"\n*/ ''' # ü.ini",
        muxes=(
            Mux("tick", (Input("/t/tick:o"),)),
            Mux("class", (Input("/t/class:o"),), verbose=True),
            Mux("a__b", (Input("/t/ab:o"),)),
            Mux("_Upper", (Input("/t/upper:o"),)),
        ),
        message=Struct(tuple(Field(s, Literal((s,), "string")) for s in strings)
                       + (Field("tick", MuxRef("tick", splice=True)),)),
        output=Output("yarp", f"/{module}/out:o"))


def hypothesis_strings(n: int = 50) -> list[str]:
    """``n`` distinct strings drawn by hypothesis (derandomized: the same
    on every run), each at most 40 characters of any kind."""
    drawn: list[str] = []

    @settings(max_examples=3 * n, phases=[Phase.generate], database=None, derandomize=True,
              deadline=None, suppress_health_check=list(HealthCheck))
    @given(st.text(max_size=40))
    def collect(s):
        drawn.append(s)

    collect()
    unique = [s for s in dict.fromkeys(drawn) if s not in FIXED_STRINGS]
    return unique[:n]


def ros1_input_program() -> Program:
    """A typed ROS 1 topic read through YARP: the point of a
    geometry_msgs/PointStamped (its header is not part of the mux)."""
    return Program(
        module="typed_ros_input", source="typed_ros_input.ini",
        muxes=(Mux("g", (Input("/ybg_goal", kind="ros1", layout=(ElementGroup("float64", 3),),
                               ros_type="geometry_msgs/PointStamped",
                               fields=("point.x", "point.y", "point.z"),
                               positions=((1, 0), (1, 1), (1, 2))),)),),
        message=Struct((Field("label", Literal(("xyz",), "string")), Field("p", MuxRef("g", splice=True)))),
        output=Output("yarp", "/typed_ros_input/out:o"), ros="ros1", distro="noetic")


HAND_PROGRAMS = {
    "values_bridge": values_program,
    "relay_bridge": relay_program,
    "escape_bridge": escape_program,
    "typed_ros_input": ros1_input_program,
}


# --------------------------------------------------------------------------
# configs


def _config_paths() -> list[Path]:
    return sorted((ROOT / "examples").glob("*.ini")) + sorted(LEGACY_DIR.glob("*.ini"))


def _compile(path: Path):
    from ybg.compiler.pipeline import compile_path
    return compile_path(path)


def supported_configs() -> list[Path]:
    """The example and legacy configs whose output kind and input kinds
    this backend handles."""
    out = []
    for p in _config_paths():
        r = _compile(p)
        prog = r.program
        if prog is None:
            continue
        if prog.output.kind in CppBackend.output_kinds and all(
                i.kind in CppBackend.input_kinds for m in prog.muxes for i in m.inputs):
            out.append(p)
    return out


SUPPORTED = supported_configs()


def config_program(path: Path) -> Program:
    from ybg.compiler.pipeline import compile_path
    r = check_result(compile_path(path), "cpp")
    assert r.program is not None, "\n".join(str(d) for d in r.diagnostics)
    return r.program


# --------------------------------------------------------------------------
# building: every module of the session in one CMake project


class Builds:
    """The modules of this test session, generated and built on first use."""

    def __init__(self, root: Path, install):
        self.root = root
        self.install = install
        self.programs: dict[str, Program] = {}
        self.optimized: set[str] = set()
        self.built = False
        self.log = ""

    def add(self, key: str, program: Program, optimize: bool = False) -> None:
        self.programs[key] = program
        if optimize:
            self.optimized.add(key)

    def refused(self, key: str) -> bool:
        """Its generated CMakeLists refuses this YARP (ROS 1 on YARP 4): it is
        left out of the one build and configured alone by the tests."""
        return _needs_ros(self.programs[key]) and self.install.key >= (4,)

    def configure_alone(self, key: str) -> subprocess.CompletedProcess:
        """Configures the module's own folder by itself, as its user would."""
        self.build()
        folder = self.root / "src" / key
        return subprocess.run(["cmake", "-S", str(folder), "-B", str(self.root / f"alone_{key}"),
                               f"-DCMAKE_PREFIX_PATH={self.install.cmake_prefix_path()}"],
                              capture_output=True, text=True)

    def build(self) -> None:
        if self.built:
            return
        self.built = True
        src = self.root / "src"
        src.mkdir(parents=True, exist_ok=True)
        backend = CppBackend()
        subdirs = []
        for key, program in sorted(self.programs.items()):
            folder = src / key
            folder.mkdir(exist_ok=True)
            for name, text in backend.render(program).items():
                (folder / name).write_text(text, encoding="utf-8")
            if not self.refused(key):
                subdirs.append(key)
        # YARP found once up front: each module's own find_package() then
        # costs nothing (found per folder, it takes 2 s each)
        (src / "CMakeLists.txt").write_text(
            "cmake_minimum_required(VERSION 3.16)\nproject(ybgc_cpp_tests CXX)\n"
            "find_package(YARP REQUIRED COMPONENTS os)\nfind_package(Threads REQUIRED)\n"
            + "".join(f"add_subdirectory({k})\n" for k in subdirs)
            + "".join(f"target_compile_options({self.programs[k].module} PRIVATE -O2)\n"
                      for k in sorted(self.optimized) if k in subdirs))
        build = self.root / "build"
        env = dict(os.environ)
        # a build type of no flags at all (the modules default to Release only when none is given)
        cfg = subprocess.run(["cmake", "-S", str(src), "-B", str(build), f"-DCMAKE_PREFIX_PATH={self.install.cmake_prefix_path()}",
                              "-DCMAKE_CXX_FLAGS=-Werror", "-DCMAKE_BUILD_TYPE=Tests"],
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


@pytest.fixture(scope="session")
def builds(tmp_path_factory, yarp) -> Builds:
    """Every module of these tests, built against the matrix version ``yarp``."""
    b = Builds(tmp_path_factory.mktemp(f"cpp_modules_{yarp.version}"), yarp)
    b.add("values_bridge", values_program())
    b.add("relay_bridge", relay_program(), optimize=True)
    b.add("newest_bridge", newest_only_program())
    b.add("escape_hypothesis", escape_program(FIXED_STRINGS + tuple(hypothesis_strings()), "escape_hypothesis"))
    b.add("typed_ros_input", ros1_input_program())
    for path in SUPPORTED:
        b.add(path.stem, config_program(path))
    return b


# --------------------------------------------------------------------------
# running


class Module(Proc):
    """A built module run with the given environment and arguments."""

    def __init__(self, env, exe: Path, *args, name=None, gate_output=False):
        super().__init__([exe, *args], env=env, name=name or exe.name, gate_output=gate_output)

    def wait_log(self, pattern: str, timeout: float = 60.0, count: int = 1) -> str:
        end = time.monotonic() + timeout
        while True:
            log = self.log_text()
            if len(re.findall(pattern, log)) >= count:
                return log
            if not self.alive:
                raise AssertionError(f"{self.name} exited ({self.returncode}); log:\n{log[-3000:]}")
            if time.monotonic() > end:
                raise AssertionError(f"no {pattern!r} (x{count}) in the log of {self.name}:\n{log[-3000:]}")
            time.sleep(0.02)

    def count(self, pattern: str) -> int:
        return len(re.findall(pattern, self.log_text()))

    def interrupt(self, sig=signal.SIGINT) -> tuple[int, float]:
        """Send ``sig`` to the module alone: (exit status, seconds to exit)."""
        t0 = time.monotonic()
        os.kill(self.pid, sig)
        try:
            rc = self.popen.wait(6.0)
        except subprocess.TimeoutExpired:
            rc = None
        elapsed = time.monotonic() - t0
        self.stop()
        return rc, elapsed


def ros_master_nodes(stack, topic: str) -> tuple[list, list]:
    """(publishers, subscribers) of ``topic`` that the ROS master knows."""
    import xmlrpc.client
    code, _, (pubs, subs, _) = xmlrpc.client.ServerProxy(stack.uri).getSystemState("/ybg_test")
    assert code == 1
    find = lambda rows: next((nodes for name, nodes in rows if name == topic), [])  # noqa: E731
    return find(pubs), find(subs)


def yarp_ports(server) -> set[str]:
    out = server.yarp("name", "list").stdout
    return set(re.findall(r"registration name (\S+)", out))


def exactly(a, b) -> bool:
    """Equal values, NaN equal to NaN, int and float told apart."""
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(exactly(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float):
        return (math.isnan(a) and math.isnan(b)) or a == b
    return type(a) is type(b) and a == b


# --------------------------------------------------------------------------
# escaping


def parse_cpp_literal(text: str) -> bytes:
    """The bytes of a C++ narrow string literal, by the language's rules
    (octal escapes take up to three digits, hex escapes every hex digit)."""
    assert text.startswith('"') and text.endswith('"'), text
    body = text[1:-1]
    out = bytearray()
    simple = {"n": 10, "t": 9, "r": 13, "\\": 92, '"': 34, "'": 39, "?": 63, "a": 7, "b": 8,
              "f": 12, "v": 11}
    i = 0
    while i < len(body):
        c = body[i]
        if c == '"':
            raise AssertionError(f"unescaped quote in {text}")
        if c != "\\":
            assert 0x20 <= ord(c) < 0x7F, f"raw {c!r} in {text}"
            out.append(ord(c))
            i += 1
            continue
        e = body[i + 1]
        if e in simple:
            out.append(simple[e])
            i += 2
        elif e in "01234567":
            m = re.match(r"[0-7]{1,3}", body[i + 1:])
            out.append(int(m.group(0), 8))
            i += 1 + len(m.group(0))
        elif e == "x":
            m = re.match(r"[0-9a-fA-F]+", body[i + 2:])
            out.append(int(m.group(0), 16))
            i += 2 + len(m.group(0))
        else:
            raise AssertionError(f"unknown escape \\{e} in {text}")
    return bytes(out)


@settings(max_examples=300, deadline=None)
@given(st.text())
def test_string_literal_round_trips(s):
    lit = cpp_string(s)
    assert parse_cpp_literal(lit) == s.encode("utf-8", "surrogatepass")
    assert "??" not in lit  # no trigraph-like sequence
    assert "\n" not in lit and "\r" not in lit
    assert all(0x20 <= ord(c) < 0x7F for c in lit)
    std = cpp_std_string(s)
    if "\0" in s:
        assert std == f"std::string({lit}, {len(s.encode('utf-8', 'surrogatepass'))})"
    else:
        assert std == lit


def test_string_literal_cases():
    assert cpp_string('a"b') == r'"a\"b"'
    assert cpp_string("a\\b") == r'"a\\b"'
    assert cpp_string("l1\nl2") == r'"l1\nl2"'
    assert cpp_string("*/") == '"*/"'
    assert cpp_string("??=") == r'"?\?="'
    assert cpp_string("???") == r'"?\?\?"'
    assert cpp_string("é1") == r'"\303\2511"'  # three digits: the 1 is not part of the escape
    assert cpp_string("\0") == r'"\000"'
    assert cpp_std_string("a\0b") == r'std::string("a\000b", 3)'
    assert cpp_string("\ud800") == r'"\355\240\200"'  # lone surrogate: still a literal
    # a comment never ends with a backslash (line splice) nor holds a line break
    for text in ("end\\", "a\nb", "??/", "*/"):
        c = cpp_comment(text)
        assert not c.endswith("\\") and "\n" not in c and "??" not in c


def test_identifiers():
    for word in ("class", "int", "and", "namespace", "main", "override", "NULL"):
        assert word in CPP_KEYWORDS
        with pytest.raises(ValueError):
            cpp_identifier(word)
    for bad in ("", "1x", "a-b", "a b", "__x", "a__b", "_Upper", "é"):
        with pytest.raises(ValueError):
            cpp_identifier(bad)
    assert cpp_identifier("arm") == "arm"
    assert cpp_identifier("_lower") == "_lower"
    assert mangle("mux_", "class") == "mux_class"
    assert mangle("mux_", "a__b") == "mux_a_b"
    assert mangle("mux_", "x-y z") == "mux_x_y_z"


@settings(max_examples=300, deadline=None)
@given(st.floats(allow_nan=False, allow_infinity=False))
def test_float_literals_are_exact(x):
    text = cpp_float(x)
    assert float(text) == x and math.copysign(1, float(text)) == math.copysign(1, x)
    assert "." in text or "e" in text


def test_numeric_literals():
    assert cpp_float(float("inf")) == "std::numeric_limits<double>::infinity()"
    assert cpp_float(float("-inf")) == "-std::numeric_limits<double>::infinity()"
    assert cpp_float(1.0) == "1.0"
    assert cpp_float(DEG) == "0.017453292519943295"
    assert cpp_int(-2 ** 63) == "(-9223372036854775807 - 1)"
    assert cpp_int(4000000000, 32) == "-294967296"  # wraps like the cast to int32
    assert cpp_int(255, 8) == "-1"
    with pytest.raises(TypeError):
        cpp_int(True)


def test_wire_tables_cover_every_element_type():
    assert set(WIRE_YARP) == set(WIRE_ROS1) == set(ir.BOTTLE_ELEMENT_TYPES)
    assert WIRE_YARP["uint32"] == "Int64" and WIRE_ROS1["uint32"] == "Int32"
    assert WIRE_ROS1["float32"] == "Float32" and WIRE_ROS1["bool"] == "Int8"


# --------------------------------------------------------------------------
# generation


def test_backend_registered():
    b = get_backend("cpp")
    assert isinstance(b, CppBackend)
    assert b.output_kinds == {"yarp", "ros1"} and b.input_kinds == {"yarp", "ros1"}


def render(program) -> dict[str, str]:
    return CppBackend().render(program)


GOLDEN_CASES = [(k, f) for k, f in HAND_PROGRAMS.items()] + [(p.stem, p) for p in SUPPORTED]


@pytest.mark.parametrize("key,what", GOLDEN_CASES, ids=[k for k, _ in GOLDEN_CASES])
def test_golden_files(key, what, update_goldens):
    program = config_program(what) if isinstance(what, Path) else what()
    files = render(program)
    assert set(files) == {f"{program.module}.cpp", "CMakeLists.txt", "ybgc_runtime.hpp", "ybgc_runtime.cpp"}
    files = without_runtime(files)  # the runtime's own golden files: tests/test_runtime.py
    folder = GOLDEN / key
    if update_goldens or os.environ.get("YBG_UPDATE_GOLDENS") == "1":
        folder.mkdir(parents=True, exist_ok=True)
        for old in folder.iterdir():
            old.unlink()
        for name, text in files.items():
            (folder / name).write_text(text, encoding="utf-8")
        return
    assert folder.is_dir(), f"no golden files for {key}: run pytest --update-goldens"
    assert sorted(p.name for p in folder.iterdir()) == sorted(files)
    for name, text in files.items():
        assert (folder / name).read_text(encoding="utf-8") == text, f"{key}/{name} differs from its golden file"


def test_generated_text_is_deterministic_and_marked():
    program = escape_program()
    files = render(program)
    assert files == render(escape_program())
    code = ("import sys, json; sys.path.insert(0, %r); from test_backend_cpp import escape_program, render; "
            "print(json.dumps(render(escape_program())))" % str(Path(__file__).parent))
    other = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env={**os.environ, "PYTHONHASHSEED": "12345", "PYTHONPATH": str(ROOT)}, check=True)
    assert json.loads(other.stdout) == files
    cpp = files["escape_bridge.cpp"]
    assert re.search(r"generated by ybgc [0-9.]+ from", cpp.splitlines()[0])
    assert "generated by ybgc from" in files["CMakeLists.txt"].splitlines()[0]
    for region in ("includes", "state", "compute", "message"):
        assert cpp.count(f"// ybgc:user-begin {region}\n") == 1
        assert cpp.count(f"// ybgc:user-end {region}\n") == 1
    assert all(ord(c) < 0x80 for c in cpp)  # every config string is escaped
    assert "mux_class" in cpp and "mux_a_b" in cpp and "mux_Upper" in cpp


def test_user_code_is_kept_on_regeneration(tmp_path):
    from ybg.writer import write_files
    program = relay_program()
    write_files(tmp_path, render(program))
    path = tmp_path / "relay_bridge.cpp"
    text = path.read_text()
    path.write_text(text.replace("    // ybgc:user-begin compute\n",
                                 "    // ybgc:user-begin compute\n    mux.data.clear();\n"))
    write_files(tmp_path, render(program))
    assert "    // ybgc:user-begin compute\n    mux.data.clear();\n" in path.read_text()


def test_unsupported_programs_are_refused():
    base = relay_program()
    with pytest.raises(LoweringError):
        render(Program(module="x", source="x.ini", muxes=base.muxes, message=base.message,
                       output=Output("ros2", "/t")))
    with pytest.raises(LoweringError):
        render(Program(module="x", source="x.ini", muxes=(Mux("m", (Input("/t", kind="ros2"),)),),
                       message=base.message, output=base.output))
    with pytest.raises(LoweringError):
        render(Program(module="x", source="x.ini", muxes=base.muxes,
                       message=Struct((Field("h", Default(), TypeRef("std_msgs/Header")),)),
                       output=base.output))


def test_ros1_input_fields_are_found_by_path():
    cpp = render(ros1_input_program())["typed_ros_input.cpp"]
    assert '{{"point.x", {1, 0}}, {"point.y", {1, 1}}, {"point.z", {1, 2}}}' in cpp


# --------------------------------------------------------------------------
# building


# the first of these builds every module of the session (two jobs, about two
# minutes on a quiet machine): more time than a single test gets
@pytest.mark.timeout(900)
@pytest.mark.parametrize("key", ["values_bridge", "relay_bridge", "newest_bridge", "escape_hypothesis",
                                 "typed_ros_input"] + [p.stem for p in SUPPORTED])
def test_builds_with_werror(builds, key):
    if builds.refused(key):
        # YARP 4 has no ROS 1: the module's CMakeLists says so, with the fix
        r = builds.configure_alone(key)
        said = " ".join(r.stderr.split())  # CMake wraps its messages
        assert r.returncode != 0
        assert "removed in YARP 4.0" in said and "`via = ros2`" in said, r.stderr[-2000:]
        return
    exe = builds.exe(key)
    assert os.access(exe, os.X_OK)


def test_help_and_bad_options(builds):
    exe = builds.exe("relay_bridge")
    env = middleware.base_env()
    r = subprocess.run([exe, "--help"], capture_output=True, text=True, env=env, timeout=60)
    assert r.returncode == 0
    for opt in ("--prefix P", "--rate HZ", "--timeout S", "--verbose", "--help"):
        assert opt in r.stdout
    assert "Generated by ybgc from relay_bridge.ini." in r.stdout
    for bad in (["--rate", "-1"], ["--rate=x"], ["--timeout", "0"], ["--prefix", "nope"], ["--bogus"],
                ["--rate"]):
        r = subprocess.run([exe, *bad], capture_output=True, text=True, env=env, timeout=60)
        assert r.returncode == 2, bad
        assert "usage:" in r.stderr


def test_install_rule(builds, tmp_path):
    builds.exe("relay_bridge")
    r = subprocess.run(["cmake", "--install", str(builds.root / "build" / "relay_bridge"), "--prefix", str(tmp_path)],
                       capture_output=True, text=True)
    assert r.returncode == 0, r.stdout + r.stderr
    assert os.access(tmp_path / "bin" / "relay_bridge", os.X_OK)


# --------------------------------------------------------------------------
# behaviour against a real yarpserver


def test_values_order_nesting_counter_and_stamps(builds, yarp_server):
    env = yarp_server.env
    exe = builds.exe("values_bridge")
    arm = [0.0, 90.0, 180.0, -45.0, 30.5, 1e-7]
    sens = [7, -3, 0.25, "abc", 1]
    with Module(env, exe) as module, \
            YarpReader(env, "/test/values:i", source="/values_bridge/out:o") as reader, \
            YarpProducer(env, "/t/arm:o") as p_arm, YarpProducer(env, "/t/sens:o") as p_sens:
        module.wait_log(r"connected /t/sens:o -> /values_bridge/sens/in0:i")
        module.wait_log(r"connected /t/arm:o -> /values_bridge/arm/in0:i")
        reader.wait_connected()
        p_arm.write(arm)
        time.sleep(0.3)
        assert reader.bottles == []  # trigger = all: sens has not delivered yet
        t_write = time.time()
        p_sens.write(sens, stamp=[5, 1234.5678])
        (got,) = reader.wait_for(1)
        d, types = got.data, got.types
        rad = [x * DEG + 0.0 for x in arm]
        assert d[0] == "hello"
        assert d[1] == 0  # counter
        assert abs(d[2] - t_write) < 2.0  # seconds
        sec, nsec = d[3]
        assert abs(sec + nsec / 1e9 - got.t) < 2.0 and 0 <= nsec < 1_000_000_000
        assert d[4] == [1234, 567800000]  # the envelope stamp of sens
        assert exactly(d[5], rad)
        assert all(abs(a - math.radians(b)) <= 1e-12 for a, b in zip(d[5], arm))
        assert exactly(d[6], rad[0])
        assert d[7:9] == [7, -1]  # -3 * 0.5 = -1.5, an int32 stays an integer: truncated to -1
        assert exactly(d[9], 0.25 * 2.0 + 1.0)
        assert d[10:12] == ["abc", 1]
        assert exactly(d[12], [1.5, [1, 2, 3], [], rad[0:3]])
        assert d[13:15] == [2 ** 40, 4000000000]
        assert exactly(d[15], 0.1)  # a float32 goes as a float64 on a YARP output
        assert d[16:] == [[], [0, 0], [0, 0, 0]]  # defaults of float64[], time, int32[3]
        assert types == ["string", "int32", "float64", ["int64", "int64"], ["int64", "int64"],
                         ["float64"] * 6, "float64", "int32", "int32", "float64", "string", "int32",
                         ["float64", ["int64"] * 3, [], ["float64"] * 3], "int64", "int64", "float64",
                         [], ["int64", "int64"], ["int32"] * 3]
        # the next message only when both inputs have new data; the counter counts messages
        p_arm.write([1.0] * 3)
        time.sleep(0.3)
        assert len(reader.bottles) == 1
        p_sens.write([1, 2, 3.0, "x", 0])
        (_, second) = reader.wait_for(2)
        assert second.data[1] == 1
        assert second.data[5] == [DEG, DEG, DEG]
        assert second.data[10:12] == ["x", 0]
        rc, elapsed = module.interrupt(signal.SIGINT)
    assert rc == 0 and elapsed < 2.0
    log = module.log_text()
    assert "input /t/arm:o: received 2, dropped 0, stale periods" in log
    assert "published 2 messages" in log


def test_producer_never_starts(builds, yarp_server):
    env = yarp_server.env
    with Module(env, builds.exe("values_bridge")) as module, \
            YarpReader(env, "/test/never:i", source="/values_bridge/out:o") as reader:
        reader.wait_connected()
        time.sleep(2.5)
        assert module.alive
        assert module.count(r"waiting for /t/arm:o") == 1
        assert module.count(r"waiting for /t/sens:o") == 1
        assert reader.bottles == []
        rc, elapsed = module.interrupt(signal.SIGTERM)
    assert rc == 0 and elapsed < 2.0
    log = module.log_text()
    assert "input /t/arm:o: received 0, dropped 0, stale periods 0" in log
    assert "published 0 messages" in log


def test_malformed_bottles_and_nan_are_dropped_and_counted(builds, yarp_server):
    env = yarp_server.env
    with Module(env, builds.exe("values_bridge")) as module, \
            YarpReader(env, "/test/drops:i", source="/values_bridge/out:o") as reader, \
            YarpProducer(env, "/t/arm:o") as p_arm, YarpProducer(env, "/t/sens:o") as p_sens:
        module.wait_log(r"connected /t/sens:o")
        module.wait_log(r"connected /t/arm:o")
        reader.wait_connected()
        # spaced out: an input keeps only its newest Bottle, so a burst could
        # reach the checks as its last Bottle only
        for producer, data in ((p_sens, [1, 2, 3.0, "a"]),          # 4 elements, expected 5
                               (p_sens, [1, "two", 3.0, "a", 1]),   # a string where an int32 goes
                               (p_sens, [1, 2, 3.0, "a", 2]),       # 2 is not a bool
                               (p_arm, [1.0, float("nan")]),        # on_nan = drop
                               (p_arm, [1.0, "x"]),                 # not a number
                               (p_arm, [1.0, [2.0]])):              # a list is not a number
            producer.write(data)
            time.sleep(0.15)
        time.sleep(0.3)
        assert reader.bottles == []
        p_arm.write([10.0, 20.0, 30.0])
        p_sens.write([4, 5, 6.0, "ok", 1])
        (got,) = reader.wait_for(1)
        assert got.data[10] == "ok" and exactly(got.data[5], [10.0 * DEG, 20.0 * DEG, 30.0 * DEG])
        time.sleep(0.3)
        assert len(reader.bottles) == 1
        assert module.alive
        assert module.count(r"input /t/sens:o: dropped a Bottle \(4 elements, expected 5\)") == 1
        assert module.count(r"input /t/arm:o: dropped a Bottle \(element 1 is NaN\)") == 1
        assert module.count(r"dropped a Bottle") == 2  # the first drop of each input only
        rc, _ = module.interrupt()
    assert rc == 0
    log = module.log_text()
    assert "input /t/sens:o: received 4, dropped 3, stale periods 0" in log
    assert "input /t/arm:o: received 4, dropped 3, stale periods 0" in log
    assert "published 1 messages" in log


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_signal_mid_stream(builds, yarp_server, sig):
    env = yarp_server.env
    with Module(env, builds.exe("relay_bridge")) as module, \
            YarpReader(env, "/test/sig:i", source="/relay_bridge/out:o") as reader, \
            YarpProducer(env, "/t/src:o", bottles=[[1.0, 2.0, 3.0]], rate=100):
        reader.wait_for(20)
        assert {"/relay_bridge/data/in0:i", "/relay_bridge/out:o"} <= yarp_ports(yarp_server)
        rc, elapsed = module.interrupt(sig)
        assert rc == 0, module.log_text()[-2000:]
        assert elapsed < 2.0
        assert not any(p.startswith("/relay_bridge") for p in yarp_ports(yarp_server))
    log = module.log_text()
    assert "totals:" in log and "Traceback" not in log
    assert re.search(r"published (\d+) messages", log) and int(re.search(r"published (\d+)", log).group(1)) >= 20


def test_producer_killed_and_restarted(builds, yarp_server):
    env = yarp_server.env
    producer = YarpProducer(env, "/t/src:o", bottles=[[5.0, 6.0]], rate=20)
    with Module(env, builds.exe("relay_bridge"), "--timeout", "0.5", "--prefix", "/relay2") as module, \
            YarpReader(env, "/test/restart:i", source="/relay_bridge/out:o") as reader:
        assert yarp_server.exists("/relay2/data/in0:i")
        producer.start()
        try:
            reader.wait_for(5)
            producer.kill()
            module.wait_log(r"input /t/src:o is stale \(no data for 0\.\d s\)", timeout=60)
            n = len(reader.bottles)
            time.sleep(1.0)
            assert len(reader.bottles) <= n + 1
            assert module.count(r"is stale") == 1  # said once, not once per cycle
            producer.start()
            reader.wait_for(n + 5, timeout=60)
            module.wait_log(r"input /t/src:o is fresh again")
            assert module.count(r"connected /t/src:o -> /relay2/data/in0:i") == 2
            counters = [b.data[0] for b in reader.bottles]
            assert counters == list(range(len(counters)))  # no message lost or repeated by the module
        finally:
            producer.stop()
        rc, _ = module.interrupt()
    assert rc == 0
    assert "stale periods 1" in module.log_text()


def rate_from_counters(bottles, skipped: int, nominal: float) -> tuple:
    """(lowest, highest) rate a fixed-rate module can have had, from the
    message counters (data[0]) and receive times of ``bottles``: between the
    message received soonest after its cycle in the first second and the
    same in the last second (a reader held up by the machine only delays a
    receive time, never advances it), the module published the counter
    difference and skipped at most ``skipped`` cycles."""
    per = max(1, int(nominal))
    def soonest(part):
        return min(part, key=lambda b: b.t - b.data[0] / nominal)
    a, b = soonest(bottles[:per]), soonest(bottles[-per:])
    span = b.t - a.t
    published = b.data[0] - a.data[0]
    return published / span, (published + skipped) / span


def test_fixed_rate_50hz_with_nan_passing(builds, yarp_server):
    """--rate 50: a true period over 4 s (200 cycles), whatever the input
    rate (200 Hz); NaN passes (on_nan = pass).
    Forced: the rate is read from the module's message counter against the
    receive times least delayed by the machine, and cycles it had to skip
    (counted in its totals) are allowed for, so a loaded machine only
    widens nothing: 49.5..50.5 Hz either way."""
    env = yarp_server.env
    with Module(env, builds.exe("relay_bridge"), "--rate", "50") as module, \
            YarpReader(env, "/test/rate:i", source="/relay_bridge/out:o") as reader, \
            YarpProducer(env, "/t/src:o", bottles=[[1.0, float("nan")]], rate=200):
        first = reader.wait_for(10, timeout=60)[-1]
        reader.wait(lambda: reader.bottles[-1].t - first.t >= 4.0, 60, "4 s of messages")
        got = list(reader.bottles)
        rc, _ = module.interrupt()
    assert rc == 0
    counters = [b.data[0] for b in got]
    assert counters == list(range(counters[0], counters[0] + len(got)))  # each message reached the reader
    skipped = int(re.search(r"skipped (\d+) cycles", module.log_text()).group(1))
    low, high = rate_from_counters(got[10:], skipped, 50.0)
    assert low <= 50.5 and high >= 49.5, (low, high, skipped)
    assert math.isnan(got[-1].data[2])  # on_nan = pass


def test_queue_one_keeps_the_newest_bottle_only(builds, yarp_server):
    """`queue = 1`: two stamped Bottles on a before any on b; the first is
    replaced (unused) and the one message pairs the newest of a with b's
    first (with the default queue both would be paired: test_differential)."""
    env = yarp_server.env
    with Module(env, builds.exe("newest_bridge")) as module, \
            YarpReader(env, "/test/newest:i", source="/newest_bridge/out:o") as reader, \
            YarpProducer(env, "/t/a:o") as a, YarpProducer(env, "/t/b:o") as b:
        reader.wait_connected(timeout=60)
        a.wait_outputs(1, timeout=60)
        b.wait_outputs(1, timeout=60)
        a.write([1.0], stamp=[1, 500.001])
        time.sleep(0.1)
        a.write([2.0], stamp=[2, 500.002])
        time.sleep(0.3)
        b.write([10.0], stamp=[1, 500.001])
        time.sleep(0.1)
        b.write([20.0], stamp=[2, 500.002])
        reader.wait_for(1)
        time.sleep(0.3)
        got = [r.data for r in reader.bottles]
        rc, _ = module.interrupt()
    assert rc == 0
    assert got == [[0, 2.0, 10.0]]
    assert re.search(r"input /t/a:o: received 2, dropped 0, stale periods \d+, unused 1", module.log_text())


def test_fixed_rate_skips_overrun_cycles(builds, yarp_server):
    """A module held up for a second at 50 Hz skips the cycles it missed and
    counts them; it does not catch up with a burst, and goes on afterwards.
    Forced: the module is stopped (SIGSTOP, as a machine under load would)
    for a time the test measures, d. The cycles missed (50 d, less the one
    it may publish late) must be counted as skipped, and published + skipped
    can never exceed the cycles of its life: a catch-up burst fails one or
    the other, whatever the machine's speed (other overruns only add skips)."""
    env = yarp_server.env
    with Module(env, builds.exe("relay_bridge"), "--rate", "50") as module, \
            YarpReader(env, "/test/skip:i", source="/relay_bridge/out:o") as reader, \
            YarpProducer(env, "/t/src:o", bottles=[[1.0]], rate=100, wait_connected=True) as producer:
        reader.wait_for(10, timeout=60)
        first_write = producer.sent[0]["t"]  # no message before the first Bottle
        os.kill(module.pid, signal.SIGSTOP)
        t0 = time.monotonic()
        time.sleep(1.0)
        d = time.monotonic() - t0
        os.kill(module.pid, signal.SIGCONT)
        reader.wait_for(len(reader.bottles) + 50, timeout=60)  # it goes on
        rc, _ = module.interrupt()
        end = time.time()
    assert rc == 0
    log = module.log_text()
    skipped = int(re.search(r"skipped (\d+) cycles", log).group(1))
    published = int(re.search(r"published (\d+) messages", log).group(1))
    assert skipped >= 50 * d - 2, (skipped, d)
    assert published + skipped <= 50 * (end - first_write) + 2, (published, skipped, end - first_write)


def test_stalled_consumer_does_not_stall_the_module(builds, yarp_server):
    """A reader that stops reading (SIGSTOP) does not hold the module up:
    the other reader keeps getting every message in order, and the module
    exits within 2 s and unregisters though a peer does not answer.
    Forced: the stalled reader stays stopped while the live one waits for
    300 messages of 4 kB (more than the stalled connection's buffers hold:
    a module that waited for it would publish none) and 200 more; counts
    of messages, not durations, so a slow machine only takes longer."""
    env = yarp_server.env
    big = [float(k) for k in range(500)]  # 4 kB messages: a stalled reader's buffers fill fast
    stalled = YarpReader(env, "/test/stalled:i", source="/relay_bridge/out:o")
    with Module(env, builds.exe("relay_bridge"), "--rate", "100") as module, \
            YarpReader(env, "/test/live:i", source="/relay_bridge/out:o") as live, \
            YarpProducer(env, "/t/src:o", bottles=[big], rate=50):
        stalled.start()
        try:
            stalled.wait_for(5, timeout=60)
            live.wait_for(1, timeout=60)
            os.kill(stalled.pid, signal.SIGSTOP)
            n = len(live.bottles)
            live.wait_for(n + 300, timeout=60)  # the stalled connection's buffers are full by now
            got = live.wait_for(n + 500, timeout=60)[n + 300:]
            counters = [b.data[0] for b in got]
            assert counters == sorted(set(counters)), "out of order"
            assert module.alive
            rc, elapsed = module.interrupt()
            assert rc == 0 and elapsed < 2.0
            # closing waits for the stalled peer at most a deadline, then unregisters the names
            assert not any(p.startswith("/relay_bridge") for p in yarp_ports(yarp_server))
        finally:
            os.kill(stalled.pid, signal.SIGCONT)
            stalled.stop()


#: the runtime's bound on unread Bottles (docs/runtime.md, "Reading"): a
#: reader more than this far behind skips the oldest unread
BACKLOG = 64


def test_a_burst_within_the_backlog_is_relayed_whole_and_in_order(builds, yarp_server):
    """Inputs are read strictly: bursts of 65 Bottles written back to back
    (as fast as the connection takes them, far faster than a robot port)
    all come out, in order, none overwritten or skipped; the totals say so.
    Forced: each burst is as long as the runtime may ever have to hold
    (while it handles one Bottle at most 64 are unread), and the next burst
    starts once every message of the last one is out, so that the result
    does not depend on how fast the machine is."""
    env = yarp_server.env
    bursts, size = 8, BACKLOG + 1
    n = bursts * size
    with Module(env, builds.exe("relay_bridge")) as module, \
            YarpReader(env, "/test/burst:i", source="/relay_bridge/out:o") as reader, \
            YarpProducer(env, "/t/src:o") as producer:
        reader.wait_connected(timeout=60)
        module.wait_log(r"connected /t/src:o -> /relay_bridge/data/in0:i", timeout=60)
        for b in range(bursts):
            producer.burst([[float(k)] for k in range(b * size, (b + 1) * size)])
            got = reader.wait_for((b + 1) * size, timeout=60)
        rc, _ = module.interrupt()
    assert rc == 0
    assert [b.data for b in got] == [[k, float(k)] for k in range(n)]
    assert re.search(rf"input /t/src:o: received {n}, dropped 0, stale periods \d+, unused 0",
                     module.log_text())


def hold_the_reader(module, reader, producer, width=16, limit=500) -> int:
    """Hold up the module's thread that reads (and publishes, event-driven)
    while its port goes on accepting: with the module's stdout held, write
    one Bottle at a time until that thread blocks printing one (--verbose);
    returns how many Bottles were written, the last one being the one held."""
    module.hold_output()
    k = 0
    while k < limit:
        producer.write([float(k)] + [0.5] * (width - 1))
        k += 1
        # its message comes out, or the thread is held printing it
        middleware._wait_until(lambda: len(reader.bottles) >= k or module.output_blocked(), 60,
                               f"message {k} or a held stdout", module)
        if len(reader.bottles) < k:
            module.wait_output_blocked()
            return k
    raise AssertionError(f"{module.name}: never blocked on its held stdout")


def test_a_reader_held_up_skips_the_oldest_and_says_so(builds, yarp_server):
    """A reader thread more than 64 Bottles behind skips the oldest unread
    Bottles so that it catches up, counts them as unused, and keeps the
    order of what it relays (docs/runtime.md, "Reading").
    Forced: the module's reading thread is held up (it blocks printing its
    --verbose values on a held stdout) while the producer writes a burst
    that the module's port accepts whole (strict writes, each acknowledged);
    then it is let go. Exactly the Bottles read before the hold and the
    last 65 come out: the ones in between were more than 64 behind."""
    env = yarp_server.env
    m = 300
    with Module(env, builds.exe("relay_bridge"), "--verbose", "--timeout", "60",
                gate_output=True) as module, \
            YarpReader(env, "/test/behind:i", source="/relay_bridge/out:o") as reader, \
            YarpProducer(env, "/t/src:o") as producer:
        reader.wait_connected(timeout=60)
        module.wait_log(r"connected /t/src:o -> /relay_bridge/data/in0:i", timeout=60)
        held = hold_the_reader(module, reader, producer)
        n = held + m
        producer.burst([[float(k)] for k in range(held, n)])
        assert module.output_blocked() and len(reader.bottles) == held - 1
        module.release_output()
        keep = list(range(held)) + list(range(n - BACKLOG - 1, n))
        got = reader.wait_for(len(keep), timeout=60)
        module.wait_log(r"\[data\] 0: %r\n" % float(n - 1), timeout=60)
        rc, _ = module.interrupt()
    assert rc == 0
    assert [b.data[0] for b in got] == list(range(len(keep)))  # the module's counter
    assert [b.data[1] for b in got] == [float(k) for k in keep]
    unused = n - len(keep)
    assert re.search(rf"input /t/src:o: received {n}, dropped 0, stale periods \d+, unused {unused}\n",
                     module.log_text()), module.log_text()[-1500:]
    assert f"published {len(keep)} messages" in module.log_text()


def test_escaped_strings_arrive_exactly(builds, yarp_server):
    env = yarp_server.env
    strings = list(FIXED_STRINGS) + hypothesis_strings()
    assert len(strings) >= 70
    with Module(env, builds.exe("escape_hypothesis")) as module, \
            YarpReader(env, "/test/esc:i", source="/escape_hypothesis/out:o") as reader, \
            YarpProducer(env, "/t/tick:o") as tick:
        module.wait_log(r"connected /t/tick:o")
        reader.wait_connected()
        tick.write([42.0])
        (got,) = reader.wait_for(1)
        rc, _ = module.interrupt()
    assert rc == 0
    assert got.data[:-1] == strings
    assert got.types[:-1] == ["string"] * len(strings)
    assert got.data[-1] == 42.0


def test_verbose_prints_values_after_conversion(builds, yarp_server):
    env = yarp_server.env
    with Module(env, builds.exe("values_bridge"), "--verbose") as module, \
            YarpReader(env, "/test/verbose:i", source="/values_bridge/out:o") as reader, \
            YarpProducer(env, "/t/arm:o") as p_arm, YarpProducer(env, "/t/sens:o") as p_sens:
        module.wait_log(r"connected /t/sens:o")
        module.wait_log(r"connected /t/arm:o")
        p_arm.write([90.0, 1e16, 0.0001])
        p_sens.write([7, -3, 0.25, "abc", 1])
        reader.wait_for(1)
        log = module.wait_log(r"\[sens\] 4: ")
        module.interrupt()
    assert f"[arm] 0: {math.pi / 2!r}\n" in log
    assert f"[arm] 1: {1e16 * DEG!r}\n" in log
    assert f"[arm] 2: {0.0001 * DEG!r}\n" in log
    assert "[sens] 0: 7\n[sens] 1: -1\n[sens] 2: 1.5\n[sens] 3: 'abc'\n[sens] 4: True\n" in log


# --------------------------------------------------------------------------
# every supported example and legacy config, from the real file


@dataclass
class Changing:
    """A value that changes from message to message: matched by its kind."""
    kind: str  # counter | time | seconds


def input_values(inp: Input, k: int) -> list:
    if inp.layout is None:
        return [10.0 * (k + 1) + 1.5 * j for j in range(8)]
    out = []
    for j, t in enumerate(inp.element_types):
        if t in ir.FLOAT_TYPES:
            out.append(5.0 * (k + 1) + 0.25 * j)
        elif t == "string":
            out.append(f"s{k}_{j}")
        elif t == "bool":
            out.append(j % 2)
        else:
            out.append(10 * k + j)
    return out


POINT = {"x": 0.5, "y": -1.25, "z": 2.0}


def mux_values(program: Program) -> dict[str, list]:
    """The mux values after conversion, for the values the test writes."""
    out = {}
    k = 0
    for m in program.muxes:
        values: list = []
        for inp in m.inputs:
            if inp.kind == "ros1":
                raw = [POINT["x"], POINT["y"], POINT["z"]]  # a geometry_msgs/Point, every leaf
            else:
                raw = input_values(inp, k)
            types = inp.element_types or ("float64",) * len(raw)
            for x, t in zip(raw, types):
                values.append(float(x) if t in ir.FLOAT_TYPES else (bool(x) if t == "bool" else x))
            k += 1
        for c in m.converters:
            if c.scale == 1.0 and c.offset == 0.0 and not c.to_float:
                continue
            stop = len(values) if c.stop is None else min(c.stop, len(values))
            for i in range(c.start, stop):
                x = values[i]
                if isinstance(x, str):
                    continue
                y = x * c.scale + c.offset
                values[i] = float(y) if c.to_float or isinstance(x, float) else int(y)
        out[m.name] = values
    return out


def _default(typ: TypeRef | None):
    if typ.array == "sequence":
        return []
    if typ.base in ("time", "duration"):
        return {"secs": 0, "nsecs": 0}
    v = 0.0 if typ.base in ir.FLOAT_TYPES else ("" if typ.base == "string" else 0)
    return [v] * typ.size if typ.array == "fixed" else v


def expected_tree(program: Program, values: dict[str, list], as_dict: bool):
    """What the message must hold: nested lists (a Bottle) or nested dicts
    (a rospy message), from the IR and the mux values."""
    def struct(s: Struct):
        items = [] if not as_dict else {}
        for f in s.fields:
            v = source(f.source, f)
            if as_dict:
                items[f.name] = v
            elif isinstance(f.source, MuxRef) and f.source.splice:
                items.extend(v)
            else:
                items.append(v)
        return items

    def source(src, f):
        if isinstance(src, Struct):
            return struct(src)
        if isinstance(src, Literal):
            vals = [int(v) if isinstance(v, bool) and not as_dict else v for v in src.values]
            return vals if src.is_list else vals[0]
        if isinstance(src, MuxRef):
            v = values[src.mux]
            if src.index is not None:
                return v[src.index]
            if src.into_fields is not None:
                part = v[src.start:src.start + len(src.into_fields)]
                return dict(zip(src.into_fields, part)) if as_dict else part
            return v[src.start:src.stop]
        if isinstance(src, Counter):
            return Changing("counter")
        if isinstance(src, Timestamp):
            return Changing("time")
        if isinstance(src, Seconds):
            return Changing("seconds")
        if isinstance(src, Default):
            d = _default(f.type)
            return [d["secs"], d["nsecs"]] if isinstance(d, dict) and not as_dict else d
        raise AssertionError(src)

    return struct(program.message)


def matches(want, got, now: float, path="msg") -> None:
    if isinstance(want, Changing):
        if want.kind == "counter":
            assert isinstance(got, int) and got >= 0, (path, got)
        elif want.kind == "seconds":
            assert isinstance(got, float) and abs(got - now) < 30, (path, got)
        else:
            sec, nsec = (got["secs"], got["nsecs"]) if isinstance(got, dict) else got
            assert abs(sec + nsec / 1e9 - now) < 30 and 0 <= nsec < 10 ** 9, (path, got)
        return
    if isinstance(want, dict):
        assert isinstance(got, dict) and set(want) <= set(got), (path, got)
        for k in want:
            matches(want[k], got[k], now, f"{path}.{k}")
        return
    if isinstance(want, list):
        assert isinstance(got, list) and len(got) == len(want), (path, want, got)
        for i, (w, g) in enumerate(zip(want, got)):
            matches(w, g, now, f"{path}[{i}]")
        return
    if isinstance(want, float):
        assert isinstance(got, float) and (got == want or (math.isnan(got) and math.isnan(want))), \
            (path, want, got)
        return
    assert got == want, (path, want, got)


ROSPY_PUBLISHER = r"""
import json, sys, time
import rospy, roslib.message
cfg = json.loads(sys.argv[1])
cls = roslib.message.get_message_class(cfg["type"])
rospy.init_node("ybg_cpp_test_pub", anonymous=True, disable_signals=True)
pub = rospy.Publisher(cfg["topic"], cls, queue_size=10)
msg = cls(**cfg["fields"])
while True:
    pub.publish(msg)
    time.sleep(1.0 / cfg["rate"])
"""


def _ros1_type_known(msg_type: str | None) -> bool:
    if not msg_type or "/" not in msg_type:
        return False
    pkg, name = msg_type.split("/")
    return (middleware.ROS1_MSG_ROOT / pkg / "msg" / f"{name}.msg").exists()


def _needs_ros(program: Program) -> bool:
    return program.output.kind == "ros1" or any(i.kind == "ros1" for m in program.muxes for i in m.inputs)


def assert_refuses_ros1(builds, key: str, server) -> None:
    """A ROS 1 module where YARP has no ROS 1: YARP 4 refuses it at configure
    time; YARP 3.10 to 3.12 build it, and it stops at start saying why
    (without YARP's yarp-ros plugins) instead of publishing into nothing."""
    if builds.refused(key):
        r = builds.configure_alone(key)
        assert r.returncode != 0 and "`via = ros2`" in " ".join(r.stderr.split()), r.stderr[-2000:]
        return
    r = subprocess.run([builds.exe(key)], env=server.env, capture_output=True, text=True, timeout=60)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "cannot use ROS 1 topics" in r.stdout + r.stderr and "yarp-ros plugins" in r.stdout + r.stderr


@pytest.mark.parametrize("path", SUPPORTED, ids=[p.stem for p in SUPPORTED])
def test_config_end_to_end(path, builds, request):
    """The module generated from the real config reads real producers and
    publishes exactly what the config asks for; SIGINT ends it cleanly."""
    program = config_program(path)
    if _needs_ros(program) and not builds.install.has_ros1:
        assert_refuses_ros1(builds, path.stem, request.getfixturevalue("yarp_server"))
        return
    exe = builds.exe(path.stem)
    stack = request.getfixturevalue("yarp_ros_server" if _needs_ros(program) else "yarp_server")
    env = stack.env
    out = program.output
    ros_dict = out.kind == "ros1" and _ros1_type_known(out.msg_type)
    want = expected_tree(program, mux_values(program), as_dict=ros_dict)
    peers = []
    try:
        module = Module(env, exe, name=path.stem).start()
        peers.append(module)
        if ros_dict:
            consumer = RospySubscriber(env, out.name, out.msg_type).start()
        elif out.kind == "ros1":
            consumer = YarpReader(env, "/test/cfg:i", source=f"{out.name}+@{out.node}").start()
        elif out.connect_to:
            consumer = YarpReader(env, out.connect_to).start()  # the module connects to it
        else:
            consumer = YarpReader(env, "/test/cfg:i", source=out.name).start()
        peers.append(consumer)
        k = 0
        for m in program.muxes:
            for inp in m.inputs:
                if inp.kind == "ros1":
                    peers.append(Proc([ROS1_PYTHON, "-c", ROSPY_PUBLISHER, json.dumps(
                        {"topic": inp.name, "type": "geometry_msgs/Point", "fields": POINT, "rate": 20})],
                        env=env, name=f"rospy_pub_{path.stem}").start())
                else:
                    peers.append(YarpProducer(env, inp.name, bottles=[input_values(inp, k)], rate=20).start())
                k += 1
        got = consumer.wait_for(3, timeout=30)
        last = got[-1]
        data = last.msg if ros_dict else last.data
        matches(want, data, time.time())
        counters = [g.msg["header"]["seq"] if ros_dict else None for g in got]
        if ros_dict and "header" in want and isinstance(want["header"].get("seq"), Changing):
            assert counters == sorted(counters) and len(set(counters)) == len(counters)
        rc, elapsed = module.interrupt(signal.SIGINT)
        assert rc == 0 and elapsed < 2.0, module.log_text()[-2000:]
        log = module.log_text()
        assert "totals:" in log
        assert not re.search(r"published 0 messages", log)
        if not _needs_ros(program):
            assert not any(p.startswith(f"/{program.module}") for p in yarp_ports(stack))
    finally:
        for p in reversed(peers):
            p.stop()


def test_thesis_rviz_scenario_through_ros1(builds, yarp_ros_server):
    """The thesis' figure 5 (legacy config, verbatim): the arm in degrees on a
    YARP port becomes a sensor_msgs/JointState with names, radians,
    frame_id and empty velocity/effort that a rospy subscriber receives."""
    path = LEGACY_DIR / "thesis_figure5_rviz.ini"
    assert path in SUPPORTED
    env = yarp_ros_server.env
    degrees = [0.0, 15.0, 30.0, 45.0, 60.0, 90.0, -90.0, 180.0]
    with Module(env, builds.exe(path.stem)) as module, \
            RospySubscriber(env, "/yarp/joint_states") as sub, \
            YarpProducer(env, "/vizzySim/left_shoulder_arm/state:o", bottles=[degrees], rate=30):
        msgs = sub.wait_for(10, timeout=30)
        assert "/yarp/thesis_figure5_rviz" in ros_master_nodes(yarp_ros_server, "/yarp/joint_states")[0]
        rc, elapsed = module.interrupt()
    assert rc == 0 and elapsed < 2.0
    # closed: withdrawn from the ROS master too (YARP 3.5 leaves it registered)
    assert "/yarp/thesis_figure5_rviz" not in ros_master_nodes(yarp_ros_server, "/yarp/joint_states")[0]
    m = msgs[-1].msg
    assert m["name"] == ["l_shoulder_scapula_joint", "l_shoulder_flection_joint", "l_shoulder_abduction_joint",
                         "l_shoulder_rotation_joint", "l_elbow_flection_joint", "l_forearm_pronation_joint",
                         "l_wrist_abduction_joint", "l_wrist_flection_joint"]
    assert m["position"] == [x * DEG for x in degrees]
    assert all(abs(a - math.radians(b)) <= 1e-12 for a, b in zip(m["position"], degrees))
    assert m["velocity"] == [] and m["effort"] == []  # empty float64[] arrive (a defect of the original)
    assert m["header"]["frame_id"] == "0"
    seqs = [x.msg["header"]["seq"] for x in msgs]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
    stamps = [x.msg["header"]["stamp"]["secs"] + x.msg["header"]["stamp"]["nsecs"] / 1e9 for x in msgs]
    assert stamps == sorted(stamps) and abs(stamps[-1] - msgs[-1].t) < 2.0
    assert "[mux1] 7: " in module.log_text()  # verbose = true in the config


def test_typed_ros1_topic_input(builds, yarp_ros_server):
    """A ROS 1 topic of a known type: the fields named by the config are taken
    from the message YARP reads (header.seq, stamp and frame_id are not)."""
    env = yarp_ros_server.env
    fields = {"header": {"frame_id": "cam"}, "point": {"x": 1.5, "y": -2.0, "z": 1e-3}}
    script = ROSPY_PUBLISHER.replace("msg = cls(**cfg[\"fields\"])", (
        "from std_msgs.msg import Header\nfrom geometry_msgs.msg import Point\n"
        "msg = cls(header=Header(frame_id=cfg['fields']['header']['frame_id']), "
        "point=Point(**cfg['fields']['point']))"))
    assert script != ROSPY_PUBLISHER
    with Module(env, builds.exe("typed_ros_input")) as module, \
            YarpReader(env, "/test/typed:i", source="/typed_ros_input/out:o") as reader, \
            Proc([ROS1_PYTHON, "-c", script, json.dumps({"topic": "/ybg_goal", "type": "geometry_msgs/PointStamped",
                                                         "fields": fields, "rate": 20})], env=env, name="rospy_pub_goal"):
        got = reader.wait_for(3, timeout=30)
        assert "/typed_ros_input/g_in0" in ros_master_nodes(yarp_ros_server, "/ybg_goal")[1]
        rc, elapsed = module.interrupt()
        assert "/typed_ros_input/g_in0" not in ros_master_nodes(yarp_ros_server, "/ybg_goal")[1]
    assert rc == 0 and elapsed < 2.0
    assert got[-1].data == ["xyz", 1.5, -2.0, 1e-3]
    assert "dropped" not in module.log_text().split("totals:")[0]


def test_no_name_server(builds, tmp_path):
    """Without a reachable yarpserver the module says so and exits 1."""
    env = middleware.base_env(tmp_path)
    env.update(middleware.yarp_env(tmp_path / "yarp", middleware.free_port()))
    exe = builds.exe("relay_bridge")
    t0 = time.monotonic()
    r = subprocess.run([exe], capture_output=True, text=True, env=env, timeout=30)
    assert r.returncode == 1
    assert "cannot reach the YARP name server" in r.stdout
    assert time.monotonic() - t0 < 10


def test_hold_policy_and_trigger_any(builds, yarp_server):
    """examples/mixed_types_yarp.ini (on_stale = hold, trigger = any):
    nothing before every input delivered once; then a message for each new
    Bottle of any input, with the last values of a stale one (said once).
    Forced: each joints Bottle carries its own number, so "one message per
    Bottle" is read from the messages (every number once, in order), not
    from how many arrived in a wall-clock window."""
    path = ROOT / "examples" / "mixed_types_yarp.ini"
    program = config_program(path)
    assert program.policy.on_stale == "hold" and program.timing.trigger == "any"
    env = yarp_server.env
    joints = [[100.0 * k + j for j in range(6)] for k in range(600)]  # 30 s at 20 Hz
    with Module(env, builds.exe(path.stem), "--timeout", "0.5") as module, \
            YarpReader(env, "/test/hold:i", source="/hand_status/out:o") as reader, \
            YarpProducer(env, "/icub/left_hand/status:o") as status, \
            YarpProducer(env, "/icub/left_hand/joints:o", bottles=joints, rate=20):
        module.wait_log(r"connected /icub/left_hand/status:o", timeout=60)
        module.wait_log(r"connected /icub/left_hand/joints:o", timeout=60)
        time.sleep(1.0)
        assert reader.bottles == []  # hold: not before every input delivered once
        status.write([1, 0, 1])
        reader.wait_for(5, timeout=60)
        module.wait_log(r"input /icub/left_hand/status:o is stale \(no data for 0\.\d s\)", timeout=60)
        n = len(reader.bottles)
        got = reader.wait_for(n + 20, timeout=60)[n:]
        rc, _ = module.interrupt()
    assert rc == 0
    numbers = [round(b.data[1][0] / DEG / 100.0) for b in got]
    assert numbers == list(range(numbers[0], numbers[0] + len(got)))  # one per joints Bottle
    for b, k in zip(got, numbers):
        assert b.data == ["left_hand", [x * DEG for x in joints[k]], 1, [1, 0, 1]]
    assert module.count(r"is stale") == 1
