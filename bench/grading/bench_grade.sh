#!/usr/bin/env bash
# Wall time and peak memory of `pinsim grade` on the correct submission (the shipped
# plugins) over a rubric (default: the force rubric), median of REPEATS runs, as CSV. Given a
# second program (an older build), both grade the same rubric in the same run, alternating,
# and the ratio of their medians is printed. Not a timed test: run it on a quiet machine.
# Usage: bench/grading/bench_grade.sh [PINSIM] [BASELINE_PINSIM] [REPEATS] [RUBRIC]
set -euo pipefail
cd "$(dirname "$0")/../.."
pinsim=${1:-build/release/bin/pinsim}
baseline=${2:-}
repeats=${3:-7}
rubric=${4:-configs/grading/force_assignment.json}
work=$(mktemp -d "${TMPDIR:-/tmp}/pinsim-bench-grade.XXXXXX")
trap 'rm -rf "$work"' EXIT
programs=("$pinsim")
[ -n "$baseline" ] && programs+=("$baseline")
# Each program grades the shipped plugins of its own build (their ABI is its own).
for k in "${!programs[@]}"; do
  mkdir "$work/sub.$k"
  cp "$(dirname "$(dirname "${programs[$k]}")")"/plugins/libpinsim_plugin_{linear_spring,damped_spring,bending}.so \
    "$work/sub.$k/"
done

# One grade: appends "seconds max_rss_kb score max_score" to $work/runs.K
run() {
  /usr/bin/time -f "%e %M" -o "$work/time" "$1" -q grade --rubric "$rubric" \
    --submission "$work/sub.$2" --out "$work/out" >/dev/null 2>&1 || true
  python3 -c 'import json, sys
t = open(sys.argv[1]).read().split()
r = json.load(open(sys.argv[2]))
print(t[0], t[1], r["score"], r["max_score"], len(r["tests"]))' "$work/time" "$work/out/results.json" >> "$work/runs.$2"
}
for ((i = 0; i < repeats; i++)); do
  for k in "${!programs[@]}"; do run "${programs[$k]}" "$k"; done
done
echo "program,rubric,tests,median_wall_s,max_rss_kb,score,max_score,repeats"
for k in "${!programs[@]}"; do
  python3 - "$work/runs.$k" "${programs[$k]}" "$(basename "$rubric")" "$repeats" <<'PY' | tee -a "$work/csv"
import statistics, sys
rows = [l.split() for l in open(sys.argv[1])]
wall = statistics.median(float(r[0]) for r in rows)
rss = max(int(r[1]) for r in rows)
print(f"{sys.argv[2]},{sys.argv[3]},{rows[-1][4]},{wall:.3f},{rss},{rows[-1][2]},{rows[-1][3]},{sys.argv[4]}")
PY
done
if [ -n "$baseline" ]; then
  python3 -c 'import sys
rows = [l.split(",") for l in open(sys.argv[1])]
print(f"ratio {rows[0][0]} / {rows[1][0]}: {float(rows[0][3]) / float(rows[1][3]):.2f}")' "$work/csv"
fi
