#!/usr/bin/env bash
# The main job on the simulator: a full simulated scan into scans/demo (or the directory given).
# Installs and builds only what the scan needs (the test tools come with scripts/test.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh --build
export PATH="$HOME/.cargo/bin:$PATH"
out="${1:-scans/demo}"
cargo run --release --bin footscan -- scan --config config/sim.toml --out "$out"
