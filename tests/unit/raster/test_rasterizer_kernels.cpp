// The rasteriser's two triangle kernels against each other: the
// bounding-box kernel for small triangles (32-bit edge tests) must cover
// exactly the pixels of the scanline walk (64-bit exact edge walkers), on
// random sub-pixel and pixel-aligned triangles, and its SIMD and portable
// forms must write identical bits.
#include <doctest/doctest.h>

#include <cstdint>
#include <random>
#include <vector>

#include "core/raster/triangle.h"

using namespace st::raster;

namespace {

constexpr int kW = 64, kH = 48;

// Owns one set of target buffers (1/z, ids, mask, dirty columns).
struct TestTarget {
  std::vector<float> iz = std::vector<float>(kW * kH + kTargetPad, 0.0f);
  std::vector<std::int32_t> id = std::vector<std::int32_t>(kW * kH + kTargetPad, -1);
  std::vector<std::uint8_t> mask = std::vector<std::uint8_t>(kW * kH + kTargetPad, 0);
  std::vector<std::int32_t> x0 = std::vector<std::int32_t>(kH, kW);
  std::vector<std::int32_t> x1 = std::vector<std::int32_t>(kH, -1);
  Target view(bool simd, bool avx512 = false) {
    Target t;
    t.depth = iz.data();
    t.triangle_id = id.data();
    t.mask = mask.data();
    t.width = kW;
    t.height = kH;
    t.stride = kW;
    t.use_simd = simd;
    t.use_avx512 = avx512;
    t.dirty_x0 = x0.data();
    t.dirty_x1 = x1.data();
    return t;
  }
};

// Gives t the positive signed area the kernels require (swapping two
// vertices); false if it has none (degenerate).
bool orient_positive(FixedTriangle* t) {
  const std::int64_t area =
      (t->x[1] - t->x[0]) * (t->y[2] - t->y[0]) - (t->y[1] - t->y[0]) * (t->x[2] - t->x[0]);
  if (area == 0) return false;
  if (area < 0) {
    std::swap(t->x[1], t->x[2]);
    std::swap(t->y[1], t->y[2]);
  }
  return true;
}

// A random triangle with a pixel box under kSmallBoxPx, some of it off the
// image, vertices on the pixel grid (aligned) or anywhere on the sub-pixel
// grid; positive signed area as the kernels require. False if degenerate.
bool random_small_triangle(std::mt19937& rng, bool aligned, FixedTriangle* t) {
  std::uniform_int_distribution<int> centre_x(-4, kW + 4), centre_y(-4, kH + 4);
  const std::int64_t half = (kSmallBoxPx / 2 - 1) * kSubpixelScale;
  std::uniform_int_distribution<std::int64_t> offset(-half, half);
  const std::int64_t cx = centre_x(rng) * kSubpixelScale, cy = centre_y(rng) * kSubpixelScale;
  for (int i = 0; i < 3; ++i) {
    std::int64_t dx = offset(rng), dy = offset(rng);
    if (aligned) {
      dx -= dx % (kSubpixelScale / 2);  // pixel centres and half-pixel points
      dy -= dy % (kSubpixelScale / 2);
    }
    t->x[i] = cx + dx;
    t->y[i] = cy + dy;
  }
  return orient_positive(t);
}

DepthPlane test_plane() {
  DepthPlane p;
  p.c = 0.01;
  p.gx = 1.5e-5;
  p.gy = -0.7e-5;
  p.iz_min = 0.002f;
  p.iz_max = 0.05f;
  return p;
}

}  // namespace

TEST_CASE("raster kernels: the box kernel covers exactly the scanline walk's pixels") {
  std::mt19937 rng(7);
  const DepthPlane plane = test_plane();
  int tested = 0;
  for (int k = 0; k < 4000; ++k) {
    FixedTriangle t;
    if (!random_small_triangle(rng, k % 2 == 0, &t)) continue;
    TestTarget box, scan;
    Counters c_box, c_scan;
    const Target tb = box.view(false), ts = scan.view(false);
    REQUIRE(draw_small(t, plane, 5, tb, &c_box));
    PreparedTriangle p;
    if (prepare(t, plane, 5, ts, &p)) draw_rows(&p, kH - 1, ts, &c_scan);
    CAPTURE(k);
    CHECK(c_box.fragments == c_scan.fragments);
    long differ = 0;
    for (int i = 0; i < kW * kH; ++i) differ += (box.id[i] == 5) != (scan.id[i] == 5);
    CHECK(differ == 0);
    // Every pixel drawn lies inside the columns marked as written.
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x)
        if (box.id[y * kW + x] == 5) CHECK((box.x0[y] <= x && x <= box.x1[y]));
    ++tested;
  }
  CHECK(tested > 3500);
}

// The forms of the box kernel this machine runs: universal SIMD (SSE2 or
// NEON), and AVX-512 where the CPU has it.
void box_kernels_match_portable(bool avx512) {
  std::mt19937 rng(11);
  const DepthPlane plane = test_plane();
  TestTarget simd, portable;
  Counters c_simd, c_portable;
  // Many overlapping triangles into the same buffers: the depth test runs.
  for (int k = 0; k < 2000; ++k) {
    FixedTriangle t;
    if (!random_small_triangle(rng, k % 3 == 0, &t)) continue;
    DepthPlane p = plane;
    p.c += 1e-4 * (k % 17);
    draw_small(t, p, k, simd.view(true, avx512), &c_simd);
    draw_small(t, p, k, portable.view(false), &c_portable);
  }
  CHECK(c_simd.fragments == c_portable.fragments);
  CHECK(c_simd.fragments > 10000);
  long differ = 0;
  for (int i = 0; i < kW * kH + kTargetPad; ++i)
    differ += simd.iz[i] != portable.iz[i] || simd.id[i] != portable.id[i];
  CHECK(differ == 0);
  // The padding after the last pixel is read and written back unchanged.
  for (int i = kW * kH; i < kW * kH + kTargetPad; ++i) CHECK(simd.iz[i] == 0.0f);
}

TEST_CASE("raster kernels: SIMD and portable box kernels write identical bits") {
  box_kernels_match_portable(false);
  if (avx512_available()) {
    MESSAGE("AVX-512 box kernel tested too");
    box_kernels_match_portable(true);
  }
}

namespace {

// The exact inside test of one pixel centre, straight from the definition
// (64-bit edge functions, top-left rule): the reference for the walkers.
bool inside_exact(const FixedTriangle& t, int x, int y) {
  const std::int64_t X = x * kSubpixelScale, Y = y * kSubpixelScale;
  for (int i = 0; i < 3; ++i) {
    const int j = i == 2 ? 0 : i + 1;
    const std::int64_t dx = t.x[j] - t.x[i], dy = t.y[j] - t.y[i];
    const std::int64_t e = dx * (Y - t.y[i]) - dy * (X - t.x[i]);
    const bool top_left = dy < 0 || (dy == 0 && dx > 0);
    if (e < 0 || (e == 0 && !top_left)) return false;
  }
  return true;
}

// A random triangle of any size and shape over and around a kW x kH image:
// vertices anywhere on the sub-pixel grid, on pixel centres, or sharing a
// row or a column (horizontal and vertical edges), some far outside.
bool random_big_triangle(std::mt19937& rng, int kind, FixedTriangle* t) {
  std::uniform_int_distribution<std::int64_t> px(-40 * kSubpixelScale, (kW + 40) * kSubpixelScale);
  for (int i = 0; i < 3; ++i) {
    t->x[i] = px(rng);
    t->y[i] = px(rng) * kH / kW;
    if (kind == 1) {  // pixel centres and half pixels
      t->x[i] -= t->x[i] % (kSubpixelScale / 2);
      t->y[i] -= t->y[i] % (kSubpixelScale / 2);
    }
  }
  if (kind == 2) t->y[1] = t->y[0];  // a horizontal edge
  if (kind == 3) t->x[2] = t->x[1];  // a vertical edge
  if (kind == 4) {                   // a sliver: the third vertex near the first edge
    t->x[2] = (t->x[0] + t->x[1]) / 2 + (px(rng) % 300);
    t->y[2] = (t->y[0] + t->y[1]) / 2 + (px(rng) % 300);
  }
  return orient_positive(t);
}

}  // namespace

TEST_CASE("raster kernels: the scanline walk covers exactly the pixels of the exact edge test") {
  std::mt19937 rng(23);
  const DepthPlane plane = test_plane();
  int tested = 0, resumed = 0;
  long pixels = 0;
  for (int k = 0; k < 6000; ++k) {
    FixedTriangle t;
    if (!random_big_triangle(rng, k % 5, &t)) continue;
    TestTarget scan;
    Counters c;
    // Portable, universal SIMD and (where the CPU has it) AVX-512 spans.
    const Target ts = scan.view(k % 3 != 0, k % 3 == 2 && avx512_available());
    PreparedTriangle p;
    if (prepare(t, plane, 9, ts, &p)) {
      // Half the triangles of each kernel form are drawn in bands of rows,
      // as a resumed walk.
      if ((k / 3) % 2 == 0) {
        for (int y_stop = (k / 3) % 7; y_stop < kH - 1; y_stop += 1 + (k / 3) % 11)
          draw_rows(&p, y_stop, ts, &c);
        ++resumed;
      }
      draw_rows(&p, kH - 1, ts, &c);
    }
    long expected = 0, differ = 0;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const bool in = inside_exact(t, x, y);
        expected += in;
        differ += in != (scan.id[y * kW + x] == 9);
        if (in) CHECK((scan.x0[y] <= x && x <= scan.x1[y]));
      }
    CAPTURE(k);
    CHECK(differ == 0);
    CHECK(c.fragments == expected);
    pixels += expected;
    ++tested;
  }
  CHECK(tested > 5000);
  CHECK(resumed > 1500);
  CHECK(pixels > 1000000);
}
