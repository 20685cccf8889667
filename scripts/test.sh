#!/usr/bin/env bash
# The test command: install what is needed, then build and run every test of the workspace.
# The test binaries run one at a time, with the CPU-bound ones beside them at nice 10
# (scripts/testrun.py; docs/method.md 14j); FOOTSCAN_TEST_JOBS=2 adds a second waiting lane on
# a quiet machine. Arguments are cargo test's options, then `--` and test name filters.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"
exec python3 scripts/testrun.py "$@"
