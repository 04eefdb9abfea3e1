#!/usr/bin/env bash
# ctest's entry to the browser tests: runs `node SCRIPT ARGS...` from tests/web, or exits 77
# (the tests' SKIP_RETURN_CODE) when node or tests/web/node_modules is absent -
# scripts/setup.sh installs both (Debian's nodejs and npm, then `npm ci`).
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
if ! command -v node >/dev/null 2>&1; then
  echo "SKIPPED: node is not installed (scripts/setup.sh installs Debian's nodejs)"
  exit 77
fi
if [ ! -d "$here/node_modules/puppeteer-core" ]; then
  echo "SKIPPED: $here/node_modules is not installed (scripts/setup.sh runs npm ci there)"
  exit 77
fi
script="$1"
shift
exec node "$here/$script" "$@"
