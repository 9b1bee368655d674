#!/usr/bin/env bash
# Builds the libFuzzer targets in build-fuzz/ and runs each for SECONDS
# (default 60), one at a time, from the seeds in tools/fuzz/seeds, and
# prints each one's executions, speed, peak memory and coverage.
#   tools/fuzz/run.sh [SECONDS] [target...]     targets: y4m ply stl sequence_yaml tum markers register_pairs console_stream
#   FUZZ_RUNS=N tools/fuzz/run.sh SECONDS ...    stop each target after N inputs instead (SECONDS still caps it)
# Crashes land in build-fuzz/fuzz-out/<target>/crash-*; reproduce with
#   build-fuzz/bin/fuzz_<target> build-fuzz/fuzz-out/<target>/crash-...
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:-60}
shift || true
targets=("$@")
[[ ${#targets[@]} -gt 0 ]] || targets=(y4m ply stl sequence_yaml tum markers register_pairs console_stream)
cmake -S . -B build-fuzz -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
  -DSCOPETRACK_FUZZ=ON -DSCOPETRACK_BUILD_TESTS=OFF -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build build-fuzz -j"$(nproc)" --target $(printf 'fuzz_%s ' "${targets[@]}")
for t in "${targets[@]}"; do
  out=build-fuzz/fuzz-out/$t
  mkdir -p "$out/corpus"
  cp -n tools/fuzz/seeds/$t/* "$out/corpus/" 2>/dev/null || true
  echo "== fuzz_$t for ${seconds}s"
  runs=()
  [[ -n "${FUZZ_RUNS:-}" ]] && runs=(-runs="$FUZZ_RUNS")
  ASAN_OPTIONS=detect_leaks=1 build-fuzz/bin/fuzz_$t -max_total_time="$seconds" "${runs[@]}" -max_len=65536 \
    -rss_limit_mb=2048 -timeout=10 -artifact_prefix="$out/" -print_final_stats=1 "$out/corpus" 2>"$out/log.txt" || {
    echo "fuzz_$t FAILED: see $out/log.txt"; tail -30 "$out/log.txt"; exit 1; }
  # Executions, speed and memory from the final stats; coverage (edges,
  # features, corpus) from libFuzzer's last status line.
  grep -E "stat::number_of_executed_units|stat::average_exec_per_sec|stat::peak_rss_mb" "$out/log.txt" | sed "s/^/  /"
  grep -E "^#[0-9]+[[:space:]]+DONE" "$out/log.txt" | tail -1 |
    sed -E "s/.*(cov: [0-9]+ ft: [0-9]+ corp: [0-9]+\/[^ ]+).*/  coverage (edges, features, corpus): \1/" || true
done
