// FeatureSet: the keypoints and 256-bit descriptors of one frame, in fixed
// arrays (capacity kMaxKeypoints from core/base/capacity.h). A FeatureSet is a
// plain value: it never allocates, so a tracker can keep a ring of them.
#pragma once

#include <array>
#include <cstdint>

#include "core/base/capacity.h"

namespace st {

inline constexpr int kDescriptorBytes = 32;  // 256-bit rBRIEF
using Descriptor = std::array<std::uint8_t, kDescriptorBytes>;

struct Keypoint {
  float x = 0.f;          // level-0 pixel coordinates (pixel centres at integers)
  float y = 0.f;
  float angle_deg = 0.f;  // intensity-centroid orientation in [0, 360), image axes (y down)
  float response = 0.f;   // FAST score on its level (larger is a stronger corner)
  int octave = 0;         // pyramid level it was detected on
};

struct FeatureSet {
  int count = 0;
  int width = 0;   // level-0 image size the keypoints refer to
  int height = 0;
  std::array<Keypoint, kMaxKeypoints> keypoints{};
  std::array<Descriptor, kMaxKeypoints> descriptors{};
  // Per level: how many keypoints were kept (diagnostics and tests).
  std::array<int, kMaxPyramidLevels> per_level{};

  void clear() {
    count = 0;
    per_level.fill(0);
  }
};

}  // namespace st
