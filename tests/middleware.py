"""The real-middleware helpers under one name, for what imports them so from
outside the tests (bench/blocks.py, scripts/demo.py): they live in the
harness, tests/harness/ (env, procs, yarp, ros1, ros2, build), which the
test modules import."""
from harness.build import held, run_folder  # noqa: F401
from harness.env import *  # noqa: F401,F403
from harness.env import fail as _fail, python_imports as _python_imports  # noqa: F401
from harness.procs import *  # noqa: F401,F403
from harness.procs import TmpDir as _TmpDir, wait_until as _wait_until  # noqa: F401
from harness.ros1 import *  # noqa: F401,F403
from harness.ros2 import *  # noqa: F401,F403
from harness.yarp import *  # noqa: F401,F403
