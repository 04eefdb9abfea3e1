#!/usr/bin/env bash
# Out-of-tree SDK check (CI): install a pinsim build to a temporary prefix, build
# sdk/template_plugin against the installed SDK with find_package(pinsim), run
# `pinsim check-plugin` on the built library, and run a scene that uses it.
#
# Usage: scripts/test_sdk.sh [BUILD_DIR]   (default: build/release, already built)
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
BUILD=${1:-$ROOT/build/release}
TMP=$(mktemp -d "${TMPDIR:-/tmp}/pinsim-sdk.XXXXXX")
trap 'rm -rf "$TMP"' EXIT

step() { echo "== $*"; }
run_logged() {  # run a command quietly; on failure show its log and stop
  local log="$TMP/$1.log"
  shift
  if ! "$@" >"$log" 2>&1; then
    echo "FAILED: $*" >&2
    cat "$log" >&2
    exit 1
  fi
}

[ -x "$BUILD/bin/pinsim" ] || { echo "no pinsim in $BUILD/bin: build it first" >&2; exit 1; }

step "install $BUILD to a temporary prefix"
run_logged install cmake --install "$BUILD" --prefix "$TMP/prefix"
PINSIM="$TMP/prefix/bin/pinsim"
CONFIG=$(find "$TMP/prefix" -name pinsimConfig.cmake | head -n1)
[ -n "$CONFIG" ] || { echo "pinsimConfig.cmake was not installed" >&2; exit 1; }
PLUGINS=$(dirname "$(find "$TMP/prefix" -name 'libpinsim_plugin_gravity.so' | head -n1)")

step "build sdk/template_plugin out of tree against the installed SDK"
cp -r "$ROOT/sdk/template_plugin" "$TMP/src"
run_logged configure cmake -S "$TMP/src" -B "$TMP/build" -DCMAKE_BUILD_TYPE=Release \
  -DCMAKE_PREFIX_PATH="$TMP/prefix"
run_logged build cmake --build "$TMP/build" -j2
SO="$TMP/build/libpinsim_plugin_my_anchor.so"
[ -f "$SO" ] || { echo "the template did not produce $SO" >&2; exit 1; }

step "pinsim check-plugin on the built template"
"$PINSIM" check-plugin "$SO"

step "pinsim run a scene that uses it"
PINSIM_PLUGIN_PATH="$TMP/build:$PLUGINS" "$PINSIM" -q run "$TMP/src/scene.json" --out "$TMP/out"
[ -s "$TMP/out/trajectory.csv" ] || { echo "the run wrote no trajectory" >&2; exit 1; }
echo "SDK OK: template built against $(dirname "$CONFIG"), checked and run"
