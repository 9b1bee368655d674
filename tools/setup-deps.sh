#!/usr/bin/env bash
# Installs exactly the Debian 12 packages ScopeTrack's build and tests need.
# Idempotent: packages already installed are left alone and apt is not
# touched at all when nothing is missing. Runs as root (or through sudo).
#   tools/setup-deps.sh            build + tests
#   tools/setup-deps.sh --fuzz     also clang 14 + libFuzzer runtime (tools/fuzz)
set -euo pipefail

packages=(
  build-essential cmake pkg-config git
  libeigen3-dev                          # core: fixed-size linear algebra
  libopencv-core-dev                     # core: cv::Mat, FileStorage (sequence.yaml)
  libopencv-features2d-dev               # core: cv::KeyPoint types; tests/bench: cv::ORB baseline
  libopencv-imgproc-dev                  # tools/tests: baselines (fillConvexPoly), overlay drawing
  libopencv-calib3d-dev                  # tests only: projectPoints comparison
  libopencv-imgcodecs-dev                # tools: scopetrack-soak's plot (PNG)
  libceres-dev                           # core: tiny_solver shape + window BA
  libflatbuffers-dev flatbuffers-compiler  # hal: console stream; tests: flatc --json decode
  libcamera-dev                          # hal: live capture
  doctest-dev                            # tests
  ffmpeg                                 # tests + overlay tool: Y4M/MP4 conversion (host only)
  libboost-dev                           # scopetrack-studio: Boost.Beast HTTP + WebSocket (header-only)
  chromium                               # scopetrack-studio's browser tests (headless, driven by Playwright)
)
# The studio's page is built with Node.js >= 20 and npm; a machine that has
# them (Node.js from elsewhere than Debian) keeps them, one without gets Debian's.
if ! command -v node >/dev/null 2>&1 || ! command -v npm >/dev/null 2>&1; then
  packages+=(nodejs npm)
fi
if [[ "${1:-}" == "--fuzz" ]]; then
  packages+=(clang-14 libclang-rt-14-dev)
fi

missing=()
for p in "${packages[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if [[ ${#missing[@]} -eq 0 ]]; then
  echo "setup-deps: all ${#packages[@]} packages already installed"
  exit 0
fi

SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
echo "setup-deps: installing ${missing[*]}"
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
echo "setup-deps: done"
