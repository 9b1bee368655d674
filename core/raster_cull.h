// The rasteriser's per-triangle tests, 16 triangles at a time: frustum
// reject, clip needed, orientation (back-face culling), zero area and
// "covers no pixel centre", from the per-vertex outcodes and snapped
// positions of one render. Most of a closed organ's triangles end here
// (back-facing or outside the view), so these tests run for every triangle
// while the set-up runs only for those drawn. Internal to the rasteriser
// (core/rasterizer.cpp); no allocation.
#pragma once

#include <cstdint>

namespace st::raster {

// Vertex outcode: bit 0 behind the near plane, bits 1-4 beyond the guard
// band (left, right, top, bottom; these bit positions are also the clip
// plane indices), bits 5-8 outside the image by more than one pixel.
inline constexpr unsigned kOutNear = 1u << 0;
inline constexpr unsigned kOutGuardShift = 1, kOutRejectShift = 5;
inline constexpr unsigned kOutClipMask = 0x1Fu;                                // near + guard band
inline constexpr unsigned kOutRejectMask = kOutNear | (0xFu << kOutRejectShift);  // outside

// Triangles in draw order as three vertex-index arrays, and the vertices'
// outcodes and snapped positions (1/4096 px; read only where the outcode
// has no clip bit, any value elsewhere).
struct CullInput {
  const std::int32_t* v0 = nullptr;
  const std::int32_t* v1 = nullptr;
  const std::int32_t* v2 = nullptr;
  const std::uint32_t* outcode = nullptr;
  const std::int32_t* snap_x = nullptr;
  const std::int32_t* snap_y = nullptr;
  int width = 0, height = 0;  // raster pixels
  bool cull_backfaces = true;
};

// Bit k stands for triangle t0 + k of the batch.
struct CullBatch {
  std::uint32_t draw = 0;   // draw as it is (snapped, inside the guard band)
  std::uint32_t clip = 0;   // not trivially outside, a vertex needs clipping
  std::uint32_t front = 0;  // with draw: negative signed area (seen from outside)
  int outside = 0;          // trivially outside the frustum
  int culled = 0;           // back-facing, zero area, or between pixel centres
};

inline constexpr int kCullBatch = 16;

// Classifies triangles t0 .. t0 + n - 1 (1 <= n <= kCullBatch). use_avx512
// takes the AVX-512 form where it is compiled in and the CPU has it (the
// caller checks avx512_available()); both give the same bits.
void classify(const CullInput& in, int t0, int n, bool use_avx512, CullBatch* out);

}  // namespace st::raster
