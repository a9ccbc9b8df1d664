#!/usr/bin/env bash
# The property tests with hypothesis' "fuzz" profile (tests/harness/properties.py):
# at random, 20 times the examples CI draws, each test up to an hour. CI runs
# them derandomized, the same examples every run; this run looks further.
# A failure prints the example (and its @reproduce_failure blob); put the
# example in an explicit @example(...) of the test, which CI then runs every time.
#
#   scripts/fuzz.sh                              every property test
#   scripts/fuzz.sh tests/test_geometry.py -x    one file; pytest's arguments
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
export YBG_HYPOTHESIS_PROFILE=fuzz
exec .venv/bin/python -m pytest -q -m hypothesis --timeout 3600 "$@"
