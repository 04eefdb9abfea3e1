#!/usr/bin/env bash
# Installs the Debian packages pinsim needs (only the missing ones), then configures and
# builds the release preset. Safe to run again: it does only what is left to do.
#   scripts/setup.sh [run|test]
# run (the default; README command 1): the packages that build pinsim and its plugins and
#   backends, then only the `pinsim` program and the plugins (target pinsim_run): what
#   `pinsim run`, render, grade, crosscheck need; `play` and HDF5 output when their packages
#   (libsdl2-dev, libhdf5-dev) are installed.
# test (README command 2): also SDL2 and HDF5 and what only the tests, benches and CI stages
#   need (Catch2, browsers, Emscripten, clang, Slurm, node and npm, gnuplot, h5py), then the
#   whole build.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:-run}
case "$mode" in
  run|test) ;;
  *) echo "setup: unknown mode '$mode' (expected run or test)" >&2; exit 2 ;;
esac

# Building pinsim, its plugins and backends (and, for `pinsim grade`, source submissions in
# a bubblewrap sandbox).
packages=(cmake g++ make pkg-config libeigen3-dev libboost-dev libspdlog-dev
          nlohmann-json3-dev libcli11-dev libbox2d-dev libtbb-dev libcairo2-dev liblbfgspp-dev
          bubblewrap)
# What the main job does not need, with many packages of their own: `pinsim play`'s window
# (SDL2, with its X11, Wayland and sound headers) and HDF5 trajectories. `run` builds with
# them when they are installed, `test` installs them.
optional=(libsdl2-dev libhdf5-dev)
if [ "$mode" = test ]; then
  packages+=("${optional[@]}")
  # The tests (Catch2, schema and HDF5 checks, browser and Slurm tests), the bench and stress
  # figures (gnuplot), the web build (Emscripten) and the asan and fuzz stages (clang).
  packages+=(catch2 python3-jsonschema hdf5-tools python3-h5py gnuplot-nox chromium xvfb
             xauth firefox-esr emscripten slurm-wlm munge clang libclang-rt-14-dev ccache)
fi
installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }
missing=()
for p in "${packages[@]}"; do
  installed "$p" || missing+=("$p")
done
if [ "$mode" = test ]; then
  # node and npm for the browser tests (tests/web): Debian's nodejs (18.20 on bookworm) and
  # npm (9.2), only when the commands are missing - a node from elsewhere (nodesource's
  # nodejs ships its own npm and conflicts with Debian's npm package) is used as it is.
  command -v node >/dev/null 2>&1 || missing+=(nodejs)
  command -v npm >/dev/null 2>&1 || missing+=(npm)
fi
if ((${#missing[@]})); then
  echo "setup: installing missing Debian packages: ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  t0=$SECONDS
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
  echo "setup: ${#missing[@]} packages (and their dependencies) installed in $((SECONDS - t0)) s"
fi

# A compiler cache, when ccache is installed (`setup.sh test` installs it; CI runs that):
# build folders configured from here compile through it, with paths below this clone made
# relative, so a second clone (CI's clean clone) reuses what an earlier build compiled.
# ccache keys on the preprocessed source, the compiler and every flag: a hit is the object
# the compiler would make. CCACHE_DISABLE=1 turns it off; scripts/ccache_env.sh.
. scripts/ccache_env.sh

jobs=$(nproc 2>/dev/null || echo 2)
if [ "$mode" = run ]; then
  # SDL2 and HDF5 where their packages are installed (always after `setup.sh test`).
  with=()
  installed libsdl2-dev && with+=(-DPINSIM_WITH_SDL2=ON) || with+=(-DPINSIM_WITH_SDL2=OFF)
  installed libhdf5-dev && with+=(-DPINSIM_WITH_HDF5=ON) || with+=(-DPINSIM_WITH_HDF5=OFF)
  # A first configure leaves out the tests and benches (Catch2 is not installed yet); a build
  # folder configured by `setup.sh test` keeps them.
  t0=$SECONDS
  if [ -f build/release/CMakeCache.txt ]; then
    cmake --preset release "${with[@]}" >/dev/null
  else
    cmake --preset release "${with[@]}" -DPINSIM_BUILD_TESTS=OFF -DPINSIM_BUILD_BENCH=OFF >/dev/null
  fi
  cmake --build --preset release -j "$jobs" --target pinsim_run
  echo "setup: configured and built the program and its plugins in $((SECONDS - t0)) s"
  exit 0
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

cmake --preset release -DPINSIM_BUILD_TESTS=ON -DPINSIM_BUILD_BENCH=ON -DPINSIM_WITH_SDL2=ON \
  -DPINSIM_WITH_HDF5=ON >/dev/null
cmake --build --preset release -j "$jobs"
