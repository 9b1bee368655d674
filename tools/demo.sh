#!/usr/bin/env bash
# The main job end to end on a built-in default (the README's first command):
# installs the packages, builds, simulates a 1280x720 orbit sequence with
# exact ground truth, checks it, tracks it, and prints the evaluation.
#   tools/demo.sh [SCENARIO] [FRAMES]     default: orbit 300
set -euo pipefail
cd "$(dirname "$0")/.."
scenario=${1:-orbit}
frames=${2:-300}
out=out/demo-$scenario

# The same build as tools/test.sh's (tools/build.sh): the test command
# after this one does not build again.
bash tools/build.sh >/dev/null

rm -rf "$out"
echo "== simulate: $scenario, $frames frames -> $out/sequence"
build/bin/scopetrack-sim --scenario "$scenario" --frames "$frames" --seed 1 --out "$out/sequence"
echo "== check"
build/bin/scopetrack --check "$out/sequence"
echo "== track"
build/bin/scopetrack --sequence "$out/sequence" --out "$out/run"
echo "== evaluate ($out/run)"
build/bin/scopetrack-eval "$out/sequence" "$out/run"
