#!/usr/bin/env bash
# README command 1: set up, build, and run the embedded default scene into out/default.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
./build/release/bin/pinsim run --out out/default --overwrite "$@"
echo "run: wrote out/default/trajectory.csv, events.csv, summary.json"
