#include "core/raster_triangle.h"

#include <algorithm>
#include <cstring>
#include <opencv2/core/hal/intrin.hpp>

namespace st::raster {
namespace {

// floor / ceil of a fixed-point coordinate in whole pixels (arithmetic
// shift floors negative values too).
inline std::int64_t floor_px(std::int64_t v) { return v >> kSubpixelBits; }
inline std::int64_t ceil_px(std::int64_t v) { return -((-v) >> kSubpixelBits); }

// ceil(N / m) of an edge bound, exactly, as N falls by dN every row:
// N = q * m - r with 0 <= r < m; per row q drops by qd or qd + 1.
struct EdgeWalk {
  std::int64_t q, r, m, qd, rd;

  void init(std::int64_t n0, std::int64_t dn, std::int64_t m_in, double inv_m) {
    m = m_in;
    q = exact_ceil_div(n0, m, inv_m, &r);
    std::int64_t cr;
    const std::int64_t cq = exact_ceil_div(dn, m, inv_m, &cr);
    // floor division of dn from its ceiling: dn = qd m + rd, 0 <= rd < m.
    const std::int64_t exact = cr == 0;
    qd = cq - 1 + exact;
    rd = exact ? 0 : m - cr;
  }
  // An edge that never binds (q stays put): pads the walkers to two per side.
  void init_inert(std::int64_t q_fixed) {
    q = q_fixed;
    r = qd = rd = 0;
    m = 1;
  }
  // Branch-free: the carry is data-dependent, a branch would mispredict.
  void step() {
    r += rd;
    const std::int64_t carry = r >= m;
    q -= qd + carry;
    r -= m & -carry;
  }

  // ceil(n / m) and r = q m - n in [0, m), from a floating-point estimate
  // corrected exactly in integers (no 64-bit division). m >= kSubpixelScale
  // and |n| < 2^58, so the estimate is off by at most 2 (usually 0 or 1);
  // the loops are a safety net that does not run.
  static std::int64_t exact_ceil_div(std::int64_t n, std::int64_t m, double inv_m,
                                     std::int64_t* r) {
    std::int64_t q = static_cast<std::int64_t>(static_cast<double>(n) * inv_m);
    std::int64_t rem = q * m - n;
    for (int k = 0; k < 2; ++k) {
      const std::int64_t low = rem < 0;
      q += low;
      rem += m & -low;
    }
    const std::int64_t high = rem >= m;
    q -= high;
    rem -= m & -high;
    while (rem < 0) {
      ++q;
      rem += m;
    }
    while (rem >= m) {
      --q;
      rem -= m;
    }
    *r = rem;
    return q;
  }
};

// Span [x0, x1] of row y: depth test on z = 1/iz, id and mask writes.
struct Span {
  int x0, x1;
  float iz0, gx, iz_min, iz_max;
  std::int32_t id;
};

void fill_span_portable(const Span& s, float* depth, std::int32_t* ids, std::uint8_t* mask,
                        Counters* counters) {
  int newly = 0;
  for (int x = s.x0; x <= s.x1; ++x) {
    float iz = s.iz0 + s.gx * static_cast<float>(x - s.x0);
    iz = std::min(std::max(iz, s.iz_min), s.iz_max);
    const float z = 1.0f / iz;
    const float old = depth[x];
    if (old == 0.0f) ++newly;
    if (old == 0.0f || z < old) {
      depth[x] = z;
      ids[x] = s.id;
    }
    mask[x] = 255;
  }
  counters->newly_covered += newly;
}

#if CV_SIMD128
// Bytes 0xFF in the lanes whose bit is set: mask writes, 4 pixels at once.
constexpr std::uint32_t kLaneBytes[16] = {0x00000000u, 0x000000FFu, 0x0000FF00u, 0x0000FFFFu,
                                          0x00FF0000u, 0x00FF00FFu, 0x00FFFF00u, 0x00FFFFFFu,
                                          0xFF000000u, 0xFF0000FFu, 0xFF00FF00u, 0xFF00FFFFu,
                                          0xFFFF0000u, 0xFFFF00FFu, 0xFFFFFF00u, 0xFFFFFFFFu};

// Set bits of a 4-bit lane mask (the baseline x86-64 ISA has no popcnt).
constexpr int kLaneCount[16] = {0, 1, 1, 2, 1, 2, 2, 3, 1, 2, 2, 3, 2, 3, 3, 4};

// Per-triangle constants of the SIMD kernel, broadcast once per triangle
// rather than once per row (rows average ~10 pixels on the liver).
struct SimdSpanConstants {
  cv::v_float32x4 lane, four, gx, iz_min, iz_max, one;
  cv::v_int32x4 id, lane_i;
  SimdSpanConstants(float gx_in, float iz_min_in, float iz_max_in, std::int32_t id_in)
      : lane(0.f, 1.f, 2.f, 3.f),
        four(cv::v_setall_f32(4.0f)),
        gx(cv::v_setall_f32(gx_in)),
        iz_min(cv::v_setall_f32(iz_min_in)),
        iz_max(cv::v_setall_f32(iz_max_in)),
        one(cv::v_setall_f32(1.0f)),
        id(cv::v_setall_s32(id_in)),
        lane_i(0, 1, 2, 3) {}
};

// Same arithmetic as the portable kernel, 4 pixels per step (x - x0 is an
// exact small integer in float, so stepping it by 4 changes no bit). The
// last group may reach 3 pixels past x1: those lanes are read and written
// back unchanged (the buffers are padded, see Target).
inline void fill_span_simd(const Span& s, const SimdSpanConstants& c, float* depth,
                           std::int32_t* ids, std::uint8_t* mask, Counters* counters) {
  const cv::v_float32x4 zero = cv::v_setzero_f32(), iz0 = cv::v_setall_f32(s.iz0);
  cv::v_float32x4 k = c.lane;
  int newly = 0;
  for (int x = s.x0; x <= s.x1; x += 4, k = k + c.four) {
    const cv::v_float32x4 iz = cv::v_min(cv::v_max(iz0 + c.gx * k, c.iz_min), c.iz_max);
    const cv::v_float32x4 z = c.one / iz;
    const cv::v_float32x4 old = cv::v_load(depth + x);
    cv::v_float32x4 empty = old == zero;
    cv::v_float32x4 pass = empty | (z < old);
    int lanes = 15;
    if (x + 3 > s.x1) {
      const cv::v_int32x4 inside = (cv::v_setall_s32(x) + c.lane_i) <= cv::v_setall_s32(s.x1);
      const cv::v_float32x4 inside_f = cv::v_reinterpret_as_f32(inside);
      pass = pass & inside_f;
      empty = empty & inside_f;
      lanes = cv::v_signmask(inside);
    }
    cv::v_store(depth + x, cv::v_select(pass, z, old));
    const cv::v_int32x4 old_id = cv::v_load(ids + x);
    cv::v_store(ids + x, cv::v_select(cv::v_reinterpret_as_s32(pass), c.id, old_id));
    newly += kLaneCount[cv::v_signmask(empty)];
    std::uint32_t m;
    std::memcpy(&m, mask + x, 4);
    m |= kLaneBytes[lanes];
    std::memcpy(mask + x, &m, 4);
  }
  counters->newly_covered += newly;
}
#endif

// The edge set of one triangle: two walkers bounding x from below and two
// from above (a triangle has one or two of each; inert walkers pad the rest),
// and the row range (horizontal edges restrict rows, not columns).
struct Edges {
  EdgeWalk lower[2], upper[2];
  std::int64_t y_first = 0, y_last = -1;
};

// Pixel (x, y) is inside edge a->b if E = dx (Y - Ya) - dy (X - Xa) > 0, or
// E == 0 on a top or left edge (dy < 0, or dy == 0 and dx > 0), X = x S.
Edges setup_edges(const FixedTriangle& t, int width, int height) {
  constexpr std::int64_t S = kSubpixelScale;
  Edges e;
  const std::int64_t ymin = std::min({t.y[0], t.y[1], t.y[2]});
  const std::int64_t ymax = std::max({t.y[0], t.y[1], t.y[2]});
  e.y_first = std::max<std::int64_t>(0, ceil_px(ymin));
  e.y_last = std::min<std::int64_t>(height - 1, floor_px(ymax));
  int n_lower = 0, n_upper = 0;
  // 1/|dy| of the three edges from one division (an estimate is enough: the
  // edge walkers correct it exactly). Horizontal edges count as 1.
  double ady[3];
  for (int i = 0; i < 3; ++i) {
    const std::int64_t dy = t.y[i == 2 ? 0 : i + 1] - t.y[i];
    ady[i] = dy == 0 ? 1.0 : static_cast<double>(dy < 0 ? -dy : dy);
  }
  const double inv_all = 1.0 / (ady[0] * ady[1] * ady[2] * static_cast<double>(S));
  const double inv_m[3] = {ady[1] * ady[2] * inv_all, ady[0] * ady[2] * inv_all,
                           ady[0] * ady[1] * inv_all};
  for (int i = 0; i < 3; ++i) {
    const int j = i == 2 ? 0 : i + 1;
    const std::int64_t dx = t.x[j] - t.x[i], dy = t.y[j] - t.y[i];
    const bool top_left = dy < 0 || (dy == 0 && dx > 0);
    if (dy == 0) {  // top edge: rows at or below it; bottom edge: rows strictly above
      if (dx > 0)
        e.y_first = std::max(e.y_first, ceil_px(t.y[i]));
      else
        e.y_last = std::min(e.y_last, ceil_px(t.y[i]) - 1);
      continue;
    }
    // Inside: A x + B(y) + bias >= 0 with A = -dy S; bound x >= N / A (A > 0)
    // or x <= -N / |A| (A < 0), N = -(B(y) + bias), N falls by dx S per row.
    const std::int64_t bias = top_left ? 0 : -1;
    const std::int64_t n0 = -(dx * (e.y_first * S - t.y[i]) + dy * t.x[i] + bias);
    EdgeWalk& w = dy < 0 ? e.lower[n_lower++] : e.upper[n_upper++];
    w.init(n0, dx * S, (dy < 0 ? -dy : dy) * S, inv_m[i]);
  }
  if (n_lower < 2) e.lower[1].init_inert(0);                   // x >= 0 anyway
  if (n_upper < 2) e.upper[1].init_inert(-(width - 1));        // x <= width - 1 anyway
  if (n_lower == 0 || n_upper == 0) e.y_last = e.y_first - 1;  // degenerate: nothing
  return e;
}

// The scanline walk; fill(span, row offset) writes one span.
template <typename Fill>
void walk_rows(const FixedTriangle& tri, const DepthPlane& plane, const Target& target, Span* s,
               Counters* counters, Fill fill) {
  Edges e = setup_edges(tri, target.width, target.height);
  const std::int64_t x_limit = target.width - 1;
  std::int64_t fragments = 0;
  for (std::int64_t y = e.y_first; y <= e.y_last; ++y) {
    const std::int64_t x0 = std::max({std::int64_t{0}, e.lower[0].q, e.lower[1].q});
    const std::int64_t x1 = std::min({x_limit, -e.upper[0].q, -e.upper[1].q});
    e.lower[0].step();
    e.lower[1].step();
    e.upper[0].step();
    e.upper[1].step();
    if (x0 > x1) continue;
    s->x0 = static_cast<int>(x0);
    s->x1 = static_cast<int>(x1);
    s->iz0 = static_cast<float>(plane.c + plane.gy * static_cast<double>(y) +
                                plane.gx * static_cast<double>(x0));
    fill(*s, static_cast<std::ptrdiff_t>(y) * target.stride);
    target.dirty_x0[y] = std::min(target.dirty_x0[y], s->x0);
    target.dirty_x1[y] = std::max(target.dirty_x1[y], s->x1);
    fragments += x1 - x0 + 1;
  }
  counters->fragments += fragments;
}

}  // namespace

bool simd_enabled() { return CV_SIMD128 != 0; }

void rasterize(const FixedTriangle& tri, const DepthPlane& plane, std::int32_t id,
               const Target& target, Counters* counters) {
  Span s;
  s.gx = static_cast<float>(plane.gx);
  s.iz_min = plane.iz_min;
  s.iz_max = plane.iz_max;
  s.id = id;
#if CV_SIMD128
  if (target.use_simd) {
    const SimdSpanConstants c(s.gx, s.iz_min, s.iz_max, id);
    walk_rows(tri, plane, target, &s, counters, [&](const Span& span, std::ptrdiff_t row) {
      fill_span_simd(span, c, target.depth + row, target.triangle_id + row, target.mask + row,
                     counters);
    });
    return;
  }
#endif
  walk_rows(tri, plane, target, &s, counters, [&](const Span& span, std::ptrdiff_t row) {
    fill_span_portable(span, target.depth + row, target.triangle_id + row, target.mask + row,
                       counters);
  });
}

}  // namespace st::raster
