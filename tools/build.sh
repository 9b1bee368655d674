#!/usr/bin/env bash
# Configures and builds ScopeTrack, the one way both README commands do it
# (tools/demo.sh and tools/test.sh), so that the second reuses the first's
# build instead of configuring build/ with other options and rebuilding.
#   tools/build.sh              Release in build/, warnings as errors
#   tools/build.sh --sanitize   ASan + UBSan (RelWithDebInfo) in build-asan/, no bench
# Prints the build folder's name on its last line.
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup-deps.sh >&2

build=build
opts=(-DSCOPETRACK_WERROR=ON)
if [[ "${1:-}" == "--sanitize" ]]; then
  build=build-asan
  opts+=(-DSCOPETRACK_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSCOPETRACK_BUILD_BENCH=OFF)
elif [[ $# -gt 0 ]]; then
  echo "usage: tools/build.sh [--sanitize]" >&2
  exit 2
fi
if command -v ccache >/dev/null; then opts+=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi

cmake -S . -B "$build" "${opts[@]}" >&2
cmake --build "$build" -j"$(nproc)" >&2
echo "$build"
