#!/usr/bin/env bash
# `pinsim share --source` as a student uses it, from an install and nothing of the source tree
# but the kit: install the native build and the web SDK (the web preset's build) to a
# temporary prefix; build sdk/pinball_starter natively against it; share a table that names
# student_sdf with the kit's folder as --source; check that only the kit was compiled for
# the page (the engine is prebuilt), that no line of its source is in the page (HTML or the
# wasm inside it), that a folder that does not compile fails with the compiler's message and
# leaves the previous page as it was; then play the page in headless Chromium and Firefox,
# rerun its recording natively with the kit's native build (same state hash), and rerun a
# native recording in the page.
# Usage: share_source.sh RELEASE_BUILD WEB_BUILD   (exit 77: skipped, the web SDK or
#   Emscripten or the browser harness is missing)
set -euo pipefail
ROOT=$(cd "$(dirname "$0")/../.." && pwd)
RELEASE=$(cd "$1" && pwd)
WEB=$2
[ -f "$WEB/web-sdk/cmake/pinsimConfig.cmake" ] || {
  echo "SKIPPED: no web SDK in $WEB/web-sdk (build the web preset first)"
  exit 77
}
command -v emcmake >/dev/null || { echo "SKIPPED: emcmake (Debian's emscripten) is not installed"; exit 77; }
[ -d "$ROOT/tests/web/node_modules/puppeteer-core" ] || {
  echo "SKIPPED: tests/web/node_modules is not installed (scripts/setup.sh runs npm ci there)"
  exit 77
}
TMP=$(mktemp -d "${TMPDIR:-/tmp}/pinsim-share-source.XXXXXX")
trap 'rm -rf "$TMP"' EXIT
export NODE_PATH=${NODE_PATH:-/usr/share/nodejs}

echo "== install the native build and the web SDK to $TMP/prefix"
cmake --install "$RELEASE" --prefix "$TMP/prefix" >"$TMP/install.log"
cmake --install "$WEB" --prefix "$TMP/prefix" >>"$TMP/install.log"
PINSIM=$TMP/prefix/bin/pinsim
[ -f "$TMP/prefix/share/pinsim/web/pinsim_web.js" ] || { echo "the web engine was not installed" >&2; exit 1; }

echo "== build the kit natively, as the guide says"
cp -r "$ROOT/sdk/pinball_starter" "$TMP/kit"
cmake -S "$TMP/kit" -B "$TMP/kit_build" -DCMAKE_PREFIX_PATH="$TMP/prefix" >"$TMP/native.log"
cmake --build "$TMP/kit_build" -j2 >>"$TMP/native.log"
export PINSIM_PLUGIN_PATH=$TMP/kit_build
sed -e 's/"name": "sdf",/"name": "student_sdf",/' \
  -e 's/"params": {"depth_min": [^}]*}/"params": {}/' \
  "$TMP/prefix/share/pinsim/configs/pinball.json" >"$TMP/my_table.json"
grep -q '"name": "student_sdf"' "$TMP/my_table.json"

echo "== pinsim share --source (the installed pinsim, the installed web SDK)"
t0=$SECONDS
"$PINSIM" share "$TMP/my_table.json" --source "$TMP/kit" --web-build "$TMP/web_build" \
  --out "$TMP/page.html"
echo "share --source took $((SECONDS - t0)) s"
# Only the kit's source and the generated plugin table were compiled: the engine is prebuilt.
compiled=$(grep -c "Building CXX object" "$TMP/web_build/build.log" || true)
echo "files compiled for the page: $compiled"
grep "Building CXX object" "$TMP/web_build/build.log"
[ "$compiled" -eq 2 ] || { echo "expected 2 files compiled (student_sdf.cpp, the plugin table)" >&2; exit 1; }
grep -q "student_sdf.cpp" "$TMP/web_build/build.log"
grep -qx "student_sdf" "$TMP/web_build/build/pinsim_web.plugins"
node "$ROOT/tests/share/page_has_no_source.js" "$TMP/page.html" "$TMP/kit/student_sdf.cpp"

echo "== a folder that does not compile: the compiler's message, the old page kept"
cp -r "$TMP/kit" "$TMP/broken"
echo "this is not C++;" >>"$TMP/broken/student_sdf.cpp"
cp "$TMP/page.html" "$TMP/page_before.html"
if "$PINSIM" share "$TMP/my_table.json" --source "$TMP/broken" --out "$TMP/page.html" \
  2>"$TMP/broken.log"; then
  echo "share --source of a folder that does not compile succeeded" >&2
  exit 1
fi
grep -q "student_sdf.cpp.*error" "$TMP/broken.log" || { cat "$TMP/broken.log" >&2; exit 1; }
cmp -s "$TMP/page.html" "$TMP/page_before.html" || { echo "the previous page was changed" >&2; exit 1; }
if "$PINSIM" share "$TMP/my_table.json" --source "$TMP/no_such_folder" --out "$TMP/x.html" \
  2>"$TMP/missing.log"; then
  echo "share --source of a missing folder succeeded" >&2
  exit 1
fi
grep -q "no_such_folder: no such folder" "$TMP/missing.log" || { cat "$TMP/missing.log" >&2; exit 1; }

for browser in chromium firefox; do
  echo "== the page in $browser"
  rc=0
  node "$ROOT/tests/share/test_share_page.js" "$browser" --pinsim "$PINSIM" \
    --scene "$TMP/my_table.json" --page "$TMP/page.html" || rc=$?
  [ "$rc" -eq 0 ] || exit "$rc"
done
echo "SHARE --SOURCE OK"
