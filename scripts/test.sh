#!/usr/bin/env bash
# README command 2: set up, build, and run every test (ctest, then the out-of-tree SDK check).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
jobs=$(nproc 2>/dev/null || echo 2)
ctest --preset release -j "$jobs"
if [ -f scripts/test_sdk.sh ]; then
  bash scripts/test_sdk.sh
fi
