// The rasteriser's per-triangle tests (raster::classify) against a
// reference written from their definitions, and its AVX-512 form against
// the portable one, on random vertex data: outcodes of every kind,
// snapped positions anywhere in the guard band (differences near 2^28, so
// that 32-bit products would overflow), collinear and repeated vertices,
// triangles between pixel centres, partial batches.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/raster_cull.h"
#include "core/raster_triangle.h"

using namespace st::raster;

namespace {

constexpr int kW = 1280, kH = 720;

struct Scene {
  std::vector<std::int32_t> v[3];
  std::vector<std::uint32_t> outcode;
  std::vector<std::int32_t> sx, sy;
  CullInput input(bool cull_backfaces) const {
    CullInput in;
    in.v0 = v[0].data();
    in.v1 = v[1].data();
    in.v2 = v[2].data();
    in.outcode = outcode.data();
    in.snap_x = sx.data();
    in.snap_y = sy.data();
    in.width = kW;
    in.height = kH;
    in.cull_backfaces = cull_backfaces;
    return in;
  }
};

// Vertices of several kinds: in the image, anywhere in the guard band, on
// a few shared points (repeated and collinear corners), tiny offsets of one
// point (triangles between pixel centres); outcodes mostly clear, some with
// reject or clip bits.
Scene random_scene(std::mt19937& rng, int triangles) {
  const int nv = 400;
  Scene s;
  const std::int64_t S = kSubpixelScale;
  const auto guard = static_cast<std::int64_t>(kGuardBandPx) * S;
  std::uniform_int_distribution<std::int64_t> in_x(-S, kW * S), in_y(-S, kH * S);
  std::uniform_int_distribution<std::int64_t> far_x(-guard, (kW - 1) * S + guard),
      far_y(-guard, (kH - 1) * S + guard);
  std::uniform_int_distribution<int> kind(0, 9), small(-3000, 3000), bits(0, 511);
  const std::int32_t base_x = 640 * 4096 + 100, base_y = 360 * 4096 + 100;
  for (int i = 0; i < nv; ++i) {
    const int k = kind(rng);
    std::int64_t x, y;
    if (k < 5) {
      x = in_x(rng);
      y = in_y(rng);
    } else if (k < 7) {
      x = far_x(rng);
      y = far_y(rng);
    } else if (k < 8) {  // on a line through the base point
      const int t = small(rng);
      x = base_x + 3 * t;
      y = base_y - 2 * t;
    } else {  // within a pixel of the base point
      x = base_x + small(rng) / 2;
      y = base_y + small(rng) / 2;
    }
    s.sx.push_back(static_cast<std::int32_t>(x));
    s.sy.push_back(static_cast<std::int32_t>(y));
    const int b = bits(rng);
    s.outcode.push_back(kind(rng) < 7 ? 0u : static_cast<std::uint32_t>(b));
  }
  std::uniform_int_distribution<int> vertex(0, nv - 1);
  for (int t = 0; t < triangles; ++t) {
    for (auto& corner : s.v) corner.push_back(vertex(rng));
    if (kind(rng) == 0) s.v[2].back() = s.v[0].back();  // two corners the same
  }
  return s;
}

// From the definitions, in other arithmetic: the signed area in double of
// exact 64-bit products' difference, pixel-centre coverage by floor/ceil.
CullBatch reference(const Scene& s, int t0, int n, bool cull_backfaces) {
  CullBatch b;
  for (int k = 0; k < n; ++k) {
    const int t = t0 + k;
    const int i[3] = {s.v[0][t], s.v[1][t], s.v[2][t]};
    const std::uint32_t c[3] = {s.outcode[i[0]], s.outcode[i[1]], s.outcode[i[2]]};
    bool outside = false;
    for (unsigned bit = 0; bit < 9; ++bit) {
      const bool reject_bit = bit == 0 || bit >= kOutRejectShift;
      if (reject_bit && (c[0] >> bit & 1u) && (c[1] >> bit & 1u) && (c[2] >> bit & 1u))
        outside = true;
    }
    if (outside) {
      ++b.outside;
      continue;
    }
    if (((c[0] | c[1] | c[2]) & 0x1Fu) != 0) {
      b.clip |= 1u << k;
      continue;
    }
    const long double ax = s.sx[i[1]] - static_cast<long double>(s.sx[i[0]]);
    const long double ay = s.sy[i[1]] - static_cast<long double>(s.sy[i[0]]);
    const long double bx = s.sx[i[2]] - static_cast<long double>(s.sx[i[0]]);
    const long double by = s.sy[i[2]] - static_cast<long double>(s.sy[i[0]]);
    const long double area = ax * by - ay * bx;  // |products| < 2^57: exact in long double
    bool covers = true;
    for (int axis = 0; axis < 2; ++axis) {
      const std::vector<std::int32_t>& p = axis == 0 ? s.sx : s.sy;
      const double lo = std::min({p[i[0]], p[i[1]], p[i[2]]}) / 4096.0;
      const double hi = std::max({p[i[0]], p[i[1]], p[i[2]]}) / 4096.0;
      const double first = std::max(0.0, std::ceil(lo));
      const double last = std::min(axis == 0 ? kW - 1.0 : kH - 1.0, std::floor(hi));
      covers = covers && first <= last;
    }
    if (area == 0 || (area > 0 && cull_backfaces) || !covers) {
      ++b.culled;
      continue;
    }
    b.draw |= 1u << k;
    if (area < 0) b.front |= 1u << k;
  }
  return b;
}

void check_same(const CullBatch& a, const CullBatch& b) {
  CHECK(a.draw == b.draw);
  CHECK(a.clip == b.clip);
  CHECK(a.front == b.front);
  CHECK(a.outside == b.outside);
  CHECK(a.culled == b.culled);
}

}  // namespace

TEST_CASE("raster cull: portable and AVX-512 classify match the definitions") {
  const bool avx512 = avx512_available();
  if (avx512) MESSAGE("AVX-512 classify tested too");
  std::mt19937 rng(20261127);
  int drawn = 0, clipped = 0, outside = 0, culled = 0, front = 0;
  for (int round = 0; round < 40; ++round) {
    const int n = 16 * 25 + round % 16;  // partial last batch in most rounds
    const Scene s = random_scene(rng, n);
    for (bool cull_backfaces : {true, false}) {
      const CullInput in = s.input(cull_backfaces);
      for (int t0 = 0; t0 < n; t0 += kCullBatch) {
        const int m = std::min(kCullBatch, n - t0);
        const CullBatch want = reference(s, t0, m, cull_backfaces);
        CullBatch got;
        classify(in, t0, m, false, &got);
        check_same(got, want);
        if (avx512) {
          classify(in, t0, m, true, &got);
          check_same(got, want);
        }
        drawn += __builtin_popcount(want.draw);
        front += __builtin_popcount(want.front);
        clipped += __builtin_popcount(want.clip);
        outside += want.outside;
        culled += want.culled;
      }
    }
  }
  // Every outcome occurs often, so each comparison above was exercised.
  CHECK(drawn > 2000);
  CHECK(drawn - front > 500);  // back faces drawn without culling
  CHECK(clipped > 1000);
  CHECK(outside > 500);
  CHECK(culled > 2000);
}
