# Sourced by scripts/setup.sh and scripts/test.sh: when ccache is installed, the CMake build
# folders configured afterwards compile through it (CMake takes CMAKE_<LANG>_COMPILER_LAUNCHER
# from the environment when it first configures a folder; a folder configured earlier keeps
# its setting). CCACHE_BASEDIR makes the paths below this clone relative in ccache's keys, so
# two clones in different places share their objects; CCACHE_NOHASHDIR, for the same reason,
# leaves the build folder out of the key of objects with debug line tables (the asan build:
# their debug information then names the folder that first compiled them). An explicit
# launcher in the environment, or CCACHE_DISABLE=1, is left as it is.
if command -v ccache >/dev/null 2>&1 && [ -z "${CMAKE_CXX_COMPILER_LAUNCHER:-}" ]; then
  export CMAKE_C_COMPILER_LAUNCHER=ccache CMAKE_CXX_COMPILER_LAUNCHER=ccache
  export CCACHE_BASEDIR=${CCACHE_BASEDIR:-$PWD} CCACHE_NOHASHDIR=${CCACHE_NOHASHDIR:-true}
fi
