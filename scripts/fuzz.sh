#!/usr/bin/env bash
# Builds the libFuzzer programs of the `asan` preset (clang, ASan + UBSan; the `fuzz` build
# preset is those targets of build/asan) and fuzzes each target for a fixed time from a fixed
# seed, as many targets at once as there are cores, starting from the seed corpus
# (tests/fuzz/corpus/TARGET, the regressions in tests/fuzz/regressions/TARGET and the shipped
# configs). See docs/fuzzing.md.
#   scripts/fuzz.sh [--time SECONDS_PER_TARGET] [--corpus DIR] [--seed N] [TARGET...]
# --corpus DIR keeps what the fuzzer learns in DIR/TARGET between runs (default: a fresh
# temporary folder, so CI's run is reproducible). A crash, hang, leak or sanitizer report
# fails the script; the input is saved as build/asan/findings/TARGET/crash-..., and
# docs/fuzzing.md says how to add it to the regression corpus.
set -euo pipefail
cd "$(dirname "$0")/.."

seconds=30
seed=1
corpus=""
targets=()
while (($#)); do
  case "$1" in
    --time) seconds="$2"; shift 2 ;;
    --corpus) corpus="$2"; shift 2 ;;
    --seed) seed="$2"; shift 2 ;;
    -h|--help) sed -n '2,10p' "$0"; exit 0 ;;
    *) targets+=("$1"); shift ;;
  esac
done
((${#targets[@]})) || targets=(scene set sweep_config rubric)

jobs=$(nproc 2>/dev/null || echo 2)
cmake --preset asan >/dev/null
cmake --build --preset fuzz -j "$jobs"

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
[ -n "$corpus" ] || corpus="$tmp/corpus"

# The seed corpus of each target beside its hand-made seeds and regressions.
seeds() {
  case "$1" in
    scene) echo configs configs/crosscheck configs/grading/scenes ;;
    set) ;;
    sweep_config) echo configs/bench configs/stress ;;
    rubric) echo configs/grading ;;
  esac
}
# Longest input: the largest shipped config is ~13 KB; PATH=VALUE lines are short.
max_len() { [ "$1" = set ] && echo 1024 || echo 16384; }

# One fuzzer per core at a time (each is one process on one core), so a target gets its
# seconds of a core whatever the number of cores.
fuzz_one() {
  local t=$1 d rc=0 dirs=("$corpus/$1")
  for d in "tests/fuzz/corpus/$t" "tests/fuzz/regressions/$t" $(seeds "$t"); do
    [ -d "$d" ] && dirs+=("$d")
  done
  # -timeout: seconds per input (a hang); -rss_limit_mb: the memory an input may take.
  ASAN_OPTIONS="${ASAN_OPTIONS:-}:detect_leaks=1" build/asan/tests/fuzz/fuzz_"$t" \
    -seed="$seed" -max_total_time="$seconds" -max_len="$(max_len "$t")" -timeout=10 \
    -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="build/asan/findings/$t/" \
    "${dirs[@]}" >"$tmp/$t.log" 2>&1 || rc=$?
  echo "$rc" >"$tmp/$t.rc"
}
for t in "${targets[@]}"; do
  mkdir -p "$corpus/$t" "build/asan/findings/$t"
done
running=0
for t in "${targets[@]}"; do
  if ((running == jobs)); then
    wait -n || true
    running=$((running - 1))
  fi
  echo "fuzz: $t for ${seconds}s (seed $seed)"
  fuzz_one "$t" &
  running=$((running + 1))
done
wait
failed=()
for t in "${targets[@]}"; do
  echo "fuzz: $t:"
  if [ "$(cat "$tmp/$t.rc")" != 0 ]; then
    failed+=("$t")
    tail -n 60 "$tmp/$t.log"
  fi
  grep -E '^(stat::number_of_executed_units|stat::peak_rss_mb|#[0-9]+ +DONE)' "$tmp/$t.log" || true
done
if ((${#failed[@]})); then
  echo "fuzz: FAILED: ${failed[*]} (inputs in build/asan/findings/; docs/fuzzing.md)" >&2
  exit 1
fi
echo "fuzz: no findings"
