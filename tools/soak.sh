#!/usr/bin/env bash
# Hours of operation in one run: builds ScopeTrack (tools/build.sh) and runs
# scopetrack-soak for FRAMES frames (default 100,000; about 14 min at
# 640x360 on the 2-core machine) into out/soak/: report.txt, soak.csv (a
# sample every 1,000 frames), soak.png, the tracker's output in run/.
# Exit status 0 when every check passed (tools/soak/soak_run.h).
#   tools/soak.sh [FRAMES] [scopetrack-soak options...]
set -euo pipefail
cd "$(dirname "$0")/.."
frames=${1:-100000}
shift || true
build=$(bash tools/build.sh)
exec "$build/bin/scopetrack-soak" --out out/soak --frames "$frames" --segment-frames 500 "$@"
