// The rasteriser's per-vertex and per-triangle work before any set-up:
// every vertex into the camera frame with its frustum outcode and snapped
// image position, then the per-triangle tests 16 triangles at a time
// (frustum reject, clip needed, orientation (back-face culling), zero area,
// "covers no pixel centre"). Most of a closed organ's triangles end there
// (back-facing or outside the view), so this runs for every vertex and
// triangle while the set-up runs only for those drawn. Internal to the
// rasteriser (core/raster/rasterizer.cpp); no allocation. Each has a portable and
// an AVX-512 form (chosen at run time) that give the same bits.
#pragma once

#include <cstdint>

#include "core/raster/triangle.h"

namespace st::raster {

// Vertex outcode: bit 0 behind the near plane, bits 1-4 beyond the guard
// band (left, right, top, bottom; these bit positions are also the clip
// plane indices), bits 5-8 outside the image by more than one pixel.
inline constexpr unsigned kOutNear = 1u << 0;
inline constexpr unsigned kOutGuardShift = 1, kOutRejectShift = 5;
inline constexpr unsigned kOutClipMask = 0x1Fu;                                // near + guard band
inline constexpr unsigned kOutRejectMask = kOutNear | (0xFu << kOutRejectShift);  // outside

// Round half away from zero to the sub-pixel grid (1/kSubpixelScale px),
// without libm calls. |px| < 2^19 (the guard band) wherever it is kept.
inline std::int32_t snap(double px) {
  const double s = px * static_cast<double>(kSubpixelScale);
  const auto i = static_cast<std::int64_t>(s);
  const double f = s - static_cast<double>(i);
  return static_cast<std::int32_t>(i + (f >= 0.5) - (f <= -0.5));
}

// The per-render constants of the vertex pass: camera <- model (row-major
// R, t), the raster's pinhole, the near plane, and the bounds of the guard
// band and of the reject test (u, v in raster pixels). Behind the near
// plane the reject bits come from the four planes through the eye and the
// reject bounds instead (outside where a x + b y + c z + d < 0 in the
// camera frame), in the order left, right, top, bottom.
struct VertexPass {
  double R[9] = {}, t[3] = {};
  double fx = 0, fy = 0, cx = 0, cy = 0;
  double near_mm = 0;
  double guard_lo = 0, guard_hi_u = 0, guard_hi_v = 0;
  double in_lo = 0, in_hi_u = 0, in_hi_v = 0;
  double reject_plane[4][4] = {};
};

// Model-frame vertices in, camera-frame vertices, outcodes and snapped
// positions out (the snapped ones written only where the outcode has no
// clip bit). count entries each.
struct VertexArrays {
  const float* model_x = nullptr;
  const float* model_y = nullptr;
  const float* model_z = nullptr;
  double* x = nullptr;
  double* y = nullptr;
  double* z = nullptr;
  std::uint32_t* outcode = nullptr;
  std::int32_t* snap_x = nullptr;
  std::int32_t* snap_y = nullptr;
  int count = 0;
};

void transform_vertices(const VertexPass& pass, const VertexArrays& v, bool use_avx512);

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
