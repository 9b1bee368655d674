#!/usr/bin/env bash
# Builds ScopeTrack and runs the whole test suite (the README's test command).
#   tools/test.sh              Release build in build/ (tools/build.sh), warnings as errors
#   tools/test.sh --sanitize   ASan + UBSan build in build-asan/, without the tests
#                              labelled "long" (whole-sequence replays and renders,
#                              which the Release run covers)
set -euo pipefail
cd "$(dirname "$0")/.."

ctest_opts=()
export SCOPETRACK_TIME_SCALE=${SCOPETRACK_TIME_SCALE:-1}
if [[ "${1:-}" == "--sanitize" ]]; then
  build=$(bash tools/build.sh --sanitize)
  export SCOPETRACK_TIME_SCALE=10
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1
  export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  ctest_opts+=(--label-exclude long)
else
  build=$(bash tools/build.sh)
fi
# Parallel on every core; the doctest suite "serial" runs alone (tests/CMakeLists.txt).
ctest --test-dir "$build" --output-on-failure -j"$(nproc)" "${ctest_opts[@]}"
