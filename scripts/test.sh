#!/usr/bin/env bash
# README command 2: set up, build, and run every test, in stages (README, docs/fuzzing.md):
#   release  the release build: ctest but the label web (with the out-of-tree SDK checks,
#            "sdk: ...");
#   web      the WebAssembly engine of `pinsim share` (the web preset, Emscripten), then the
#            tests labelled web (node: the engine bit-identical to native; headless Chromium
#            and Firefox: the share and replay pages, the browser harness);
#   asan     the ctest suite under AddressSanitizer + UBSan (the asan preset: clang, one
#            build that also holds the libFuzzer programs), zero reports, plus the
#            sanitizers' own canary tests (tests/sanitizers); the asan test preset leaves out
#            the labels web and release_only (browsers, installs, out-of-tree builds, the
#            Slurm cluster: tests/CMakeLists.txt, pinsim_test_properties);
#   fuzz     a bounded libFuzzer run of the parsers (the asan build's fuzz_* programs;
#            30 s per target). After the asan stage it builds nothing; alone, it builds
#            only those programs.
# Each stage prints its time. PINSIM_TEST_STAGES picks them (default "release web asan
# fuzz").
# The stages run one after another, so the release and asan suites' Slurm tests never meet
# (each starts and stops its own cluster, in its own folder, on free ports).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh test
# The web and asan build folders compile through ccache too when it is installed.
. scripts/ccache_env.sh
jobs=$(nproc 2>/dev/null || echo 2)
stages=${PINSIM_TEST_STAGES:-release web asan fuzz}
has() { [[ " $stages " == *" $1 "* ]]; }
took() { echo "test.sh: $1 took $((SECONDS - $2)) s"; }

if has release; then
  t=$SECONDS
  # Two tests per core: most of the release suite's time is waiting (sandboxed child
  # processes, time limits, signals), about 60 s of CPU in 3 to 5 minutes at -j2. The
  # browser and node tests (label web) run in the web stage, one per core.
  ctest --preset release -j "$((2 * jobs))" -LE '^web$'
  took "release tests" $t
fi

if has web; then
  t=$SECONDS
  NODE_PATH=/usr/share/nodejs cmake --preset web >/dev/null
  NODE_PATH=/usr/share/nodejs cmake --build --preset web -j "$jobs"
  took "web build" $t
  t=$SECONDS
  ctest --preset release -L '^web$' -j "$jobs"
  took "web tests" $t
fi

if has asan; then
  t=$SECONDS
  cmake --preset asan >/dev/null
  cmake --build --preset asan -j "$jobs"
  took "asan build" $t
  t=$SECONDS
  # Any report fails its test: ASan halts at the first error, UBSan is built without
  # recovery (-fno-sanitize-recover=all), leaks are errors at exit. The test preset sets
  # ASAN_/UBSAN_/LSAN_OPTIONS (third-party leak suppressions: tests/support/lsan.supp).
  ctest --preset asan -j "$jobs"
  took "asan tests" $t
fi

if has fuzz; then
  t=$SECONDS
  bash scripts/fuzz.sh --time 30
  took "fuzz build and run" $t
fi
