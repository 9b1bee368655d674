// One screen-space triangle into depth / triangle-id / mask buffers:
// exact fixed-point edge functions walked scanline by scanline, top-left
// fill rule, perspective-correct depth (1/z is affine in the image), depth
// test on z. Internal to the rasteriser (core/rasterizer.cpp); no allocation.
#pragma once

#include <cstddef>
#include <cstdint>

namespace st::raster {

// Sub-pixel precision of the snapped vertices: 1/4096 px. With the guard
// band below, every edge-function value fits in int64 with margin:
// |X| < 2^27, differences < 2^28, products < 2^56.
inline constexpr int kSubpixelBits = 12;
inline constexpr std::int64_t kSubpixelScale = std::int64_t{1} << kSubpixelBits;
// Vertices projecting further than this outside the image are clipped in
// 3D first (guard band), so fixed-point coordinates stay bounded.
inline constexpr double kGuardBandPx = 16384.0;

// Target buffers: stride in elements, shared by the three planes. Every
// buffer holds at least 4 elements after the last pixel (SIMD groups may
// read and write back up to 3 pixels past a span end, unchanged).
struct Target {
  float* depth = nullptr;  // mm; 0 = empty
  std::int32_t* triangle_id = nullptr;
  std::uint8_t* mask = nullptr;
  int width = 0, height = 0;
  std::ptrdiff_t stride = 0;
  bool use_simd = true;  // false: the portable span kernel (tests compare both)
  // Per row, the columns written so far [dirty_x0, dirty_x1] (height
  // entries each): the next render clears only those.
  std::int32_t* dirty_x0 = nullptr;
  std::int32_t* dirty_x1 = nullptr;
};

// 1/z over the image: iz(x, y) = c + gx * x + gy * y (raster pixels),
// clamped to [iz_min, iz_max] (the triangle's own depth range) so that pixel
// centres snapped just outside a grazing triangle never extrapolate wildly.
struct DepthPlane {
  double c = 0, gx = 0, gy = 0;
  float iz_min = 0, iz_max = 0;
};

// Snapped vertices in 1/kSubpixelScale px, with positive signed area
// (X1-X0)(Y2-Y0) - (Y1-Y0)(X2-X0) > 0 (the caller orders them).
struct FixedTriangle {
  std::int64_t x[3], y[3];
};

struct Counters {
  std::int64_t fragments = 0;  // pixels inside the triangle (before the depth test)
  int newly_covered = 0;       // pixels that were empty before
};

// Rasterises one triangle; pixel centres at integer coordinates.
void rasterize(const FixedTriangle& tri, const DepthPlane& plane, std::int32_t id,
               const Target& target, Counters* counters);

// True if the SIMD span kernel is compiled in (else the portable one runs).
bool simd_enabled();

}  // namespace st::raster
