// One screen-space triangle into 1/z and triangle-id buffers: exact
// fixed-point edge functions, top-left fill rule, perspective-correct depth
// (1/z is affine in the image), depth test on 1/z. Small triangles take a
// bounding-box kernel (32-bit edge tests), the rest a scanline walk (64-bit
// exact edge walkers); both cover the same pixels. resolve_row turns 1/z
// into depth and writes the mask once at the end. Internal to the
// rasteriser (core/raster/rasterizer.cpp); no allocation.
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/base/cpu_features.h"  // the AVX-512 forms: ST_HAVE_AVX512, ST_AVX512

namespace st::raster {

// Sub-pixel precision of the snapped vertices: 1/4096 px. With the guard
// band below, every edge-function value fits in int64 with margin:
// |X| < 2^27, differences < 2^28, products < 2^56.
inline constexpr int kSubpixelBits = 12;
inline constexpr std::int64_t kSubpixelScale = std::int64_t{1} << kSubpixelBits;
// floor / ceil of a fixed-point coordinate in whole pixels (arithmetic
// shift floors negative values too).
inline std::int64_t floor_px(std::int64_t v) { return v >> kSubpixelBits; }
inline std::int64_t ceil_px(std::int64_t v) { return -((-v) >> kSubpixelBits); }

// Vertices projecting further than this outside the image are clipped in
// 3D first (guard band), so fixed-point coordinates stay bounded.
inline constexpr double kGuardBandPx = 16384.0;

// Elements every target buffer holds after its last pixel: SIMD groups may
// read and write back up to kTargetPad - 1 pixels past a span end, unchanged.
inline constexpr int kTargetPad = 16;

// Target buffers: stride in elements, shared by the three planes.
struct Target {
  float* depth = nullptr;  // while drawing 1/z (1/mm), 0 = empty; resolve_row makes it mm
  std::int32_t* triangle_id = nullptr;
  std::uint8_t* mask = nullptr;
  int width = 0, height = 0;
  std::ptrdiff_t stride = 0;
  bool use_simd = true;  // false: the portable span and box kernels (tests compare both)
  // With use_simd: the AVX-512 forms of both kernels (16 pixels a step,
  // masked loads and stores). Only where avx512_available() says so.
  bool use_avx512 = false;
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
};

// ceil(N / m) of an edge bound, exactly, as N falls by a fixed step every
// row: N = q m - r with 0 <= r < m; per row q drops by qd or qd + 1.
struct EdgeWalk {
  std::int64_t q, r, m, qd, rd;
};

// A triangle set up for the scanline walk, resumable row band by row band.
// At any row one edge bounds x from below and one from above: a side with
// two edges (sharing the middle vertex of that side) hands over from its
// upper to its lower edge after row y_switch; on a convex triangle the edge
// not in charge of a row never binds there, so this equals intersecting all
// three edges. Rows y_next..y_last remain. Setup once, drawn by one or more
// draw_rows() calls.
struct PreparedTriangle {
  EdgeWalk lower, upper;  // in charge of row y_next
  EdgeWalk next;          // takes over after row y_switch (side: switch_lower)
  std::int32_t y_next = 0, y_last = -1;
  std::int32_t y_switch = 0;  // last row of the first edge; >= y_last: no hand-over
  bool switch_lower = false;  // the hand-over is on the lower (true) or upper side
  std::int32_t id = -1;
  float gx = 0, iz_min = 0, iz_max = 0;
  double c = 0, gy = 0, gx_d = 0;  // the depth plane (see DepthPlane)
};

// Sets up tri for rows 0..target.height-1; false if it covers no row.
bool prepare(const FixedTriangle& tri, const DepthPlane& plane, std::int32_t id,
             const Target& target, PreparedTriangle* out);

// Draws the prepared triangle's remaining rows up to y_stop (inclusive) and
// advances it past them.
void draw_rows(PreparedTriangle* tri, int y_stop, const Target& target, Counters* counters);

// Triangles whose pixel bounding box is under this many pixels on both
// sides take the bounding-box kernel (draw_small), the rest the scanline walk.
inline constexpr int kSmallBoxPx = 16;

// Draws tri if it is small (see kSmallBoxPx) and returns true; else false
// and draws nothing. Same pixels, depth and ids as the scanline walk.
bool draw_small(const FixedTriangle& tri, const DepthPlane& plane, std::int32_t id,
                const Target& target, Counters* counters);

// Rasterises one triangle; pixel centres at integer coordinates.
void rasterize(const FixedTriangle& tri, const DepthPlane& plane, std::int32_t id,
               const Target& target, Counters* counters);

// After the last triangle: turns 1/z into depth (mm, 0 stays 0) and writes
// the mask (255 where covered, else 0) over columns x0..x1 of one row;
// returns the covered pixel count. Bit-identical with and without SIMD;
// use_avx512 (with use_simd) takes the AVX-512 form where it is compiled in.
int resolve_row(float* depth, std::uint8_t* mask, int x0, int x1, bool use_simd,
                bool use_avx512);

// True if the SIMD span kernel is compiled in (else the portable one runs).
bool simd_enabled();

// True if this build has the AVX-512 kernels (x86-64, GCC or Clang) and the
// CPU and OS it runs on support AVX-512F. Bit-identical with the others.
bool avx512_available();

}  // namespace st::raster
