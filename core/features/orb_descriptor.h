// Orientation by intensity centroid and 256-bit steered BRIEF (rBRIEF-style)
// on a smoothed pyramid level.
//
// The test pattern is our own: 256 point pairs drawn once, deterministically
// and with integer arithmetic only (so every build and board produces the
// same descriptors), from an approximately Gaussian distribution (sigma
// ~6.3 px, the BRIEF "G II" choice for a 31x31 patch) and kept inside a disc
// of radius 14 so every rotation stays inside the 15-pixel patch.
// Steering uses a table of the pattern rotated to kAngleBins angles, built
// once; compute() allocates nothing.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/features/feature_set.h"
#include "core/image/image.h"

namespace st {

inline constexpr int kOrbPatchRadius = 15;  // orientation patch and pattern reach, level pixels
inline constexpr int kOrbAngleBins = 128;   // steering resolution: 2.8 degrees

class OrbDescriptor {
 public:
  OrbDescriptor();  // builds the pattern and its rotations (~128 KB, once)

  // Intensity-centroid angle in degrees [0, 360) of the disc of radius 15
  // around (x, y); the pixel must be >= 15 pixels inside the image.
  static float orientation_deg(GrayView level, int x, int y);
  // Descriptor of the smoothed level at (x, y), pattern steered by angle_deg;
  // (x, y) must be >= 15 pixels inside the image.
  void compute(GrayView smoothed_level, int x, int y, float angle_deg, std::uint8_t* out32) const;

  // Precomputes the rotated pattern as pixel offsets for images of this row
  // stride (configure time: allocates 128 KB). compute() on an image with
  // that stride then reads one offset per point instead of (dx, dy) times
  // the stride; same descriptors. Strides above 2340 (offsets past int16)
  // keep the (dx, dy) path. Returns whether the offsets are in use.
  bool set_stride(std::ptrdiff_t stride);

  // The unrotated pattern (for tests): pair i is (a[i], b[i]), each (dx, dy).
  struct PointPair {
    std::int8_t ax, ay, bx, by;
  };
  const std::array<PointPair, 256>& pattern() const { return pattern_; }

 private:
  std::array<PointPair, 256> pattern_{};
  std::array<std::array<PointPair, 256>, kOrbAngleBins> rotated_{};
  std::vector<std::int16_t> offsets_;  // per bin: 256 x (a, b) pixel offsets for offsets_stride_
  std::ptrdiff_t offsets_stride_ = 0;  // 0: no offsets
};

}  // namespace st
