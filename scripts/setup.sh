#!/usr/bin/env bash
# Installs the Debian packages pinsim needs (only the missing ones), then configures and
# builds the release preset. Safe to run again: it does only what is left to do.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(cmake g++ make pkg-config libeigen3-dev libboost-dev libspdlog-dev catch2
          nlohmann-json3-dev libcli11-dev libbox2d-dev libtbb-dev
          libcairo2-dev libsdl2-dev chromium xvfb xauth gnuplot-nox python3-jsonschema
          slurm-wlm munge bubblewrap clang libclang-rt-14-dev firefox-esr emscripten
          libhdf5-dev hdf5-tools python3-h5py liblbfgspp-dev)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
# node and npm for the browser tests (tests/web): Debian's nodejs (18.20 on bookworm) and
# npm (9.2), only when the commands are missing - a node from elsewhere (nodesource's nodejs
# ships its own npm and conflicts with Debian's npm package) is used as it is.
command -v node >/dev/null 2>&1 || missing+=(nodejs)
command -v npm >/dev/null 2>&1 || missing+=(npm)
if ((${#missing[@]})); then
  echo "setup: installing missing Debian packages: ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

# The browser tests' node modules (puppeteer-core, pngjs; pinned in tests/web/package-lock.json)
# into tests/web/node_modules (not committed). Skipped when that lock file is already
# installed, so this needs the npm registry only the first time; if npm ci fails (offline),
# the browser tests skip.
web=tests/web
if command -v npm >/dev/null 2>&1 && ! cmp -s "$web/package-lock.json" "$web/node_modules/.pinsim-installed-lock"; then
  echo "setup: npm ci in $web"
  if (cd "$web" && npm ci --no-audit --no-fund --loglevel=error); then
    cp "$web/package-lock.json" "$web/node_modules/.pinsim-installed-lock"
  else
    echo "setup: warning: npm ci in $web failed; the browser tests (ctest -L web) will skip" >&2
  fi
fi

jobs=$(nproc 2>/dev/null || echo 2)
cmake --preset release >/dev/null
cmake --build --preset release -j "$jobs"
