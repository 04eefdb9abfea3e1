#!/usr/bin/env bash
# scripts/gradescope/run_autograder in a temporary copy of Gradescope's layout
# (ROOT/source = this repository, ROOT/submission, ROOT/results): a submission of the shipped
# force plugins gets full marks in ROOT/results/results.json, and a submission that does not
# compile gets 0 with the compiler's message, still in a valid results.json, and a grader
# that leaves an empty results.json is replaced by a valid one with score 0.
# Usage: test_run_autograder.sh SOURCE_DIR PINSIM_BIN PLUGIN_DIR
set -euo pipefail
src=$1 bin=$2 plugins=$3
root=$(mktemp -d "${TMPDIR:-/tmp}/pinsim-gradescope.XXXXXX")
trap 'rm -rf "$root"' EXIT

check() {  # check EXPECTED_FULL_MARKS(yes|no) PATTERN
  python3 - "$root/results/results.json" "$1" "$2" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
full, pattern = sys.argv[2] == "yes", sys.argv[3]
score = r["score"]
best = sum(t["max_score"] for t in r["tests"])
text = " ".join(t["output"] for t in r["tests"])
print(f"score {score} of {best}, {len(r['tests'])} tests")
ok = (score == best) if full else (score == 0)
ok = ok and best > 0 and pattern in text
sys.exit(0 if ok else 1)
PY
}

mkdir -p "$root/submission" "$root/results"
ln -s "$src" "$root/source"
for p in linear_spring damped_spring bending; do
  cp "$plugins/libpinsim_plugin_$p.so" "$root/submission/"
done
AUTOGRADER_ROOT=$root PINSIM_BIN=$bin bash "$src/scripts/gradescope/run_autograder" >/dev/null
check yes "loaded plugin"

rm -rf "$root/submission" "$root/results"/*
cp -r "$src/tests/framework/grading/submissions/does_not_compile" "$root/submission"
AUTOGRADER_ROOT=$root PINSIM_BIN=$bin bash "$src/scripts/gradescope/run_autograder" >/dev/null
check no "does not compile"
# A grader that leaves an empty results.json (as a crashed grader might): Gradescope still
# gets a valid file, score 0, saying the autograder failed.
rm -rf "$root/results"/*
fake=$root/fake-pinsim
printf '#!/bin/sh\nmkdir -p "$AUTOGRADER_ROOT/results/pinsim"\n: > "$AUTOGRADER_ROOT/results/pinsim/results.json"\nexit 2\n' > "$fake"
chmod +x "$fake"
AUTOGRADER_ROOT=$root PINSIM_BIN=$fake bash "$src/scripts/gradescope/run_autograder" >/dev/null
python3 - "$root/results/results.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
assert r["score"] == 0 and "autograder failed" in r["output"], r
print("empty results.json replaced:", r["output"])
PY
echo "run_autograder OK"
