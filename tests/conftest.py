"""Shared pytest setup: real middleware fixtures (the helpers are the
harness's, tests/harness/), the YARP version matrix, the ``--update-goldens``
option, the ``slow`` marker, a default timeout and hypothesis' profile
(harness.properties: derandomized unless ``YBG_HYPOTHESIS_PROFILE=fuzz``).

The YARP matrix: every test that uses the ``yarp`` fixture (directly, or
through ``yarp_server``, or through a fixture of its own that asks for
``yarp``) runs once per YARP version of ``--yarp`` (default: every version of
``harness.env.MATRIX``: PyPI's 3.5, 3.12.3, 4.0.0), with the test id
``[yarp<version>]``. Tests of YARP's ROS 1 support (``yarp_ros_server``) run
on the versions that have it (before 3.10). A version that is not built is a
skip saying how to build it, except in CI (``CI`` set), where it fails.

Fixtures
    yarp              session scope, one per matrix version: the YarpInstall,
                      made the active one (harness.env.use_yarp) for the test.
    yarp_server       function scope: a YarpServer on 127.0.0.1:<free port>;
                      use ``yarp_server.env`` for every YARP process.
    yarp_ros_server   module scope: roscore + ``yarpserver --ros`` + the type
                      server (every Debian message type); a YarpRosStack with
                      ``.env`` (YARP and ROS_MASTER_URI/ROS_IP), ``.uri``, ``.port``.
    ros2_domain       function scope: a Ros2Domain with its own ROS_DOMAIN_ID;
                      use ``ros2_domain.env`` for every ROS 2 process.
    mw                function scope: yarp_server and ros2_domain in one
                      environment, ``.env`` (and ``.yarp``, ``.ros2``); a test
                      module with an ``mw`` of its own uses its own.
    node_logs         the logs of the harness's Nodes (harness.module.Node) a
                      test started, printed after it (shown when it fails);
                      a test module asks for it with
                      ``pytest.mark.usefixtures("node_logs")``.
    update_goldens    bool, true with ``--update-goldens``: golden-file tests
                      rewrite their expected files instead of comparing.
    ybgc              the ybgc command run in-process in ``tmp_path``:
                      ``ybgc(*args) -> (exit status, stderr)``.
    builds            session scope, one per matrix version: every C++ module
                      of the tests (harness.programs.build_programs) in one
                      CMake project, built on first use, once for the run
                      (harness.build.session_builds).
"""
import os
import resource
from types import SimpleNamespace

import pytest

# the harness's asserts say what they compared, as the tests' own do
pytest.register_assert_rewrite("harness")

from harness import env, procs, properties  # noqa: E402
from harness.build import Builds, session_builds, use_ccache  # noqa: E402
from harness.module import Node  # noqa: E402
from harness.ros1 import YarpRosStack  # noqa: E402
from harness.ros2 import Ros2Domain, ros2_environment  # noqa: E402
from harness.yarp import YarpServer, require_yarp  # noqa: E402

# hypothesis' profile (harness.properties): ci, derandomized, unless
# YBG_HYPOTHESIS_PROFILE says fuzz; loaded before any test module makes its
# @settings, which inherit it
properties.load()

#: where a test's CPU count starts (pytest_runtest_setup)
_CPU_AT_SETUP = pytest.StashKey[float]()

DEFAULT_TIMEOUT = 180  # seconds per test, when pytest-timeout is installed
#: the seconds of a test that may build the session's C++ modules of a YARP
#: release (the first to ask one of them builds them all: about a minute on
#: a quiet machine, with an empty ccache; minutes on a busy one)
BUILD_TIMEOUT = 900
#: the fixtures that give the session's modules (harness.build.session_builds)
BUILD_FIXTURES = {"builds", "cpp_builds"}


def pytest_addoption(parser):
    parser.addoption("--update-goldens", action="store_true", default=False,
                     help="rewrite the golden files instead of comparing against them")
    parser.addoption("--yarp", default=os.environ.get("YBG_YARP_MATRIX", ",".join(env.MATRIX)),
                     help="comma-separated YARP versions to run the YARP-facing tests on "
                          "(default: %(default)s; also YBG_YARP_MATRIX)")


def matrix_versions(config) -> list:
    return [v.strip() for v in config.getoption("--yarp").split(",") if v.strip()]


def pytest_generate_tests(metafunc):
    if "yarp" not in metafunc.fixturenames:
        return
    versions = matrix_versions(metafunc.config)
    if "yarp_ros_server" in metafunc.fixturenames:
        versions = [v for v in versions if env.yarp_install(v).has_ros1]
    oldest = metafunc.definition.get_closest_marker("yarp_min")
    if oldest is not None:  # a tool that older YARP releases lack: those are not in the matrix
        versions = [v for v in versions if env.yarp_install(v).key >= tuple(oldest.args[0])]
    if metafunc.definition.get_closest_marker("yarp_ends") is not None and len(versions) > 2:
        # the oldest and the newest release: a release between them is shown by the
        # version tests (tests/test_yarp_versions.py) and the runtime's own tests
        ordered = sorted(versions, key=lambda v: env.yarp_install(v).key)
        versions = [v for v in versions if v in (ordered[0], ordered[-1])]
    metafunc.parametrize("yarp", versions, indirect=True, scope="session",
                         ids=[f"yarp{v}" for v in versions])


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config):
    use_ccache()
    config.addinivalue_line("markers", "yarp_min(version): run on the YARP releases of the matrix "
                                       "from `version` (a tuple) on only")
    config.addinivalue_line("markers", "yarp_ends: run on the oldest and the newest YARP release of the "
                                       "matrix only (docs/yarp-versions.md)")
    config.addinivalue_line("markers", "builds: the test may build the session's C++ modules through "
                                       "request.getfixturevalue (a build's timeout, as a test with the fixture)")
    config.addinivalue_line("markers", "slow: a long test (real middleware, seconds or more); "
                                       "deselect with -m 'not slow'")
    # A default per-test timeout, so that a hung middleware process cannot
    # hang the whole run; --timeout, PYTEST_TIMEOUT or an ini value win.
    if config.pluginmanager.hasplugin("timeout"):
        if (config.getoption("timeout", None) is None and not os.environ.get("PYTEST_TIMEOUT")
                and not config.getini("timeout")):
            config.option.timeout = DEFAULT_TIMEOUT


def pytest_collection_modifyitems(config, items):
    """A test that may build the session's modules has the build's time,
    unless it sets its own. Under hypothesis' ci profile, a property test
    that would draw other examples on another run is an error."""
    from hypothesis import settings

    if settings.get_current_profile_name() == "ci":
        random = [item.nodeid for item in items
                  if not properties.deterministic(getattr(getattr(item, "obj", None),
                                                          "_hypothesis_internal_use_settings", settings.default))]
        if random:
            raise pytest.UsageError("property tests not derandomized, or with an example database, under the ci "
                                    "profile (tests/harness/properties.py): " + ", ".join(random))
    for item in items:
        builds = BUILD_FIXTURES & set(getattr(item, "fixturenames", ())) or item.get_closest_marker("builds")
        if builds and item.get_closest_marker("timeout") is None:
            item.add_marker(pytest.mark.timeout(BUILD_TIMEOUT))


def pytest_unconfigure(config):
    procs.stop_all()


# --- where the time goes: the seconds of each test file (setup, call and
# teardown; under pytest-xdist, summed over the workers), and the CPU seconds
# it cost (its worker's own and those of the processes it started and waited
# for: the middleware, the peers, the modules, the compilers), printed after
# the run, so that a test that costs more than it should is seen. On a
# machine of few cores the run's time is its CPU's: the CPU column says where
# to cut.

_FILE_SECONDS: dict = {}
_FILE_CPU: dict = {}


def _cpu_seconds() -> float:
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    item.stash[_CPU_AT_SETUP] = _cpu_seconds()


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    if call.when == "teardown" and _CPU_AT_SETUP in item.stash:
        outcome.get_result().user_properties.append(("cpu_s", _cpu_seconds() - item.stash[_CPU_AT_SETUP]))


def pytest_runtest_logreport(report):
    path = report.nodeid.split("::", 1)[0]
    _FILE_SECONDS[path] = _FILE_SECONDS.get(path, 0.0) + report.duration
    for key, value in report.user_properties:
        if key == "cpu_s":
            _FILE_CPU[path] = _FILE_CPU.get(path, 0.0) + value


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if not _FILE_SECONDS or config.getoption("collectonly", False):
        return
    total = sum(_FILE_SECONDS.values())
    cpu = sum(_FILE_CPU.values())
    terminalreporter.write_sep("-", f"seconds per test file ({total:.1f} s of tests in all, "
                                    f"{cpu:.1f} s of CPU)")
    terminalreporter.write_line(f"{'seconds':>8}  {'CPU s':>8}  file")
    for path, seconds in sorted(_FILE_SECONDS.items(), key=lambda kv: -kv[1])[:25]:
        terminalreporter.write_line(f"{seconds:8.1f}  {_FILE_CPU.get(path, 0.0):8.1f}  {path}")
    terminalreporter.write_line("by CPU:")
    for path, seconds in sorted(_FILE_CPU.items(), key=lambda kv: -kv[1])[:25]:
        terminalreporter.write_line(f"{_FILE_SECONDS.get(path, 0.0):8.1f}  {seconds:8.1f}  {path}")


@pytest.fixture
def ybgc(tmp_path, monkeypatch, capsys):
    """The ybgc command, run in-process in ``tmp_path``: a function of the
    command's arguments giving (exit status, stderr); never a traceback."""
    from ybg import cli

    monkeypatch.chdir(tmp_path)

    def run(*args) -> tuple[int, str]:
        capsys.readouterr()
        try:
            status = cli.main([str(a) for a in args])
        except SystemExit as e:  # usage errors exit from inside the command
            status = e.code
        err = capsys.readouterr().err
        assert "Traceback" not in err
        return status, err

    return run


@pytest.fixture(scope="session")
def update_goldens(request) -> bool:
    return bool(request.config.getoption("--update-goldens"))


@pytest.fixture(scope="session")
def yarp(request):
    """The YARP install of this matrix version, made the active one."""
    install = env.yarp_install(getattr(request, "param", "3.5"))
    missing = install.missing()
    if missing and install.python_path is not None:  # a release built from its sources
        msg = (f"YARP {install.version} is not built here (missing {missing[0]}). "
               f"{install.build_hint()}")
        if os.environ.get("CI"):
            pytest.fail(msg, pytrace=False)
        pytest.skip(msg)
    require_yarp(install)
    env.use_yarp(install)
    yield install
    env.use_yarp(env.DEFAULT_YARP)


@pytest.fixture(autouse=True)
def _active_yarp(request):
    """Each test sees its own matrix version as the active YARP (others: 3.5)."""
    if "yarp" in request.fixturenames:
        env.use_yarp(request.getfixturevalue("yarp"))
    else:
        env.use_yarp(env.DEFAULT_YARP)
    yield


@pytest.fixture
def yarp_server(yarp):
    with YarpServer(install=yarp) as server:
        yield server


@pytest.fixture(scope="module")
def yarp_ros_server(yarp):
    with YarpRosStack() as stack:
        yield stack


@pytest.fixture
def ros2_domain():
    with Ros2Domain() as domain:
        yield domain


@pytest.fixture
def mw(yarp_server, ros2_domain):
    """One environment with the YARP name server and the ROS 2 domain."""
    return SimpleNamespace(env=ros2_environment(yarp_server.env, ros2_domain), yarp=yarp_server, ros2=ros2_domain)


@pytest.fixture
def node_logs():
    """The logs of the nodes a test ran, shown by pytest when it fails."""
    Node.started.clear()
    yield
    for node in Node.started:
        print(f"---- log of {node.name}:\n{node.log_text()[-4000:]}")


@pytest.fixture(scope="session")
def builds(tmp_path_factory, yarp) -> Builds:
    """Every C++ module of the tests, built against the matrix version
    ``yarp``: once for the run, shared by the pytest-xdist workers whose
    programs are the same."""
    return session_builds(tmp_path_factory, yarp)
