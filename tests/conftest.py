"""Shared pytest setup: real middleware fixtures (see tests/middleware.py),
the YARP version matrix, the ``--update-goldens`` option, the ``slow`` marker
and a default timeout.

The YARP matrix: every test that uses the ``yarp`` fixture (directly, or
through ``yarp_server``, or through a fixture of its own that asks for
``yarp``) runs once per YARP version of ``--yarp`` (default: every version of
``middleware.MATRIX``: PyPI's 3.5, 3.12.3, 4.0.0), with the test id
``[yarp<version>]``. Tests of YARP's ROS 1 support (``yarp_ros_server``) run
on the versions that have it (before 3.10). A version that is not built is a
skip saying how to build it, except in CI (``CI`` set), where it fails.

Fixtures
    yarp              session scope, one per matrix version: the YarpInstall,
                      made the active one (middleware.use_yarp) for the test.
    yarp_server       function scope: a YarpServer on 127.0.0.1:<free port>;
                      use ``yarp_server.env`` for every YARP process.
    yarp_ros_server   module scope: roscore + ``yarpserver --ros`` + the type
                      server (every Debian message type); a YarpRosStack with
                      ``.env`` (YARP and ROS_MASTER_URI/ROS_IP), ``.uri``, ``.port``.
    ros2_domain       function scope: a Ros2Domain with its own ROS_DOMAIN_ID;
                      use ``ros2_domain.env`` for every ROS 2 process.
    update_goldens    bool, true with ``--update-goldens``: golden-file tests
                      rewrite their expected files instead of comparing.
    ybgc              the ybgc command run in-process in ``tmp_path``:
                      ``ybgc(*args) -> (exit status, stderr)``.
"""
import os

import pytest

import middleware

DEFAULT_TIMEOUT = 180  # seconds per test, when pytest-timeout is installed


def pytest_addoption(parser):
    parser.addoption("--update-goldens", action="store_true", default=False,
                     help="rewrite the golden files instead of comparing against them")
    parser.addoption("--yarp", default=os.environ.get("YBG_YARP_MATRIX", ",".join(middleware.MATRIX)),
                     help="comma-separated YARP versions to run the YARP-facing tests on "
                          "(default: %(default)s; also YBG_YARP_MATRIX)")


def matrix_versions(config) -> list:
    return [v.strip() for v in config.getoption("--yarp").split(",") if v.strip()]


def pytest_generate_tests(metafunc):
    if "yarp" not in metafunc.fixturenames:
        return
    versions = matrix_versions(metafunc.config)
    if "yarp_ros_server" in metafunc.fixturenames:
        versions = [v for v in versions if middleware.yarp_install(v).has_ros1]
    oldest = metafunc.definition.get_closest_marker("yarp_min")
    if oldest is not None:  # a tool that older YARP releases lack: those are not in the matrix
        versions = [v for v in versions if middleware.yarp_install(v).key >= tuple(oldest.args[0])]
    metafunc.parametrize("yarp", versions, indirect=True, scope="session",
                         ids=[f"yarp{v}" for v in versions])


def _compile_once() -> None:
    """The tests build many small CMake projects, each compiling a module and
    the runtime library beside it: ccache (when installed, as the setup
    does) compiles each distinct source once, in ~/.cache/ybgc/ccache (its
    paths made relative to the temp folder, where the builds are, so that
    one runtime library beside two modules is one entry). Set in the
    environment, so every cmake the tests run (and the processes they
    start) configures with it."""
    import shutil
    import tempfile

    if os.environ.get("YBG_NO_CCACHE") or not shutil.which("ccache"):
        return
    os.environ.setdefault("CMAKE_CXX_COMPILER_LAUNCHER", "ccache")
    os.environ.setdefault("CMAKE_C_COMPILER_LAUNCHER", "ccache")
    os.environ.setdefault("CCACHE_DIR", str(middleware.YARP_CACHE / "ccache"))
    os.environ.setdefault("CCACHE_BASEDIR", os.path.realpath(tempfile.gettempdir()))
    os.environ.setdefault("CCACHE_NOHASHDIR", "1")
    # the sources are written just before they are compiled
    os.environ.setdefault("CCACHE_SLOPPINESS", "include_file_mtime,include_file_ctime,time_macros")
    os.environ.setdefault("CCACHE_MAXSIZE", "3G")


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config):
    _compile_once()
    config.addinivalue_line("markers", "yarp_min(version): run on the YARP releases of the matrix "
                                       "from `version` (a tuple) on only")
    config.addinivalue_line("markers", "slow: a long test (real middleware, seconds or more); "
                                       "deselect with -m 'not slow'")
    # A default per-test timeout, so that a hung middleware process cannot
    # hang the whole run; --timeout, PYTEST_TIMEOUT or an ini value win.
    if config.pluginmanager.hasplugin("timeout"):
        if (config.getoption("timeout", None) is None and not os.environ.get("PYTEST_TIMEOUT")
                and not config.getini("timeout")):
            config.option.timeout = DEFAULT_TIMEOUT


def pytest_unconfigure(config):
    middleware.stop_all()


# --- where the time goes: the seconds of each test file (setup, call and
# teardown; under pytest-xdist, summed over the workers), printed after the
# run, so that a test that costs more than it should is seen

_FILE_SECONDS: dict = {}


def pytest_runtest_logreport(report):
    path = report.nodeid.split("::", 1)[0]
    _FILE_SECONDS[path] = _FILE_SECONDS.get(path, 0.0) + report.duration


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if not _FILE_SECONDS or config.getoption("collectonly", False):
        return
    total = sum(_FILE_SECONDS.values())
    terminalreporter.write_sep("-", f"seconds per test file ({total:.1f} s of tests in all)")
    for path, seconds in sorted(_FILE_SECONDS.items(), key=lambda kv: -kv[1])[:20]:
        terminalreporter.write_line(f"{seconds:8.1f}  {path}")


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
    install = middleware.yarp_install(getattr(request, "param", "3.5"))
    missing = install.missing()
    if missing and install.python_path is not None:  # a release built from its sources
        msg = (f"YARP {install.version} is not built here (missing {missing[0]}). "
               f"{install.build_hint()}")
        if os.environ.get("CI"):
            pytest.fail(msg, pytrace=False)
        pytest.skip(msg)
    middleware.require_yarp(install)
    middleware.use_yarp(install)
    yield install
    middleware.use_yarp(middleware.DEFAULT_YARP)


@pytest.fixture(autouse=True)
def _active_yarp(request):
    """Each test sees its own matrix version as the active YARP (others: 3.5)."""
    if "yarp" in request.fixturenames:
        middleware.use_yarp(request.getfixturevalue("yarp"))
    else:
        middleware.use_yarp(middleware.DEFAULT_YARP)
    yield


@pytest.fixture
def yarp_server(yarp):
    with middleware.YarpServer(install=yarp) as server:
        yield server


@pytest.fixture(scope="module")
def yarp_ros_server(yarp):
    with middleware.YarpRosStack() as stack:
        yield stack


@pytest.fixture
def ros2_domain():
    with middleware.Ros2Domain() as domain:
        yield domain
