"""Shared pytest setup: real middleware fixtures (see tests/middleware.py),
the ``--update-goldens`` option, the ``slow`` marker and a default timeout.

Fixtures
    yarp_server       function scope: a YarpServer on 127.0.0.1:<free port>;
                      use ``yarp_server.env`` for every YARP process.
    yarp_ros_server   module scope: roscore + ``yarpserver --ros`` + the type
                      server (every Debian message type); a YarpRosStack with
                      ``.env`` (YARP and ROS_MASTER_URI/ROS_IP), ``.uri``, ``.port``.
    ros2_domain       function scope: a Ros2Domain with its own ROS_DOMAIN_ID;
                      use ``ros2_domain.env`` for every ROS 2 process.
    update_goldens    bool, true with ``--update-goldens``: golden-file tests
                      rewrite their expected files instead of comparing.
"""
import os

import pytest

import middleware

DEFAULT_TIMEOUT = 180  # seconds per test, when pytest-timeout is installed


def pytest_addoption(parser):
    parser.addoption("--update-goldens", action="store_true", default=False,
                     help="rewrite the golden files instead of comparing against them")


@pytest.hookimpl(tryfirst=True)
def pytest_configure(config):
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


@pytest.fixture(scope="session")
def update_goldens(request) -> bool:
    return bool(request.config.getoption("--update-goldens"))


@pytest.fixture
def yarp_server():
    with middleware.YarpServer() as server:
        yield server


@pytest.fixture(scope="module")
def yarp_ros_server():
    with middleware.YarpRosStack() as stack:
        yield stack


@pytest.fixture
def ros2_domain():
    with middleware.Ros2Domain() as domain:
        yield domain
