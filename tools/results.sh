#!/usr/bin/env bash
# Reruns the scenario table of docs/results.md: for each simulator scenario
# and seed, simulate a sequence with exact ground truth, track it, evaluate
# it, and print one Markdown table row.
#
#   tools/results.sh [--quick] [SEED ...]        seeds default to: 1 2
#
#   --quick            60 frames, seed 1 only (a smoke test of the chain)
#   BIN=DIR            the built programs (default: build/bin of this checkout)
#   FRAMES=N           frames per sequence (default 300)
#   OUT=DIR            where sequences and runs go (default: out/results)
#   BA_LAG=N           scopetrack --ba-lag N (default 3: deterministic replays;
#                      0: live bundle adjustment, as the tracker runs on a camera)
#   SCENARIOS="..."    a subset of: orbit fast outofview manipulation invivo
#   EXTRA="..."        more arguments for every scopetrack --sequence call,
#                      split at spaces, e.g. EXTRA='--set use_ba=0' (an
#                      ablation) or EXTRA='--config my-settings.yaml'
#                      (scopetrack --print-config lists the settings)
#
# Each scenario renders at the simulator's default size (1280x720; invivo
# 960x540). fps is the tracker's own figure from summary.json: it depends on
# the machine and its load (docs/results.md, "Run-to-run noise").
set -euo pipefail

root=$(cd "$(dirname "$0")/.." && pwd)
bin=${BIN:-$root/build/bin}
frames=${FRAMES:-300}
out=${OUT:-$root/out/results}
ba_lag=${BA_LAG:-3}
scenarios=${SCENARIOS:-orbit fast outofview manipulation invivo}
read -r -a extra_args <<<"${EXTRA:-}"

seeds=()
quick=0
for arg in "$@"; do
  case "$arg" in
    --quick) quick=1 ;;
    -h|--help) sed -n '2,22p' "$0" | sed 's/^# \{0,1\}//'; exit 0 ;;
    ''|*[!0-9]*) echo "results.sh: unknown argument '$arg' (a seed is a whole number)" >&2; exit 2 ;;
    *) seeds+=("$arg") ;;
  esac
done
if (( quick )); then
  frames=60
  seeds=(1)
fi
(( ${#seeds[@]} )) || seeds=(1 2)
if ! [[ "$frames" =~ ^[0-9]+$ && "$ba_lag" =~ ^[0-9]+$ ]]; then
  echo "results.sh: FRAMES and BA_LAG must be whole numbers" >&2
  exit 2
fi

for tool in scopetrack scopetrack-sim scopetrack-eval; do
  if [[ ! -x "$bin/$tool" ]]; then
    echo "results.sh: $bin/$tool not found: build first (bash tools/test.sh) or set BIN=DIR" >&2
    exit 1
  fi
done

lag_args=()
if (( ba_lag > 0 )); then lag_args=(--ba-lag "$ba_lag"); fi

# The value of "key" in scopetrack-eval's one-line JSON (null if absent).
json_field() {
  local v
  v=$(sed -n "s/.*\"$2\": *\([^,}]*\).*/\1/p" <<<"$1")
  echo "${v:-null}"
}
# A number with the given decimals, or "-" for null.
fmt() {
  if [[ "$1" == null ]]; then echo "-"; else printf "%.${2}f" "$1"; fi
}

mkdir -p "$out"
lag_text="--ba-lag $ba_lag"
(( ba_lag > 0 )) || lag_text="live BA (no --ba-lag)"
extra_text=""
if (( ${#extra_args[@]} )); then extra_text=", ${extra_args[*]}"; fi
echo "Scenarios, $frames frames, $lag_text$extra_text, binaries from $bin"
echo
echo "| scenario | seed | lost % | wrong % | TRE median / p95 px | fps |"
echo "|---|---|---|---|---|---|"
for scenario in $scenarios; do
  for seed in "${seeds[@]}"; do
    dir=$out/$scenario-seed$seed-$frames
    seq=$dir/sequence
    run=$dir/run
    log=$dir/log.txt
    rm -rf "$dir"
    mkdir -p "$dir"
    if ! "$bin/scopetrack-sim" --scenario "$scenario" --seed "$seed" --frames "$frames" \
           --out "$seq" >"$log" 2>&1 ||
       ! "$bin/scopetrack" --sequence "$seq" --out "$run" "${lag_args[@]}" "${extra_args[@]}" >>"$log" 2>&1 ||
       ! json=$("$bin/scopetrack-eval" "$seq" "$run" --json 2>>"$log"); then
      echo "results.sh: $scenario seed $seed failed; its log ($log):" >&2
      tail -n 20 "$log" >&2
      exit 1
    fi
    echo "$json" >"$dir/eval.json"
    printf '| %s | %s | %s | %s | %s / %s | %s |\n' "$scenario" "$seed" \
      "$(fmt "$(json_field "$json" lost_pct)" 1)" "$(fmt "$(json_field "$json" wrong_pct)" 1)" \
      "$(fmt "$(json_field "$json" tre_median_px)" 2)" "$(fmt "$(json_field "$json" tre_p95_px)" 2)" \
      "$(fmt "$(json_field "$json" fps)" 1)"
  done
done
