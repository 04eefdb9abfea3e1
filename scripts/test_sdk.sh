#!/usr/bin/env bash
# Out-of-tree SDK check (CI): install a pinsim build to a temporary prefix, build
# sdk/template_plugin against the installed SDK with find_package(pinsim), run
# `pinsim check-plugin` on the built library, and run a scene that uses it; then build
# sdk/pinball_starter (the student_sdf backend on pinsim::scene_field) the same way and
# run, validate and render the shipped pinball table with it.
#
# Usage: scripts/test_sdk.sh [--starter|--template] [BUILD_DIR]   (default: build/release,
#   built). Both parts by default; ctest runs them as two tests ("sdk: ..."):
#   --starter: only the install and the pinball starter;
#   --template: everything but the pinball starter.
set -euo pipefail

ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
STARTER_ONLY=0
TEMPLATE_ONLY=0
case "${1:-}" in
  --starter) STARTER_ONLY=1; shift ;;
  --template) TEMPLATE_ONLY=1; shift ;;
esac
BUILD=$(cd "${1:-$ROOT/build/release}" && pwd -P)
TMP=$(mktemp -d "${TMPDIR:-/tmp}/pinsim-sdk.XXXXXX")
trap 'rm -rf "$TMP"' EXIT
TMP=$(cd "$TMP" && pwd -P)  # as /proc/self/exe names it

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

# sdk/pinball_starter out of tree against the installed SDK (pinsim::scene_field), on the
# shipped pinball table with its backend replaced by student_sdf.
test_starter() {
  step "build sdk/pinball_starter out of tree against the installed SDK"
  cp -r "$ROOT/sdk/pinball_starter" "$TMP/starter"
  local t0=$SECONDS
  run_logged starter_configure cmake -S "$TMP/starter" -B "$TMP/starter_build" \
    -DCMAKE_PREFIX_PATH="$TMP/prefix"
  run_logged starter_build cmake --build "$TMP/starter_build" -j2
  echo "configured and built in $((SECONDS - t0)) s"
  grep -q "warning" "$TMP/starter_build.log" && {
    echo "the starter compiled with warnings:" >&2
    cat "$TMP/starter_build.log" >&2
    exit 1
  }
  [ -f "$TMP/starter_build/libpinsim_plugin_student_sdf.so" ] || {
    echo "the starter did not produce libpinsim_plugin_student_sdf.so" >&2
    exit 1
  }
  # The table as the kit's README makes it: the shipped scene, backend student_sdf.
  sed -e 's/"name": "sdf",/"name": "student_sdf",/' \
    -e 's/"params": {"depth_min": [^}]*}/"params": {}/' "$ROOT/configs/pinball.json" \
    >"$TMP/pinball_student.json"
  grep -q '"name": "student_sdf"' "$TMP/pinball_student.json" || {
    echo "could not set the backend of configs/pinball.json to student_sdf" >&2
    exit 1
  }
  export PINSIM_PLUGIN_PATH="$TMP/starter_build:$PLUGINS"
  step "pinsim validate, run and render the pinball table with student_sdf"
  "$PINSIM" -q validate "$TMP/pinball_student.json"
  "$PINSIM" -q run "$ROOT/configs/pinball.json" --backend student_sdf --set time.duration=1 \
    --out "$TMP/starter_run"
  # The ball starts resting on the plunger: the starter must report contacts with it.
  local contacts
  contacts=$(($(wc -l <"$TMP/starter_run/events.csv") - 1))
  grep -q ',plunger,' "$TMP/starter_run/events.csv" || {
    echo "student_sdf reported no contact with the plunger ($contacts events)" >&2
    exit 1
  }
  echo "student_sdf: $contacts contacts in 1 s of the pinball table"
  # The table is drawn from the backend's outline() (FieldBackend): no warning about it.
  "$PINSIM" render "$TMP/starter_run" --out "$TMP/starter.png" 2>"$TMP/render.log"
  [ -s "$TMP/starter.png" ] || { echo "render wrote no picture" >&2; cat "$TMP/render.log" >&2; exit 1; }
  if grep -q "does not report its obstacles' outlines" "$TMP/render.log"; then
    echo "student_sdf has no outline(): the table is not drawn" >&2
    cat "$TMP/render.log" >&2
    exit 1
  fi
  step "pinsim play the table with student_sdf (no window: SDL's dummy video driver), rerun it"
  SDL_VIDEODRIVER=dummy "$PINSIM" -q play "$TMP/pinball_student.json" --seconds 0.3 \
    --record "$TMP/game.json" --screenshot "$TMP/game.png" 2>"$TMP/play.log" || {
    cat "$TMP/play.log" >&2
    exit 1
  }
  [ -s "$TMP/game.png" ] && [ -s "$TMP/game.json" ] || { echo "play wrote no frame or recording" >&2; exit 1; }
  if grep -q "does not report its obstacles' outlines" "$TMP/play.log"; then
    echo "play: student_sdf has no outline()" >&2
    exit 1
  fi
  "$PINSIM" play "$TMP/pinball_student.json" --rerun "$TMP/game.json" | tee "$TMP/rerun.log"
  grep -q "identical to the recording" "$TMP/rerun.log" || { echo "the rerun differs" >&2; exit 1; }
  unset PINSIM_PLUGIN_PATH
  echo "STARTER OK: student_sdf built against $(dirname "$CONFIG"), run, rendered, played"
}
if [ "$STARTER_ONLY" = 1 ]; then
  test_starter
  exit 0
fi

step "the installed pinsim loads the installed plugins (not the build tree's)"
first_found() {  # the first path `pinsim plugins` lists for plugin $2 (the one loaded)
  "$1" plugins | awk -v f="/libpinsim_plugin_$2.so" \
    'substr($1, length($1) - length(f) + 1) == f && !n++ { print $1 }'
}
got=$(first_found "$PINSIM" gravity)
[ "$got" = "$PLUGINS/libpinsim_plugin_gravity.so" ] || {
  echo "the installed pinsim loads $got, not $PLUGINS/libpinsim_plugin_gravity.so" >&2
  exit 1
}
step "a copy of the install moved elsewhere still finds its own plugins"
cp -r "$TMP/prefix" "$TMP/moved"
want="$TMP/moved${PLUGINS#"$TMP/prefix"}/libpinsim_plugin_sdf.so"
got=$(first_found "$TMP/moved/bin/pinsim" sdf)
[ "$got" = "$want" ] || { echo "the moved install loads $got, not $want" >&2; exit 1; }
"$TMP/moved/bin/pinsim" -q run "$ROOT/configs/empty_box.json" --out "$TMP/moved_out"
[ -s "$TMP/moved_out/trajectory.csv" ] || { echo "the moved install wrote no trajectory" >&2; exit 1; }

step "build sdk/template_plugin out of tree against the installed SDK, exactly as documented"
cp -r "$ROOT/sdk/template_plugin" "$TMP/src"
# No -DCMAKE_BUILD_TYPE: the package must make it an optimised (Release) build.
run_logged configure cmake -S "$TMP/src" -B "$TMP/build" -DCMAKE_PREFIX_PATH="$TMP/prefix"
build_type=$(sed -n 's/^CMAKE_BUILD_TYPE:[A-Z]*=//p' "$TMP/build/CMakeCache.txt")
[ "$build_type" = "Release" ] || {
  echo "the template configured without a build type is '$build_type', not Release" >&2
  exit 1
}
run_logged build cmake --build "$TMP/build" -j2 --verbose
grep -q -- '-O3' "$TMP/build.log" || { echo "the template was not compiled with -O3" >&2; exit 1; }
SO="$TMP/build/libpinsim_plugin_my_anchor.so"
[ -f "$SO" ] || { echo "the template did not produce $SO" >&2; exit 1; }
step "an explicit build type is kept"
run_logged configure_debug cmake -S "$TMP/src" -B "$TMP/build_debug" -DCMAKE_BUILD_TYPE=Debug \
  -DCMAKE_PREFIX_PATH="$TMP/prefix"
grep -q '^CMAKE_BUILD_TYPE:STRING=Debug$' "$TMP/build_debug/CMakeCache.txt" || {
  echo "-DCMAKE_BUILD_TYPE=Debug was overridden" >&2
  exit 1
}

step "pinsim check-plugin on the built template, by path and by name"
"$PINSIM" check-plugin "$SO" | tee "$TMP/check.log"
# its parameter derivatives (add_dforce_dparam) are checked too
grep -Eq '^  pass +dparam ' "$TMP/check.log" || { echo "no passing dparam check" >&2; exit 1; }
if env -u PINSIM_PLUGIN_PATH "$PINSIM" check-plugin my_anchor >"$TMP/by_name.log" 2>&1; then
  echo "check-plugin found my_anchor by name without a search path" >&2
  exit 1
fi
grep -q "unknown plugin 'my_anchor'" "$TMP/by_name.log" || { cat "$TMP/by_name.log" >&2; exit 1; }
PINSIM_PLUGIN_PATH="$TMP/build" "$PINSIM" check-plugin my_anchor -p k=5 >/dev/null
env -u PINSIM_PLUGIN_PATH "$PINSIM" check-plugin my_anchor --plugin-path "$TMP/build" >/dev/null

step "pinsim run a scene that uses it"
PINSIM_PLUGIN_PATH="$TMP/build:$PLUGINS" "$PINSIM" -q run "$TMP/src/scene.json" --out "$TMP/out"
[ -s "$TMP/out/trajectory.csv" ] || { echo "the run wrote no trajectory" >&2; exit 1; }
step "pinsim grad in its parameters, through its own derivatives"
PINSIM_PLUGIN_PATH="$TMP/build:$PLUGINS" "$PINSIM" -q grad "$TMP/src/scene.json" \
  --set time.duration=0.2 --loss final:0:x --wrt 'forces[0].params.k' 'forces[0].params.anchor' \
  --out "$TMP/grad"
grep -q '"parameter derivative": "plugin"' "$TMP/grad/gradient.json" || {
  echo "pinsim grad did not use the template's add_dforce_dparam" >&2
  exit 1
}
echo "SDK OK: template built against $(dirname "$CONFIG"), checked and run"
if [ "$TEMPLATE_ONLY" = 0 ]; then
  test_starter
fi
