#!/usr/bin/env bash
# Installs BUILD_DIR to a temporary prefix and runs the installed pinsim from a folder outside
# the source tree: a shipped scene and a shipped rubric named without a folder are found in
# PREFIX/share/pinsim, and the plugin template is installed beside them.
set -euo pipefail
build=$1
tmp=$(mktemp -d "${TMPDIR:-/tmp}/pinsim-install.XXXXXX")
trap 'rm -rf "$tmp"' EXIT
tmp=$(cd "$tmp" && pwd -P)  # as /proc/self/exe names it
fail() { echo "FAILED: $*" >&2; exit 1; }

cmake --install "$build" --prefix "$tmp/prefix" >"$tmp/install.log" 2>&1 ||
  { cat "$tmp/install.log" >&2; fail "cmake --install"; }
share=$tmp/prefix/share/pinsim
for f in configs/pinball.json configs/grading/force_assignment.json \
         configs/grading/scenes/spring_chain.json sdk/template_plugin/CMakeLists.txt \
         sdk/template_plugin/my_anchor.cpp; do
  [ -f "$share/$f" ] || fail "$share/$f not installed"
done

mkdir "$tmp/elsewhere"
cd "$tmp/elsewhere"
pinsim=$tmp/prefix/bin/pinsim

# A scene by its name: the shipped one under PREFIX, not a file here or in the source tree.
out=$("$pinsim" run projectile.json --out run 2>&1) || { echo "$out" >&2; fail "run projectile.json"; }
[ -f run/summary.json ] || fail "run projectile.json wrote no summary.json"
[[ "$out$(cat run/summary.json)" == *"$share/configs/projectile.json"* ]] ||
  fail "the run did not name $share/configs/projectile.json: $out"
# A name without .json, in a subfolder of the shipped scenes.
"$pinsim" run grading/scenes/spring_chain --out run2 >"$tmp/run2.log" 2>&1 ||
  { cat "$tmp/run2.log" >&2; fail "run grading/scenes/spring_chain"; }

# A missing scene says where it was looked for.
if "$pinsim" run no_such_scene.json --out run3 >"$tmp/run3.log" 2>&1; then fail "no_such_scene.json ran"; fi
grep -q "no_such_scene.json: scene file not found (nor in $share/configs)" "$tmp/run3.log" ||
  { cat "$tmp/run3.log" >&2; fail "missing scene: unexpected message"; }

# A rubric by its name: loaded (the error is then about the submission, not the rubric).
"$pinsim" grade --rubric force_assignment --submission "$tmp/no_submission" --out grade \
  >"$tmp/grade.log" 2>&1 || true
if grep -q "rubric file not found" "$tmp/grade.log"; then cat "$tmp/grade.log" >&2; fail "rubric not found"; fi
grep -q "no_submission" "$tmp/grade.log" || { cat "$tmp/grade.log" >&2; fail "grade: no word on the submission"; }
echo "ok: $share"
