#!/usr/bin/env bash
# The main job on the simulator: a full simulated scan into scans/demo (or the directory given).
# Installs and builds only what the scan needs (the test tools come with scripts/test.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/setup.sh --build
export PATH="$HOME/.cargo/bin:$PATH"
out="${1:-scans/demo}"
# Without default features: the simulated scan needs neither OpenCV (`calibrate --method
# opencv`), wasmtime (the `wasm` and `exec` stages) nor the fleet client (`footscan fleet`:
# PostgreSQL, tokio, OpenSSL), which are most of a fresh build (docs/method.md sections 14b
# and 14g). `cargo build --release` builds the full CLI.
cargo run --release --no-default-features --bin footscan -- scan --config config/sim.toml --out "$out"
