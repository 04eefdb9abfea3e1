#!/usr/bin/env bash
# README command 1: install what the main job needs, build the pinsim program and its plugins
# (scripts/setup.sh run: no tests, no benches), and run the embedded default scene into
# out/default.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh run
./build/release/bin/pinsim run --out out/default --overwrite "$@"
echo "run: wrote out/default/trajectory.csv, events.csv, summary.json"
