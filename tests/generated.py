"""The helpers of generated modules under their former name, for
tests/test_runtime_cpp.py: they live in tests/harness/generated.py, which
the test modules import."""
from harness.generated import *  # noqa: F401,F403
