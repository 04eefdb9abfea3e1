#!/usr/bin/env bash
# Installs the Debian packages pinsim needs (only the missing ones), then configures and
# builds the release preset. Safe to run again: it does only what is left to do.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(cmake g++ make pkg-config libeigen3-dev libboost-dev libspdlog-dev catch2
          nlohmann-json3-dev libcli11-dev libbox2d-dev
          libcairo2-dev libsdl2-dev chromium xvfb xauth gnuplot-nox python3-jsonschema
          slurm-wlm munge bubblewrap clang libclang-rt-14-dev)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "setup: installing missing Debian packages: ${missing[*]}"
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

jobs=$(nproc 2>/dev/null || echo 2)
cmake --preset release >/dev/null
cmake --build --preset release -j "$jobs"
