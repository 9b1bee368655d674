#!/bin/sh
# Comparison sheet: one simulated frame of every scenario next to the real
# laparoscopic frame of the shared data (tools/sim/sim_vs_real.jpg).
#   tools/sim/make_comparison.sh [BUILD_BIN (build/bin)] [OUT (tools/sim/sim_vs_real.jpg)] [FRAME (150)]
# Simulates each scenario (300 frames, default size, seed 1) into a
# temporary folder, takes frame FRAME of each video, and tiles 480x270
# thumbnails 2 x 3 with ffmpeg: real | invivo / orbit | fast /
# outofview | manipulation, each labelled.
set -eu
BIN=${1:-build/bin}
OUT=${2:-tools/sim/sim_vs_real.jpg}
FRAME=${3:-150}
REAL=$(dirname "$0")/../../../shared/data/real/laparoscopy_liver_1080p.jpg
FONT=/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf
TMP=$(mktemp -d)
trap 'rm -rf "$TMP"' EXIT
for s in invivo orbit fast outofview manipulation; do
  "$BIN/scopetrack-sim" --scenario "$s" --frames 300 --out "$TMP/$s" > /dev/null
done
label() {  # drawtext filter for a thumbnail title
  echo "scale=480:270,drawtext=fontfile=$FONT:text='$1':x=8:y=8:fontsize=20:fontcolor=white:box=1:boxcolor=black@0.5"
}
frame() { echo "select=eq(n\\,$FRAME),$(label "$1 (frame $FRAME)")"; }
ffmpeg -v error -y -i "$REAL" -i "$TMP/invivo/video.y4m" -i "$TMP/orbit/video.y4m" -i "$TMP/fast/video.y4m" \
  -i "$TMP/outofview/video.y4m" -i "$TMP/manipulation/video.y4m" -filter_complex \
  "[0:v]$(label 'real (shared/data/real)')[a];[1:v]$(frame invivo)[b];[2:v]$(frame orbit)[c];\
[3:v]$(frame fast)[d];[4:v]$(frame outofview)[e];[5:v]$(frame manipulation)[f];\
[a][b][c][d][e][f]xstack=inputs=6:layout=0_0|w0_0|0_h0|w0_h0|0_h0+h0|w0_h0+h0[out]" \
  -map "[out]" -frames:v 1 -q:v 3 "$OUT"
echo "wrote $OUT"
