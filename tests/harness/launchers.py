"""How each backend's module is built and started, for the behaviour tests
(harness/behaviour.py) and every test that runs a module of each backend:
a ``Launcher`` per backend (the ``modules`` fixture of a test class).

    Launcher            the interface: .program(key), .module(key, env, *args),
                        .environment(env), .refuses_ros1(key, env), .subscriber(env, program)
    CppModules(builds, request=None)   the executables of a Builds
    PyModules(folder)   the generated module run by the venv's Python
    Ros2Modules(folder, domain)   the generated rclpy node, its command line as ROS parameters
    write_module(program, folder), write_node(program, folder)   a py module, a ros2 node
                        and the runtime beside it; the path of the module
    require_message_packages(program)   fail unless rclpy imports the node's message packages
"""
from __future__ import annotations

import importlib.util
import subprocess
from pathlib import Path

import pytest

from harness.build import Builds
from harness.env import VENV_PYTHON, active_yarp
from harness.generated import module_file, write_generated
from harness.module import Module
from harness.programs import PROGRAMS, ROS1_PROGRAMS, config_program
from harness.ros2 import ros2_environment, subscriber_for
from ybg.compiler.ir import Program

class Launcher:
    """How a backend's module is built and started; each backend's test
    module gives one through its ``modules`` fixture."""

    backend = ""
    #: {what: why}: a behaviour this backend is known not to have yet; the
    #: test says so (xfail) after every other assertion of it passed
    known_gaps: dict[str, str] = {}

    def program(self, key) -> Program:
        """The Program of ``key`` (a PROGRAMS key, or a config's Path)."""
        if isinstance(key, Path):
            return config_program(key, self.backend)
        return {**PROGRAMS, **ROS1_PROGRAMS}[key]()

    def environment(self, env: dict) -> dict:
        """``env`` with what this backend's module needs besides YARP."""
        return env

    def module(self, key, env: dict, *args: str, gate_output: bool = False) -> Module:
        """The module of ``key`` with the generic command line ``args``
        (``--prefix P``, ``--rate HZ``, ``--timeout S``, ``--verbose``),
        not started yet."""
        raise NotImplementedError

    def refuses_ros1(self, key, env: dict) -> None:
        """A ROS 1 module where YARP has no ROS 1 (3.10 and later): it stops
        at start saying why (exit 1), instead of publishing into nothing:
        without YARP's yarp-ros plugins (3.10 to 3.12), or with the fix
        (YARP 4, which has none)."""
        r = subprocess.run(self.module(key, env).argv, env=env, capture_output=True, text=True, timeout=60)
        out = r.stdout + r.stderr
        assert r.returncode == 1, out
        assert "cannot use ROS 1 topics" in out, out
        if active_yarp().key >= (4,):
            assert "removed in YARP 4.0" in out and "`via = ros2`" in out, out
        else:
            assert "yarp-ros plugins" in out, out

    def subscriber(self, env: dict, program: Program):
        """A subscriber of the program's ROS 2 output (ros2 only)."""
        raise NotImplementedError(f"the {self.backend} backend has no ROS 2 output")


# --------------------------------------------------------------------------
# cpp


class CppModules(Launcher):
    """The built executable of a program, run with its command line (a
    module that publishes to ROS 2: in the test's ROS 2 domain)."""

    backend = "cpp"

    def __init__(self, builds: Builds, request=None):
        self.builds = builds
        self.request = request

    def environment(self, env: dict) -> dict:
        return ros2_environment(env, self.request.getfixturevalue("ros2_domain"))

    def subscriber(self, env: dict, program: Program):
        return subscriber_for(env, program)

    @staticmethod
    def key(key) -> str:
        return key.stem if isinstance(key, Path) else key

    def program(self, key) -> Program:
        return self.builds.programs[self.key(key)]

    def module(self, key, env, *args, gate_output=False) -> Module:
        exe = self.builds.exe(self.key(key))
        return Module([exe, *args], env=env, name=exe.name, gate_output=gate_output)

    def refuses_ros1(self, key, env) -> None:
        """YARP 4 refuses a ROS 1 module at configure time; YARP 3.10 to 3.12
        build it, and it stops at start saying why (without YARP's
        yarp-ros plugins)."""
        if self.builds.refused(self.key(key)):
            r = self.builds.configure_alone(self.key(key))
            assert r.returncode != 0 and "`via = ros2`" in " ".join(r.stderr.split()), r.stderr[-2000:]
            return
        super().refuses_ros1(key, env)


# --------------------------------------------------------------------------
# py


def write_module(program, folder: Path) -> Path:
    """The module and its runtime written in ``folder``; the module's path."""
    from ybg.backends.py import PyBackend

    files = PyBackend().render(program)
    write_generated(folder, files)
    return folder / module_file(files, ".py")[0]


class PyModules(Launcher):
    """The generated module (its runtime beside it) in a folder of its own,
    run as a script by the venv's Python."""

    backend = "py"

    def __init__(self, folder: Path):
        self.folder = folder

    def module(self, key, env, *args, gate_output=False) -> Module:
        program = self.program(key)
        path = write_module(program, self.folder / program.module)
        return Module([VENV_PYTHON, path, *args], env=env, name=program.module, gate_output=gate_output)


# --------------------------------------------------------------------------
# ros2


def require_message_packages(program: Program) -> None:
    """Fail, saying how to get them, when rclpy cannot import the node's
    message packages: tf2_msgs has no PyPI wheel, scripts/setup.sh builds it
    from msgpkgs/ (scripts/build_msgpkg.sh) into the venv."""
    from ybg.backends.ros2.lower import used_packages

    missing = [p for p in used_packages(program) if importlib.util.find_spec(p) is None]
    if missing:
        pytest.fail(f"{', '.join(missing)} does not import in this Python: run scripts/setup.sh, which "
                    "builds the message packages PyPI has no wheel for (scripts/build_msgpkg.sh msgpkgs/...)",
                    pytrace=False)


def write_node(program: Program, folder: Path) -> Path:
    """The node and its runtime written in ``folder``; the node's path."""
    from ybg.backends.ros2 import Ros2Backend

    files = Ros2Backend().render(program)
    folder.mkdir(parents=True, exist_ok=True)
    write_generated(folder, files)
    return folder / module_file(files, ".py")[0]


def ros_args(args) -> list[str]:
    """A module's command line (--prefix P, --rate HZ, --timeout S,
    --verbose) as the node's ROS parameters."""
    out: list[str] = []
    args = list(args)
    while args:
        opt = args.pop(0)
        if opt == "--verbose":
            out += ["-p", "verbose:=true"]
        elif opt == "--prefix":
            out += ["-p", f"prefix:={args.pop(0)}"]
        elif opt in ("--rate", "--timeout"):
            out += ["-p", f"{opt[2:]}:={float(args.pop(0))!r}"]
        else:
            raise ValueError(f"no ROS parameter for {opt}")
    return ["--ros-args", *out] if out else []


class Ros2Modules(Launcher):
    """The generated node (its runtime beside it) in a folder of its own,
    run as a script by the venv's Python, in the test's ROS 2 domain."""

    backend = "ros2"

    def __init__(self, folder: Path, domain):
        self.folder = folder
        self.domain = domain

    def environment(self, env: dict) -> dict:
        return ros2_environment(env, self.domain)

    def module(self, key, env, *args, gate_output=False) -> Module:
        program = self.program(key)
        require_message_packages(program)
        path = write_node(program, self.folder / program.module)
        return Module([VENV_PYTHON, path, *ros_args(args)], env=env, name=f"{program.module}_node",
                      gate_output=gate_output)

    def subscriber(self, env, program):
        return subscriber_for(env, program)
