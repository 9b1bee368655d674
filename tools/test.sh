#!/usr/bin/env bash
# Builds ScopeTrack and runs the whole test suite (the README's test command).
#   tools/test.sh              Release build in build/, warnings as errors
#   tools/test.sh --sanitize   ASan + UBSan build in build-asan/, without the tests
#                              labelled "long" (whole-sequence replays and renders,
#                              which the Release run covers)
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup-deps.sh

build=build
opts=(-DSCOPETRACK_WERROR=ON)
ctest_opts=()
export SCOPETRACK_TIME_SCALE=${SCOPETRACK_TIME_SCALE:-1}
if [[ "${1:-}" == "--sanitize" ]]; then
  build=build-asan
  opts+=(-DSCOPETRACK_SANITIZE=ON -DCMAKE_BUILD_TYPE=RelWithDebInfo -DSCOPETRACK_BUILD_BENCH=OFF)
  export SCOPETRACK_TIME_SCALE=10
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
  export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  ctest_opts+=(--label-exclude long)
fi
if command -v ccache >/dev/null; then opts+=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi

cmake -S . -B "$build" "${opts[@]}"
cmake --build "$build" -j"$(nproc)"
# Parallel on every core; the doctest suite "serial" runs alone (tests/CMakeLists.txt).
ctest --test-dir "$build" --output-on-failure -j"$(nproc)" "${ctest_opts[@]}"
