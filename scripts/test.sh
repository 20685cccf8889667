#!/usr/bin/env bash
# The test command: install what is needed, then build and run every test of the workspace.
# The test binaries run three at a time (scripts/testrun.py: most of their time is real-time
# waiting); FOOTSCAN_TEST_JOBS=1 runs them one by one as `cargo test` does. Arguments are
# cargo test's options, then `--` and test name filters.
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh
export PATH="$HOME/.cargo/bin:$PATH"
exec python3 scripts/testrun.py "$@"
