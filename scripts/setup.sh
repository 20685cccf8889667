#!/usr/bin/env bash
# Install what footscan needs to build on Debian: the system packages below and, if cargo is
# missing, a Rust toolchain through rustup. Safe to run again; it only installs what is absent.
# `setup.sh --build` (what scripts/scan-sim.sh runs) installs only what its build (without the
# default features' OpenCV, wasmtime and fleet client) needs; OpenCV and the test tools below
# (Chromium, PostgreSQL, poppler, the OpenCASCADE venv) come with scripts/test.sh.
set -euo pipefail
mode="${1:-all}"
# The build of what the simulated scan needs: bindgen for the V4L2 bindings (clang), libudev.
build_packages=(pkg-config libudev-dev gcc clang libclang-dev)

packages=("${build_packages[@]}")
# The default build's OpenCV reference calibration (`calibrate --method opencv`); scan-sim.sh
# builds without it.
packages+=(libopencv-dev)
# footscand's archive index links Debian's SQLite (crates/daemon's `bundled-sqlite` feature
# compiles its own copy instead).
packages+=(libsqlite3-dev)
# The dashboard's screenshot test (tests/dashboard_chromium.rs) runs Debian's headless Chromium.
packages+=(chromium fonts-dejavu-core)
# tests/daemon_api.rs runs the curl examples of docs/API.md.
packages+=(curl)
# tests/report_pdf.rs reads the printable report back (pdfinfo, pdftotext, pdftoppm).
packages+=(poppler-utils)
# The geometry export tests read IGES/STEP back with OpenCASCADE in a Python venv (below).
packages+=(python3-venv)
# The fleet tests (crates/fleet, crates/daemon/tests/daemon_fleet.rs, tests/fleet_cli.rs) start
# a PostgreSQL server of their own (initdb + pg_ctl); footscan-fleet's TLS links OpenSSL.
packages+=(postgresql libssl-dev openssl)
# drivers/grbl/tests/firmware.rs builds GRBL 1.1h's simulator (gcc, make) and runs it on a pty.
packages+=(make socat)
# tests/plugin_wasm.rs builds the example wasm stage (examples/plugins/cog-wasm/cog.c) with
# clang (above) for wasm32 and links it with lld's wasm-ld.
packages+=(lld)
[ "$mode" = "--build" ] && packages=("${build_packages[@]}")
missing=()
for p in "${packages[@]}"; do
  dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  echo "installing Debian packages: ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
if ! command -v cargo >/dev/null 2>&1; then
  [ -x "$HOME/.cargo/bin/cargo" ] || {
    echo "cargo not found: install Rust with rustup (https://rustup.rs), then run this again" >&2
    exit 1
  }
fi

[ "$mode" = "--build" ] && exit 0

# crates/geom/tests/export_occt.rs reads every exported IGES and STEP file back with
# OpenCASCADE 8 (scripts/occt_readback.py); it runs in a venv of its own (target/venv-occt),
# made only when it is absent or cannot import OCP. Test-time only: nothing in the product
# needs it.
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

# The test tools below are made once per machine, not once per clone: each lives in a
# directory of the tool cache named by what it holds (the pinned packages), and target/NAME is a
# symbolic link to it, so a fresh clone (CI) links what an earlier clone made instead of
# downloading and unpacking it again (the OpenCASCADE venv alone is about 400 MB). The cache is
# $FOOTSCAN_TOOL_CACHE, by default ~/.cache/footscan; FOOTSCAN_TOOL_CACHE=off makes the tools
# inside target/ as before. A lock keeps two clones' setups from making one tool at once.
tool_cache="${FOOTSCAN_TOOL_CACHE:-${XDG_CACHE_HOME:-$HOME/.cache}/footscan}"
mkdir -p "$repo/target"

# tool_dir NAME KEY...: the directory to make the tool NAME in (printed): in the tool cache,
# named by NAME and a hash of KEYs, or target/NAME when the cache is off.
tool_dir() {
  local name="$1"
  shift
  if [ "$tool_cache" = off ]; then
    echo "$repo/target/$name"
  else
    echo "$tool_cache/$name-$(printf '%s\n' "$@" | sha256sum | cut -c1-12)"
  fi
}

# link_tool NAME DIR: target/NAME is DIR (nothing to do when the cache is off).
link_tool() {
  local link="$repo/target/$1" dir="$2"
  [ "$link" = "$dir" ] && return 0
  [ -L "$link" ] && [ "$(readlink "$link")" = "$dir" ] && return 0
  rm -rf "$link"
  ln -s "$dir" "$link"
}

# locked CMD...: CMD under the tool cache's lock (a plain call when the cache is off).
locked() {
  if [ "$tool_cache" = off ]; then
    "$@"
  else
    mkdir -p "$tool_cache"
    (
      flock 9
      "$@"
    ) 9>"$tool_cache/.lock"
  fi
}

# venv NAME IMPORTS SIZE PACKAGE...: a Python venv at target/NAME with PACKAGEs, made only when
# it is absent or cannot import IMPORTS (a comma-separated list); SIZE is said while it is made.
venv() {
  local name="$1" imports="$2" size="$3"
  shift 3
  "$repo/target/$name/bin/python" -c "import $imports" >/dev/null 2>&1 && return 0
  local dir
  dir="$(tool_dir "$name" "$@")"
  locked make_venv "$dir" "$imports" "$size" "$@"
  link_tool "$name" "$dir"
}

make_venv() {
  local dir="$1" imports="$2" size="$3"
  shift 3
  "$dir/bin/python" -c "import $imports" >/dev/null 2>&1 && return 0
  local py=/usr/bin/python3
  [ -x "$py" ] || py=python3
  echo "creating $dir ($*; about $size)"
  rm -rf "$dir"
  "$py" -m venv "$dir"
  "$dir/bin/python" -m pip install -q --disable-pip-version-check "$@"
}
venv venv-occt "OCP, numpy" "400 MB" cadquery-ocp-novtk==8.0.1.1.0 numpy

# crates/geom/tests/gltf_readback.rs (and the .glb tests of the CLI and footscand) check every
# glTF file with the Khronos validator (npm gltf-validator, pinned, under target/npm-gltf) and
# read it back with Python trimesh (a venv under target/venv-gltf). Each is made only when
# absent; test-time only.
gltf_validator=gltf-validator@2.0.0-dev.3.10
make_npm_gltf() {
  local dir="$1"
  [ -f "$dir/node_modules/gltf-validator/package.json" ] && return 0
  command -v npm >/dev/null 2>&1 || {
    echo "npm not found: install Node.js 20 and npm for the glTF validator" >&2
    exit 1
  }
  echo "installing the Khronos glTF validator into $dir"
  mkdir -p "$dir"
  npm install --prefix "$dir" --no-audit --no-fund --silent "$gltf_validator"
}
if [ ! -f "$repo/target/npm-gltf/node_modules/gltf-validator/package.json" ]; then
  npm_gltf="$(tool_dir npm-gltf "$gltf_validator")"
  locked make_npm_gltf "$npm_gltf"
  link_tool npm-gltf "$npm_gltf"
fi
venv venv-gltf "trimesh, numpy" "100 MB" trimesh==4.12.2 numpy
# The process-stage examples and tests (examples/plugins/python, crates/plugins/tests,
# tests/plugin_exec.rs) run Python with numpy from a venv of their own under target/, made only
# when it is absent or cannot import numpy.
venv venv-plugins numpy "100 MB" numpy
# tests/insole.rs reads every insole.3mf back with lib3mf, the 3MF Consortium's reference
# library (scripts/threemf_lib3mf.py), in a venv of its own; test-time only.
venv venv-3mf lib3mf "10 MB" lib3mf==2.5.0
