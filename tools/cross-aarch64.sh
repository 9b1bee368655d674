#!/usr/bin/env bash
# Cross-builds ScopeTrack for the aarch64 scope processor and runs the
# portable unit tests under qemu-aarch64, without touching the host's own
# packages: the arm64 libraries are unpacked into a sysroot instead of
# installed (Debian 12's arm64 -dev packages would displace the host's).
#   tools/cross-aarch64.sh           sysroot + cross build in build-aarch64/
#   tools/cross-aarch64.sh --test    then the CTest label "portable" under qemu
# The sysroot (build-aarch64-sysroot/, about 800 MB) is made once and reused
# while the package list below is unchanged. Runs as root (or through sudo)
# for the host packages and dpkg --add-architecture; the rest needs no root.
set -euo pipefail
cd "$(dirname "$0")/.."

run_tests=0
case "${1:-}" in
  --test) run_tests=1 ;;
  "") ;;
  *) echo "usage: tools/cross-aarch64.sh [--test]" >&2; exit 2 ;;
esac

# The arm64 packages the product, tools and tests link (and their
# dependencies, which apt resolves).
arm64_packages=(
  libc6-dev libstdc++-12-dev libeigen3-dev libopencv-core-dev
  libopencv-features2d-dev libopencv-imgproc-dev libopencv-calib3d-dev
  libceres-dev libflatbuffers-dev libcamera-dev doctest-dev
)
sysroot=$PWD/build-aarch64-sysroot
build=build-aarch64
SUDO=""
if [[ $(id -u) -ne 0 ]]; then SUDO="sudo"; fi
t0=$SECONDS

# 1. Host side: the cross compiler, qemu, the host's flatc (tools/setup-deps.sh
#    has the rest), and apt's index of arm64 packages.
bash tools/setup-deps.sh >&2
host_missing=()
for p in g++-aarch64-linux-gnu qemu-user; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || host_missing+=("$p")
done
need_update=0
if ! dpkg --print-foreign-architectures | grep -qx arm64; then
  $SUDO dpkg --add-architecture arm64
  need_update=1
fi
if [[ $need_update -eq 1 || ${#host_missing[@]} -gt 0 ]]; then
  export DEBIAN_FRONTEND=noninteractive
  $SUDO apt-get update -qq
fi
if [[ ${#host_missing[@]} -gt 0 ]]; then
  echo "cross-aarch64: installing ${host_missing[*]}"
  $SUDO apt-get install -y -qq --no-install-recommends "${host_missing[@]}" >/dev/null
fi

# 2. The sysroot: download the arm64 packages with apt as if none were
#    installed (an empty dpkg status), unpack them, and do what their
#    maintainer scripts would have done for a build: absolute symlinks made
#    relative (they would point into the host), BLAS/LAPACK alternatives.
stamp="${arm64_packages[*]}"
if [[ ! -f "$sysroot/.packages" || "$(cat "$sysroot/.packages")" != "$stamp" ]]; then
  echo "cross-aarch64: making the arm64 sysroot in $sysroot"
  rm -rf "$sysroot" "$sysroot.tmp"
  mkdir -p "$sysroot.tmp/cache/partial" "$sysroot.tmp/root"
  : >"$sysroot.tmp/status"
  apt-get install -y -qq --download-only --no-install-recommends \
    -o Dir::State::status="$sysroot.tmp/status" \
    -o Dir::Cache::archives="$sysroot.tmp/cache" \
    -o APT::Architecture=arm64 -o Debug::NoLocking=1 \
    "${arm64_packages[@]}" >/dev/null
  debs=("$sysroot.tmp"/cache/*.deb)
  echo "cross-aarch64: unpacking ${#debs[@]} packages"
  for d in "${debs[@]}"; do dpkg-deb -x "$d" "$sysroot.tmp/root"; done
  root="$sysroot.tmp/root"
  while IFS= read -r link; do
    target=$(readlink "$link")
    rel=$(realpath -m --relative-to="$(dirname "$link")" "$root$target")
    ln -sfn "$rel" "$link"
  done < <(find "$root" -type l -lname '/*')
  multiarch="$root/usr/lib/aarch64-linux-gnu"
  for lib in blas lapack; do
    if [[ -e "$multiarch/$lib/lib$lib.so.3" ]]; then
      ln -sfn "$lib/lib$lib.so.3" "$multiarch/lib$lib.so.3"
      ln -sfn "$lib/lib$lib.so.3" "$multiarch/lib$lib.so"
    fi
  done
  # Ceres' exported target names BLAS and LAPACK by absolute path.
  find "$multiarch/cmake" -name '*Targets.cmake' -exec sed -i \
    '/INTERFACE_LINK_LIBRARIES/s#\([";]\)/usr/lib/#\1${CMAKE_SYSROOT}/usr/lib/#g' {} +
  mv "$root" "$sysroot"
  rm -rf "$sysroot.tmp"
  echo "$stamp" >"$sysroot/.packages"
fi
echo "cross-aarch64: sysroot ready ($((SECONDS - t0)) s)"

# 3. The cross build: product, tools and tests, warnings as errors.
export SCOPETRACK_SYSROOT="$sysroot"
export PKG_CONFIG_SYSROOT_DIR="$sysroot"
export PKG_CONFIG_LIBDIR="$sysroot/usr/lib/aarch64-linux-gnu/pkgconfig:$sysroot/usr/share/pkgconfig"
t1=$SECONDS
cmake -S . -B "$build" -DCMAKE_TOOLCHAIN_FILE=toolchains/aarch64-linux-gnu.cmake \
  -DSCOPETRACK_BOARD=generic-aarch64 -DSCOPETRACK_WERROR=ON \
  "-DCMAKE_CROSSCOMPILING_EMULATOR=qemu-aarch64;-L;$sysroot" >&2
cmake --build "$build" -j"$(nproc)" >&2
echo "cross-aarch64: built in $build ($((SECONDS - t1)) s)"

# 4. The unit tests that need no subprocess, under qemu-aarch64 (CTest runs
#    them through the emulator named above).
if [[ $run_tests -eq 1 ]]; then
  t2=$SECONDS
  export SCOPETRACK_TIME_SCALE=${SCOPETRACK_TIME_SCALE:-20}
  ctest --test-dir "$build" --output-on-failure -j"$(nproc)" --label-regex portable
  echo "cross-aarch64: portable tests passed under qemu ($((SECONDS - t2)) s)"
fi
