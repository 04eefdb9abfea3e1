#!/usr/bin/env bash
# `pinsim gradescope-pack` and the zip's scripts in a temporary copy of Gradescope's layout
# (ROOT/source = the unzipped autograder, ROOT/submission, ROOT/results; ROOT is
# AUTOGRADER_ROOT, never /autograder itself).
#   quick: the zip's contents and errors; its run_autograder with this build's pinsim
#          (PINSIM_BIN): the shipped force plugins get full marks, a source folder that does
#          not compile 0 with the compiler's message, a grader that leaves an empty
#          results.json a valid file with score 0.
#   fallback: (root only, else exit 77: skipped) as Gradescope's Docker container runs it:
#          the zip's run_autograder under container_like without Landlock, so in the
#          fallback sandbox on file permissions alone, with TMPDIR unset (the grader's staging
#          folders in /tmp, beside what it sweeps), grading a source submission with this
#          build installed in a root-only prefix (only the SDK readable, as run_autograder
#          leaves the zip's build; the build tree's plugin folder hidden): the same score as
#          the same grader gives it in bubblewrap, more than 0, said to be the fallback.
#   build: the zip's setup.sh as Gradescope runs it (apt skipped: the packages are here;
#          through ccache when the environment names it), then its run_autograder with the
#          pinsim it built: the correct source submission gets the score this build's grader
#          gives it, one that does not compile 0; as root also under container_like without
#          Landlock (Docker's defaults: the fallback sandbox, with run_autograder's
#          permissions). In a fixed folder, ${TMPDIR:-/tmp}/pinsim-gradescope-build (one run
#          at a time, under a lock): the build's compile lines hold that path, so ccache
#          reuses the last run's objects.
# Usage: test_gradescope_pack.sh quick|fallback|build SOURCE_DIR PINSIM_BIN PLUGIN_DIR
#        [CONTAINER_LIKE]
set -euo pipefail
mode=$1 src=$2 bin=$3 plugins=$4 container_like=${5:-}
if [ "$mode" = build ]; then
  tmp=${TMPDIR:-/tmp}/pinsim-gradescope-build
  exec 9>"$tmp.lock"
  flock 9
  rm -rf "$tmp"
  mkdir -m 700 "$tmp"
else
  tmp=$(mktemp -d "${TMPDIR:-/tmp}/pinsim-gradescope.XXXXXX")
fi
trap 'rm -rf "$tmp"' EXIT
root=$tmp/autograder
rubric=$src/configs/grading/force_assignment.json
subs=$src/tests/framework/grading/submissions

fail() { echo "FAIL: $*" >&2; exit 1; }

unpack() {  # unpack ZIP: a fresh ROOT with the zip in ROOT/source, as Gradescope lays it out
  rm -rf "$root"
  mkdir -p "$root/source" "$root/submission" "$root/results"
  unzip -q "$1" -d "$root/source"
}

# score_of RESULTS: a results.json's score
score_of() {
  python3 -c 'import json, sys; print(json.load(open(sys.argv[1], encoding="utf-8"))["score"])' "$1"
}

# check RESULTS EXPECTED_SCORE PATTERN [MODE]: the score, a pattern in some test's output and
# (optionally) extra_data.sandbox.mode of a results.json
check() {
  python3 - "$@" <<'PY'
import json, sys
r = json.load(open(sys.argv[1], encoding="utf-8"))
want, pattern = float(sys.argv[2]), sys.argv[3]
mode = sys.argv[4] if len(sys.argv) > 4 else None
best = sum(t["max_score"] for t in r["tests"])
text = " ".join(t.get("output", "") for t in r["tests"])
got_mode = r.get("extra_data", {}).get("sandbox", {}).get("mode")
print(f"score {r['score']} of {best}, {len(r['tests'])} tests, sandbox {got_mode}")
ok = abs(r["score"] - want) < 1e-9 and best > 0 and pattern in text
ok = ok and (mode is None or got_mode == mode)
if not ok:
    print(json.dumps(r, indent=1)[:3000])
sys.exit(0 if ok else 1)
PY
}

"$bin" -q gradescope-pack --rubric "$rubric" --out "$tmp/autograder.zip" ||
  fail "gradescope-pack exited $?"

if [ "$mode" = quick ]; then
  # Gradescope's two scripts at the top level, executable; the rubric fixed in run_autograder.
  listing=$(unzip -Z "$tmp/autograder.zip")
  for f in setup.sh run_autograder; do
    grep -Eq "^-rwxr-xr-x .* $f\$" <<<"$listing" || fail "$f is not an executable at the zip's top level"
  done
  names=$(unzip -Z1 "$tmp/autograder.zip")
  for f in CMakeLists.txt framework/src/grading/grader.cpp framework/include/pinsim/plugin.hpp \
           configs/grading/force_assignment.json configs/grading/scenes/spring_chain.json \
           plugins/linear_spring/CMakeLists.txt plugins/gravity/CMakeLists.txt; do
    grep -qx "$f" <<<"$names" || fail "$f is missing from the zip"
  done
  # Nothing of the tests', the web's, the benches', the docs' or another assignment's.
  # (The force scenes run on the backend none; the collision backends are left out.)
  if grep -E '^(tests|docs|bench|framework/src/web|framework/src/gradients|scripts|sdk|build)/|^backends/(sdf|box2d)/|^configs/grading/collision' <<<"$names"; then
    fail "the zip holds files it should not (above)"
  fi
  unzip -p "$tmp/autograder.zip" run_autograder | grep -q '^rubric=\$source/configs/grading/force_assignment.json$' ||
    fail "run_autograder does not name the rubric"
  if unzip -p "$tmp/autograder.zip" run_autograder setup.sh | grep -Eq 'PINSIM_RUBRIC|@[A-Z_]+@'; then
    fail "a script still depends on PINSIM_RUBRIC or holds a placeholder"
  fi
  unzip -p "$tmp/autograder.zip" setup.sh | grep -q -- '--target pinsim pinsim_scene_field pinsim_plugin_bending pinsim_plugin_damped_spring pinsim_plugin_gravity pinsim_plugin_linear_spring pinsim_plugin_none$' ||
    fail "setup.sh does not build exactly pinsim and the rubric's plugins"
  # The same tree gives the same bytes.
  "$bin" -q gradescope-pack --rubric "$rubric" --out "$tmp/again.zip"
  cmp -s "$tmp/autograder.zip" "$tmp/again.zip" || fail "two packs of the same tree differ"
  # The collision rubric: the sdf backend and the scenes' gravity, no Box2D (no test asks it).
  "$bin" -q gradescope-pack --rubric "$src/configs/grading/collision_assignment.json" --out "$tmp/pinball.zip"
  names=$(unzip -Z1 "$tmp/pinball.zip")
  for f in backends/sdf/CMakeLists.txt plugins/gravity/CMakeLists.txt configs/grading/scenes/hidden_table.json; do
    grep -qx "$f" <<<"$names" || fail "$f is missing from the collision zip"
  done
  ! grep -Eq '^(plugins/(linear_spring|bending)|backends/box2d)/' <<<"$names" || fail "the collision zip holds plugins it does not need"
  ! unzip -p "$tmp/pinball.zip" setup.sh | grep -q 'libbox2d-dev' || fail "libbox2d-dev in the collision setup.sh"
  # A course's own rubric outside the source tree, with a Box2D second opinion: under rubric/
  # with its scene, Box2D's backend and the sdf backend it links, and libbox2d-dev.
  mkdir -p "$tmp/course/scenes"
  cp "$src/configs/grading/scenes/corner.json" "$tmp/course/scenes/"
  cat > "$tmp/course/box2d.json" <<'JSON'
{"name": "with a second opinion", "kind": "backend",
 "tests": [{"name": "corner", "check": "backend_agreement", "plugin": "student_sdf", "points": 1,
            "reference": "sdf", "second_opinion": "box2d", "scene": "scenes/corner.json",
            "tolerance": 1e-3}]}
JSON
  "$bin" -q gradescope-pack --rubric "$tmp/course/box2d.json" --out "$tmp/box2d.zip"
  names=$(unzip -Z1 "$tmp/box2d.zip")
  for f in rubric/box2d.json rubric/scenes/corner.json backends/box2d/CMakeLists.txt backends/sdf/CMakeLists.txt; do
    grep -qx "$f" <<<"$names" || fail "$f is missing from the Box2D zip"
  done
  unzip -p "$tmp/box2d.zip" setup.sh | grep -q ' libbox2d-dev)$' || fail "no libbox2d-dev in the Box2D setup.sh"
  unzip -p "$tmp/box2d.zip" run_autograder | grep -q '^rubric=\$source/rubric/box2d.json$' ||
    fail "run_autograder does not name the course's rubric"
  # A scene outside the rubric's folder cannot be placed in the zip.
  mkdir "$tmp/course/deep"
  sed 's#scenes/corner.json#../../corner.json#' "$tmp/course/box2d.json" > "$tmp/course/deep/outside.json"
  cp "$src/configs/grading/scenes/corner.json" "$tmp/"

  # Bad input: exit 2, the file named, nothing written (not even a temporary).
  expect_error() {  # expect_error PATTERN ARGS...
    local pattern=$1 out code=0
    shift
    out=$("$bin" gradescope-pack "$@" 2>&1) || code=$?
    [ "$code" -eq 2 ] || fail "gradescope-pack $* exited $code, expected 2: $out"
    grep -qF -- "$pattern" <<<"$out" || fail "gradescope-pack $*: '$pattern' not in: $out"
  }
  mkdir "$tmp/errors"
  expect_error "$tmp/none.json: rubric file not found" --rubric "$tmp/none.json" --out "$tmp/errors/a.zip"
  printf '{"name": "x", "kind": "force", "tests": [{"name": "t", "check": "load", "plugin": "p", "pionts": 1}]}\n' > "$tmp/bad.json"
  expect_error "bad.json: tests[0].pionts: unknown key" --rubric "$tmp/bad.json" --out "$tmp/errors/a.zip"
  expect_error "$tmp/missing/a.zip" --rubric "$rubric" --out "$tmp/missing/a.zip"
  expect_error "is a folder" --rubric "$rubric" --out "$tmp/errors"
  if [ "$(id -u)" -ne 0 ]; then
    chmod a-w "$tmp/errors"
    expect_error "$tmp/errors/a.zip" --rubric "$rubric" --out "$tmp/errors/a.zip"
    chmod u+w "$tmp/errors"
  fi
  # /proc refuses new files, to root too.
  expect_error "/proc/pinsim.zip" --rubric "$rubric" --out /proc/pinsim.zip
  expect_error "../../corner.json is outside the autograder's folder" --rubric "$tmp/course/deep/outside.json" --out "$tmp/errors/a.zip"
  [ -z "$(ls -A "$tmp/errors")" ] || fail "a failed pack left files: $(ls -A "$tmp/errors")"

  # run_autograder from the zip, with this build's pinsim.
  unpack "$tmp/autograder.zip"
  for p in linear_spring damped_spring bending; do
    cp "$plugins/libpinsim_plugin_$p.so" "$root/submission/"
  done
  AUTOGRADER_ROOT=$root PINSIM_BIN=$bin "$root/source/run_autograder" >/dev/null
  check "$root/results/results.json" 68 "loaded plugin"

  rm -rf "$root/submission" "$root/results"/*
  cp -r "$subs/does_not_compile" "$root/submission"
  AUTOGRADER_ROOT=$root PINSIM_BIN=$bin "$root/source/run_autograder" >/dev/null
  check "$root/results/results.json" 0 "does not compile"

  # A grader that leaves an empty results.json (as a crashed grader might): Gradescope still
  # gets a valid file, score 0, saying the autograder failed.
  rm -rf "$root/results"/*
  fake=$tmp/fake-pinsim
  printf '#!/bin/sh\nmkdir -p "$AUTOGRADER_ROOT/results/pinsim"\n: > "$AUTOGRADER_ROOT/results/pinsim/results.json"\nexit 2\n' > "$fake"
  chmod +x "$fake"
  AUTOGRADER_ROOT=$root PINSIM_BIN=$fake "$root/source/run_autograder" >/dev/null
  python3 - "$root/results/results.json" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
assert r["score"] == 0 and "autograder failed" in r["output"], r
print("empty results.json replaced:", r["output"])
PY
  echo "gradescope-pack quick OK"
  exit 0
fi

if [ "$mode" = fallback ]; then
  if [ "$(id -u)" -ne 0 ] || [ -z "$container_like" ]; then
    echo "not root (or no container_like): the fallback sandbox cannot be tried"
    exit 77
  fi
  unpack "$tmp/autograder.zip"
  chmod 711 "$tmp"  # /autograder's parent, /, lets every uid through
  # This build installed where only root reads it but the SDK (headers, CMake package and
  # the scene-field library a source submission links), as run_autograder leaves the zip's
  # build: the grader refuses to grade in the fallback if its reference plugins are readable.
  prefix=$tmp/prefix
  cmake --install "$(dirname "$(dirname "$bin")")" --prefix "$prefix" >/dev/null
  chmod -R go-rwx "$prefix"
  chmod go+x "$prefix" "$prefix/lib"
  chmod -R go+rX "$prefix/include" "$prefix/lib/cmake" "$prefix"/lib/*.a
  cp -r "$subs/correct_source/." "$root/submission/"
  AUTOGRADER_ROOT=$root PINSIM_BIN=$prefix/bin/pinsim "$root/source/run_autograder" >/dev/null
  in_bwrap=$(score_of "$root/results/results.json")
  check "$root/results/results.json" "$in_bwrap" "loaded plugin" bubblewrap
  python3 -c 'import sys; sys.exit(0 if float(sys.argv[1]) > 0 else 1)' "$in_bwrap" ||
    fail "the correct source submission scored 0 in bubblewrap"
  rm -rf "$root/results"/*
  # The installed program also searches this build tree's plugin folder (after its own),
  # which every uid can read here and which Gradescope's image does not have: in a mount
  # namespace of the test's own it is an empty root-only folder.
  unshare --mount --propagation private -- bash -c \
    'mount -t tmpfs -o mode=0700,size=1m pinsim-hidden "$1" && shift && exec "$@"' _ "$plugins" \
    env -u TMPDIR AUTOGRADER_ROOT="$root" PINSIM_BIN="$prefix/bin/pinsim" \
    "$container_like" --no-landlock -- "$root/source/run_autograder" >/dev/null
  check "$root/results/results.json" "$in_bwrap" "loaded plugin" fallback
  echo "gradescope-pack fallback OK"
  exit 0
fi

[ "$mode" = build ] || fail "unknown mode $mode"
# What this build's grader gives the correct source submission, for the zip's to match.
unpack "$tmp/autograder.zip"
cp -r "$subs/correct_source/." "$root/submission/"
AUTOGRADER_ROOT=$root PINSIM_BIN=$bin "$root/source/run_autograder" >/dev/null
expected=$(score_of "$root/results/results.json")
unpack "$tmp/autograder.zip"
chmod 711 "$tmp"  # /autograder's parent, /, lets every uid through
# Gradescope builds from scratch; here a compiler cache in the environment (test.sh sets one
# where ccache is installed) is kept, with the paths below the unpacked zip made relative:
# what is checked is what setup.sh builds and how it grades, not how long it takes
# (docs/grading.md has the time without a cache).
[ -z "${CMAKE_CXX_COMPILER_LAUNCHER:-}" ] || export CCACHE_BASEDIR=$root/source CCACHE_NOHASHDIR=true
start=$(date +%s)
PINSIM_SETUP_JOBS=${PINSIM_SETUP_JOBS:-2} bash "$root/source/setup.sh" > "$tmp/setup.log" 2>&1 ||
  { tail -50 "$tmp/setup.log"; fail "setup.sh failed"; }
echo "setup.sh: $(($(date +%s) - start)) s"
grep -q "installing" "$tmp/setup.log" && fail "setup.sh ran apt although every package is installed"
[ -x "$root/source/build/bin/pinsim" ] || fail "setup.sh built no pinsim"
for p in bending damped_spring gravity linear_spring none; do
  [ -f "$root/source/build/plugins/libpinsim_plugin_$p.so" ] || fail "setup.sh did not build $p"
done
[ ! -e "$root/source/build/plugins/libpinsim_plugin_sdf.so" ] || fail "setup.sh built the sdf backend"

cp -r "$subs/correct_source/." "$root/submission/"
AUTOGRADER_ROOT=$root "$root/source/run_autograder" >/dev/null
check "$root/results/results.json" "$expected" "loaded plugin"

rm -rf "$root/submission"/* "$root/results"/*
cp -r "$subs/does_not_compile/." "$root/submission/"
AUTOGRADER_ROOT=$root "$root/source/run_autograder" >/dev/null
check "$root/results/results.json" 0 "does not compile"

if [ "$(id -u)" -eq 0 ] && [ -n "$container_like" ]; then
  # Docker's defaults, no Landlock: the fallback, on file permissions alone (run_autograder's).
  rm -rf "$root/submission"/* "$root/results"/*
  cp -r "$subs/correct_source/." "$root/submission/"
  env -u TMPDIR AUTOGRADER_ROOT="$root" "$container_like" --no-landlock -- \
    "$root/source/run_autograder" >/dev/null
  check "$root/results/results.json" "$expected" "loaded plugin" fallback
else
  echo "not root: the fallback sandbox is not tried"
fi
echo "gradescope-pack build OK"
