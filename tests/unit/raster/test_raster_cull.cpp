// The rasteriser's per-triangle tests (raster::classify) against a
// reference written from their definitions, and its AVX-512 form against
// the portable one, on random vertex data: outcodes of every kind,
// snapped positions anywhere in the guard band (differences near 2^28, so
// that 32-bit products would overflow), collinear and repeated vertices,
// triangles between pixel centres, partial batches. The vertex pass's two
// forms against each other, bit for bit.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/raster/cull.h"
#include "core/raster/triangle.h"
#include "core/geometry/se3.h"

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

// Model vertices in, and the vertex pass's outputs (snapped positions
// preset to a marker, written only where kept).
struct VertexBuffers {
  std::vector<float> mx, my, mz;
  std::vector<double> x, y, z;
  std::vector<std::uint32_t> code;
  std::vector<std::int32_t> sx, sy;
  static constexpr std::int32_t kUnwritten = 12345;
  explicit VertexBuffers(int n)
      : mx(n), my(n), mz(n), x(n), y(n), z(n), code(n), sx(n, kUnwritten), sy(n, kUnwritten) {}
  VertexArrays arrays() {
    VertexArrays v;
    v.model_x = mx.data();
    v.model_y = my.data();
    v.model_z = mz.data();
    v.x = x.data();
    v.y = y.data();
    v.z = z.data();
    v.outcode = code.data();
    v.snap_x = sx.data();
    v.snap_y = sy.data();
    v.count = static_cast<int>(x.size());
    return v;
  }
};

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

TEST_CASE("raster cull: the AVX-512 vertex pass writes the portable one's bits") {
  if (!avx512_available()) {
    MESSAGE("no AVX-512 on this CPU: only the portable vertex pass runs");
    return;
  }
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coord(-150.f, 150.f);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int ahead = 0, behind = 0, clipped = 0, snapped = 0;
  for (int round = 0; round < 30; ++round) {
    const int n = 1000 + round;  // a partial last step in most rounds
    VertexBuffers portable(n);
    for (int i = 0; i < n; ++i) {
      portable.mx[i] = coord(rng);
      portable.my[i] = coord(rng);
      portable.mz[i] = coord(rng);
    }
    VertexBuffers simd = portable;
    // The camera in or near the cloud: vertices behind the near plane, in
    // the image, beyond the image and beyond the guard band (grazing).
    const st::SE3 T(st::Quat(unit(rng), unit(rng), unit(rng), unit(rng)),
                    st::Vec3(20 * unit(rng), 20 * unit(rng), 60 + 80 * unit(rng)));
    VertexPass pass;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) pass.R[3 * r + c] = T.rotation()(r, c);
      pass.t[r] = T.translation()[r];
    }
    pass.fx = 900 + 100 * unit(rng);
    pass.fy = pass.fx * (1 + 0.01 * unit(rng));
    pass.cx = 639.5 + 5 * unit(rng);
    pass.cy = 359.5 + 5 * unit(rng);
    pass.near_mm = 1.0;
    pass.guard_lo = -kGuardBandPx;
    pass.guard_hi_u = kW - 1 + kGuardBandPx;
    pass.guard_hi_v = kH - 1 + kGuardBandPx;
    pass.in_lo = -1.0;
    pass.in_hi_u = kW;
    pass.in_hi_v = kH;
    const double planes[4][4] = {{pass.fx, 0, pass.cx + 1, 0},
                                 {-pass.fx, 0, kW - pass.cx, 0},
                                 {0, pass.fy, pass.cy + 1, 0},
                                 {0, -pass.fy, kH - pass.cy, 0}};
    std::copy(&planes[0][0], &planes[0][0] + 16, &pass.reject_plane[0][0]);
    transform_vertices(pass, portable.arrays(), false);
    transform_vertices(pass, simd.arrays(), true);
    long diff = 0;
    for (int i = 0; i < n; ++i) {
      diff += portable.x[i] != simd.x[i] || portable.y[i] != simd.y[i] ||
              portable.z[i] != simd.z[i] || portable.code[i] != simd.code[i] ||
              portable.sx[i] != simd.sx[i] || portable.sy[i] != simd.sy[i];
      const std::uint32_t c = portable.code[i];
      behind += (c & kOutNear) != 0;
      ahead += (c & kOutNear) == 0;
      clipped += (c & (kOutClipMask & ~kOutNear)) != 0;
      snapped += (c & kOutClipMask) == 0 && portable.sx[i] != VertexBuffers::kUnwritten;
    }
    CHECK(diff == 0);
  }
  CHECK(behind > 1000);
  CHECK(ahead > 1000);
  CHECK(clipped > 100);
  CHECK(snapped > 1000);
}

TEST_CASE("raster cull: both vertex passes snap halves away from zero") {
  // Identity pose, fx = fy = 1, principal point 0, z = 1: u = model x
  // exactly, so positions on, next to and half-way between sub-pixel steps
  // are fed in exactly.
  std::mt19937 rng(11);
  std::uniform_int_distribution<int> step(-2000000, 2000000), kind(0, 2);
  const int n = 999;
  VertexBuffers in(n);
  std::vector<std::int32_t> want_x(n), want_y(n);
  for (int i = 0; i < n; ++i) {
    const int k = step(rng), j = step(rng);
    const double frac[3] = {0.5, 0.0, 0.25};
    const double fx = k < 0 ? -frac[kind(rng)] : frac[kind(rng)];
    in.mx[i] = static_cast<float>((k + fx) / 4096.0);
    in.my[i] = static_cast<float>((j - 0.5) / 4096.0);
    in.mz[i] = 1.0f;
    want_x[i] = static_cast<std::int32_t>(std::round(k + fx));  // std::round: half away from 0
    want_y[i] = static_cast<std::int32_t>(std::round(j - 0.5));
  }
  VertexPass pass;
  pass.R[0] = pass.R[4] = pass.R[8] = 1.0;
  pass.fx = pass.fy = 1.0;
  pass.near_mm = 0.5;
  pass.guard_lo = -1e6;
  pass.guard_hi_u = pass.guard_hi_v = 1e6;
  pass.in_lo = -1e6;
  pass.in_hi_u = pass.in_hi_v = 1e6;
  for (bool avx512 : {false, true}) {
    if (avx512 && !avx512_available()) continue;
    VertexBuffers out = in;
    std::fill(out.code.begin(), out.code.end(), 99u);
    transform_vertices(pass, out.arrays(), avx512);
    int wrong = 0;
    for (int i = 0; i < n; ++i)
      wrong += out.code[i] != 0 || out.sx[i] != want_x[i] || out.sy[i] != want_y[i];
    CHECK_MESSAGE(wrong == 0, (avx512 ? "AVX-512" : "portable"));
  }
}
