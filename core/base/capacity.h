// Compile-time maxima. The runtime config may choose less; configure()
// checks it against these and parsers refuse input above them before
// allocating anything.
#pragma once

#include <cstdint>

namespace st {

inline constexpr int kMaxImageWidth = 4096;
inline constexpr int kMaxImageHeight = 4096;
inline constexpr std::int64_t kMaxMeshVertices = 2'000'000;
inline constexpr std::int64_t kMaxMeshTriangles = 4'000'000;
inline constexpr std::int64_t kMaxMeshFileBytes = 512ll << 20;
inline constexpr int kMaxPyramidLevels = 12;
inline constexpr int kMaxKeypoints = 4096;
inline constexpr int kMaxKeyframes = 256;
inline constexpr int kMaxMapPoints = 32768;
inline constexpr int kMaxMarkers = 64;
inline constexpr std::int64_t kMaxTrajectoryLines = 10'000'000;

}  // namespace st
