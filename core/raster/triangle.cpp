#include "core/raster/triangle.h"

#include <algorithm>
#include <opencv2/core/hal/intrin.hpp>

#if ST_HAVE_AVX512
#include <immintrin.h>
#endif

namespace st::raster {
namespace {

// ceil(n / m) and r = q m - n in [0, m), from a floating-point estimate
// corrected exactly in integers (no 64-bit division). m >= kSubpixelScale
// and |n| < 2^58, so the estimate is off by at most 2 (usually 0 or 1);
// the loops are a safety net that does not run.
std::int64_t exact_ceil_div(std::int64_t n, std::int64_t m, double inv_m, std::int64_t* r) {
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

// The walker of ceil(N / m) with N = n0 at the first row, falling by dn per row.
void init_walk(EdgeWalk* w, std::int64_t n0, std::int64_t dn, std::int64_t m, double inv_m) {
  w->m = m;
  w->q = exact_ceil_div(n0, m, inv_m, &w->r);
  std::int64_t cr;
  const std::int64_t cq = exact_ceil_div(dn, m, inv_m, &cr);
  // floor division of dn from its ceiling: dn = qd m + rd, 0 <= rd < m.
  const std::int64_t exact = cr == 0;
  w->qd = cq - 1 + exact;
  w->rd = exact ? 0 : m - cr;
}

// Branch-free: the carry is data-dependent, a branch would mispredict.
inline void step(EdgeWalk* w) {
  w->r += w->rd;
  const std::int64_t carry = w->r >= w->m;
  w->q -= w->qd + carry;
  w->r -= w->m & -carry;
}

// Span [x0, x1] of row y: depth test on 1/z (larger is nearer; an empty
// pixel holds 0, so any surface passes), 1/z and id writes.
struct Span {
  int x0, x1;
  float iz0, gx, iz_min, iz_max;
  std::int32_t id;
};

void fill_span_portable(const Span& s, float* iz_buf, std::int32_t* ids) {
  for (int x = s.x0; x <= s.x1; ++x) {
    float iz = s.iz0 + s.gx * static_cast<float>(x - s.x0);
    iz = std::min(std::max(iz, s.iz_min), s.iz_max);
    if (iz > iz_buf[x]) {
      iz_buf[x] = iz;
      ids[x] = s.id;
    }
  }
}

#if CV_SIMD
constexpr int kLanes = cv::v_float32::nlanes;
static_assert(kLanes <= kTargetPad, "SIMD groups may run past a span end by kLanes - 1");

// Per-triangle constants of the SIMD kernel, broadcast once per triangle
// rather than once per row (rows average ~10 pixels on the liver).
struct SimdSpanConstants {
  cv::v_float32 lane, step, gx, iz_min, iz_max;
  cv::v_int32 id, lane_i;
  SimdSpanConstants(float gx_in, float iz_min_in, float iz_max_in, std::int32_t id_in) {
    float lane_f[kLanes];
    std::int32_t lane_s[kLanes];
    for (int i = 0; i < kLanes; ++i) {
      lane_f[i] = static_cast<float>(i);
      lane_s[i] = i;
    }
    lane = cv::vx_load(lane_f);
    lane_i = cv::vx_load(lane_s);
    step = cv::vx_setall_f32(static_cast<float>(kLanes));
    gx = cv::vx_setall_f32(gx_in);
    iz_min = cv::vx_setall_f32(iz_min_in);
    iz_max = cv::vx_setall_f32(iz_max_in);
    id = cv::vx_setall_s32(id_in);
  }
};

// One group of kLanes pixels from column x (k: their x - x0): the depth
// test on 1/z and the writes, in lanes where keep is set. Both old values
// are loaded before either store.
inline void fill_group(const SimdSpanConstants& c, const cv::v_float32& iz0, const cv::v_float32& k,
                       int x, const cv::v_float32& keep, float* iz_buf, std::int32_t* ids) {
  const cv::v_float32 iz = cv::v_min(cv::v_max(iz0 + c.gx * k, c.iz_min), c.iz_max);
  const cv::v_float32 old = cv::vx_load(iz_buf + x);
  const cv::v_int32 old_id = cv::vx_load(ids + x);
  const cv::v_float32 pass = (iz > old) & keep;
  cv::v_store(iz_buf + x, cv::v_select(pass, iz, old));
  cv::v_store(ids + x, cv::v_select(cv::v_reinterpret_as_s32(pass), c.id, old_id));
}

// Same arithmetic as the portable kernel, kLanes pixels per step (x - x0 is
// an exact small integer in float, so stepping it changes no bit). The last
// group may reach kLanes - 1 pixels past x1: those lanes are read and
// written back unchanged (the buffers are padded, see Target).
inline void fill_span_simd(const Span& s, const SimdSpanConstants& c, float* iz_buf,
                           std::int32_t* ids) {
  const cv::v_float32 iz0 = cv::vx_setall_f32(s.iz0);
  const cv::v_float32 all = cv::v_reinterpret_as_f32(cv::vx_setall_s32(-1));
  cv::v_float32 k = c.lane;
  int x = s.x0;
  for (; x + kLanes - 1 <= s.x1; x += kLanes, k = k + c.step)
    fill_group(c, iz0, k, x, all, iz_buf, ids);
  if (x <= s.x1) {
    const cv::v_int32 in = (cv::vx_setall_s32(x) + c.lane_i) <= cv::vx_setall_s32(s.x1);
    fill_group(c, iz0, k, x, cv::v_reinterpret_as_f32(in), iz_buf, ids);
  }
}

// resolve_row, 4 kLanes pixels per step; returns where it stopped.
int resolve_row_simd(float* depth, std::uint8_t* mask, int x0, int x1, int* covered) {
  const cv::v_float32 zero = cv::vx_setzero_f32(), one = cv::vx_setall_f32(1.0f);
  cv::v_int32 count = cv::vx_setzero_s32();
  int x = x0;
  for (; x + 4 * kLanes - 1 <= x1; x += 4 * kLanes) {
    cv::v_int32 hit[4];
    for (int g = 0; g < 4; ++g) {
      const cv::v_float32 iz = cv::vx_load(depth + x + g * kLanes);
      const cv::v_float32 covered_f = iz > zero;
      cv::v_store(depth + x + g * kLanes, cv::v_select(covered_f, one / iz, zero));
      hit[g] = cv::v_reinterpret_as_s32(covered_f);
      count = count - hit[g];
    }
    const cv::v_int8 bytes = cv::v_pack(cv::v_pack(hit[0], hit[1]), cv::v_pack(hit[2], hit[3]));
    cv::v_store(mask + x, cv::v_reinterpret_as_u8(bytes));
  }
  *covered += cv::v_reduce_sum(count);
  return x;
}
#endif

void resolve_tail(float* depth, std::uint8_t* mask, int x0, int x1, int* covered) {
  int n = 0;
  for (int x = x0; x <= x1; ++x) {
    const float iz = depth[x];
    const bool hit = iz > 0.0f;
    depth[x] = hit ? 1.0f / iz : 0.0f;
    mask[x] = hit ? 255 : 0;
    n += hit;
  }
  *covered += n;
}

// Pixel (x, y) is inside edge a->b if E = dx (Y - Ya) - dy (X - Xa) > 0, or
// E == 0 on a top or left edge (dy < 0, or dy == 0 and dx > 0), X = x S.
// Inside: A x + B(y) + bias >= 0 with A = -dy S; bound x >= N / A (A > 0,
// a lower bound) or x <= -N / |A| (A < 0, an upper bound; the walker holds
// -x), N = -(B(y) + bias), N falls by dx S per row. The walker of edge i
// (from vertex i to i + 1) starting at row y0:
void init_edge_walk(const FixedTriangle& t, int i, std::int64_t y0, double inv_m, EdgeWalk* w) {
  constexpr std::int64_t S = kSubpixelScale;
  const int j = i == 2 ? 0 : i + 1;
  const std::int64_t dx = t.x[j] - t.x[i], dy = t.y[j] - t.y[i];
  const std::int64_t bias = dy < 0 ? 0 : -1;  // top-left edges include E == 0
  const std::int64_t n0 = -(dx * (y0 * S - t.y[i]) + dy * t.x[i] + bias);
  init_walk(w, n0, dx * S, (dy < 0 ? -dy : dy) * S, inv_m);
}

// Fills the walkers, the hand-over and the row range of out; false if no
// row is covered.
bool setup_edges(const FixedTriangle& t, int height, PreparedTriangle* out) {
  constexpr std::int64_t S = kSubpixelScale;
  const std::int64_t ymin = std::min({t.y[0], t.y[1], t.y[2]});
  const std::int64_t ymax = std::max({t.y[0], t.y[1], t.y[2]});
  std::int64_t y_first = std::max<std::int64_t>(0, ceil_px(ymin));
  std::int64_t y_last = std::min<std::int64_t>(height - 1, floor_px(ymax));
  // Horizontal edges restrict rows, not columns: top edge, rows at or below
  // it; bottom edge, rows strictly above it.
  for (int i = 0; i < 3; ++i) {
    const int j = i == 2 ? 0 : i + 1;
    if (t.y[j] != t.y[i]) continue;
    if (t.x[j] > t.x[i])
      y_first = std::max(y_first, ceil_px(t.y[i]));
    else
      y_last = std::min(y_last, ceil_px(t.y[i]) - 1);
  }
  if (y_first > y_last) return false;
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
  int lower[2], upper[2], n_lower = 0, n_upper = 0;
  for (int i = 0; i < 3; ++i) {
    const std::int64_t dy = t.y[i == 2 ? 0 : i + 1] - t.y[i];
    if (dy < 0) lower[n_lower++] = i;
    if (dy > 0) upper[n_upper++] = i;
  }
  if (n_lower == 0 || n_upper == 0) return false;  // degenerate: nothing
  // The side with two edges: they share the vertex v; the edge reaching
  // above v is in charge of the rows up to v's, the other one below.
  const bool two_lower = n_lower == 2;
  const int* side = two_lower ? lower : upper;
  int first = side[0], second = side[0];
  std::int64_t y_switch = y_last;
  if (n_lower == 2 || n_upper == 2) {
    const int e0 = side[0], e1 = side[1];
    const int v = e1 == (e0 == 2 ? 0 : e0 + 1) ? e1 : e0;  // the shared vertex
    const int e_into_v = v == 0 ? 2 : v - 1;  // edge e runs from vertex e to e + 1
    const bool into_is_upper = t.y[e_into_v] < t.y[v == 2 ? 0 : v + 1];
    first = into_is_upper ? e_into_v : v;
    second = into_is_upper ? v : e_into_v;
    y_switch = floor_px(t.y[v]);
  }
  const int lower_edge = two_lower ? first : lower[0];
  const int upper_edge = two_lower ? upper[0] : first;
  if (y_switch < y_first) {
    // The hand-over lies above the first row drawn: start with the second edge.
    init_edge_walk(t, second, y_first, inv_m[second], two_lower ? &out->lower : &out->upper);
    init_edge_walk(t, two_lower ? upper_edge : lower_edge, y_first,
                   inv_m[two_lower ? upper_edge : lower_edge], two_lower ? &out->upper : &out->lower);
    y_switch = y_last;
  } else {
    init_edge_walk(t, lower_edge, y_first, inv_m[lower_edge], &out->lower);
    init_edge_walk(t, upper_edge, y_first, inv_m[upper_edge], &out->upper);
    if (y_switch < y_last) init_edge_walk(t, second, y_switch + 1, inv_m[second], &out->next);
  }
  out->y_switch = static_cast<std::int32_t>(std::min(y_switch, y_last));
  out->switch_lower = two_lower;
  out->y_next = static_cast<std::int32_t>(y_first);
  out->y_last = static_cast<std::int32_t>(y_last);
  return true;
}

// The scanline walk over rows y_next..y_stop; fill(span, row offset) writes
// one span. The two walkers in charge live in registers.
// Always inlined, so that a caller built for another instruction set
// (the AVX-512 kernel) gets its own copy with its span kernel inlined.
template <typename Fill>
[[gnu::always_inline]] inline void walk_rows(PreparedTriangle* t, int y_stop, const Target& target,
                                             Span* s, Counters* counters, Fill fill) {
  const std::int64_t x_limit = target.width - 1;
  std::int64_t fragments = 0;
  const int y_end = std::min<int>(t->y_last, y_stop);
  EdgeWalk lo = t->lower, up = t->upper;
  std::int32_t* const dirty_x0 = target.dirty_x0;
  std::int32_t* const dirty_x1 = target.dirty_x1;
  int y = t->y_next;
  while (y <= y_end) {
    const int seg_end = std::min(y_end, static_cast<int>(t->y_switch));
    for (; y <= seg_end; ++y) {
      const std::int64_t x0 = std::max(std::int64_t{0}, lo.q);
      const std::int64_t x1 = std::min(x_limit, -up.q);
      step(&lo);
      step(&up);
      if (x0 > x1) continue;
      s->x0 = static_cast<int>(x0);
      s->x1 = static_cast<int>(x1);
      s->iz0 = static_cast<float>(t->c + t->gy * static_cast<double>(y) +
                                  t->gx_d * static_cast<double>(x0));
      fill(*s, static_cast<std::ptrdiff_t>(y) * target.stride);
      dirty_x0[y] = std::min(dirty_x0[y], s->x0);
      dirty_x1[y] = std::max(dirty_x1[y], s->x1);
      fragments += x1 - x0 + 1;
    }
    if (y > y_end) break;
    // Past the middle vertex of the side with two edges: hand over.
    (t->switch_lower ? lo : up) = t->next;
    t->y_switch = t->y_last;
  }
  t->lower = lo;
  t->upper = up;
  t->y_next = y;
  counters->fragments += fragments;
}

// The bounding-box kernel's view of a small triangle: per edge, the exact
// inside test at pixel centres reduced to the sign of a 32-bit integer.
// E = dx (Y - Ya) - dy (X - Xa) at X = x S, Y = y S is S K' + r with
// 0 <= r < S; E >= e_min (0 on top-left edges, else 1) iff K = K' - t >= 0,
// t = 1 where r == 0 on other edges. K moves by -dy per column and by dx per
// row, and stays far inside int32 for a box of kSmallBoxPx.
struct BoxSetup {
  int x0, y0, x1, y1;  // pixel box, clipped to the image, inclusive
  bool clipped_right;  // the triangle goes on past the image's last column
  std::int32_t k0[3], kx[3], ky[3];
  double iz_c, iz_gx, iz_gy;
  float gx, iz_min, iz_max;
  std::int32_t id;
};

bool setup_box(const FixedTriangle& t, const DepthPlane& plane, std::int32_t id,
               const Target& target, BoxSetup* b) {
  constexpr std::int64_t S = kSubpixelScale;
  const std::int64_t x_lo = ceil_px(std::min({t.x[0], t.x[1], t.x[2]}));
  const std::int64_t x_hi = floor_px(std::max({t.x[0], t.x[1], t.x[2]}));
  const std::int64_t y_lo = ceil_px(std::min({t.y[0], t.y[1], t.y[2]}));
  const std::int64_t y_hi = floor_px(std::max({t.y[0], t.y[1], t.y[2]}));
  if (x_hi - x_lo >= kSmallBoxPx || y_hi - y_lo >= kSmallBoxPx) return false;
  b->x0 = static_cast<int>(std::max<std::int64_t>(x_lo, 0));
  b->x1 = static_cast<int>(std::min<std::int64_t>(x_hi, target.width - 1));
  b->y0 = static_cast<int>(std::max<std::int64_t>(y_lo, 0));
  b->y1 = static_cast<int>(std::min<std::int64_t>(y_hi, target.height - 1));
  b->clipped_right = x_hi > target.width - 1;
  for (int i = 0; i < 3; ++i) {
    const int j = i == 2 ? 0 : i + 1;
    const std::int64_t dx = t.x[j] - t.x[i], dy = t.y[j] - t.y[i];
    const std::int64_t e0 = dx * (b->y0 * S - t.y[i]) - dy * (b->x0 * S - t.x[i]);
    const bool top_left = dy < 0 || (dy == 0 && dx > 0);
    const bool on_pixel_grid = (e0 & (S - 1)) == 0;
    b->k0[i] = static_cast<std::int32_t>((e0 >> kSubpixelBits) - (on_pixel_grid && !top_left));
    b->kx[i] = static_cast<std::int32_t>(-dy);
    b->ky[i] = static_cast<std::int32_t>(dx);
  }
  b->iz_c = plane.c;
  b->iz_gx = plane.gx;
  b->iz_gy = plane.gy;
  b->gx = static_cast<float>(plane.gx);
  b->iz_min = plane.iz_min;
  b->iz_max = plane.iz_max;
  b->id = id;
  return true;
}

// 1/z at the box's first column of row y (the row's float origin).
inline float box_row_iz(const BoxSetup& b, int y) {
  return static_cast<float>(b.iz_c + b.iz_gy * static_cast<double>(y) +
                            b.iz_gx * static_cast<double>(b.x0));
}

// Marks the box's columns of rows y0..y1 as written (cleared and resolved
// next time; a superset of the pixels drawn is harmless).
void mark_box_dirty(const BoxSetup& b, const Target& target) {
  for (int y = b.y0; y <= b.y1; ++y) {
    const std::ptrdiff_t px = static_cast<std::ptrdiff_t>(y) * target.stride + b.x0;
    __builtin_prefetch(target.depth + px, 1);
    __builtin_prefetch(target.triangle_id + px, 1);
    target.dirty_x0[y] = std::min(target.dirty_x0[y], b.x0);
    target.dirty_x1[y] = std::max(target.dirty_x1[y], b.x1);
  }
}

void draw_box_portable(const BoxSetup& b, const Target& target, Counters* counters) {
  std::int32_t kr[3] = {b.k0[0], b.k0[1], b.k0[2]};
  std::int64_t fragments = 0;
  for (int y = b.y0; y <= b.y1; ++y) {
    float* iz_buf = target.depth + static_cast<std::ptrdiff_t>(y) * target.stride;
    std::int32_t* ids = target.triangle_id + static_cast<std::ptrdiff_t>(y) * target.stride;
    const float iz_row = box_row_iz(b, y);
    std::int32_t ka = kr[0], kb = kr[1], kc = kr[2];
    for (int x = b.x0; x <= b.x1; ++x, ka += b.kx[0], kb += b.kx[1], kc += b.kx[2]) {
      if ((ka | kb | kc) < 0) continue;
      ++fragments;
      float iz = iz_row + b.gx * static_cast<float>(x - b.x0);
      iz = std::min(std::max(iz, b.iz_min), b.iz_max);
      if (iz > iz_buf[x]) {
        iz_buf[x] = iz;
        ids[x] = b.id;
      }
    }
    for (int e = 0; e < 3; ++e) kr[e] += b.ky[e];
  }
  counters->fragments += fragments;
}

#if CV_SIMD
// Same tests and arithmetic as draw_box_portable, kLanes columns per step;
// lanes past the box are masked off (they may lie past the image edge).
void draw_box_simd(const BoxSetup& b, const Target& target, Counters* counters) {
  static constexpr std::int32_t kLaneI[] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
  static constexpr float kLaneF[] = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
  static_assert(kLanes <= 16, "lane tables hold 16 lanes");
  const cv::v_int32 lanes = cv::vx_load(kLaneI);
  cv::v_int32 k_lane[3], k_step[3];
  for (int e = 0; e < 3; ++e) {
    k_lane[e] = lanes * cv::vx_setall_s32(b.kx[e]);
    k_step[e] = cv::vx_setall_s32(b.kx[e] * kLanes);
  }
  const cv::v_int32 last = cv::vx_setall_s32(b.x1), minus_one = cv::vx_setall_s32(-1),
                    id = cv::vx_setall_s32(b.id);
  const cv::v_float32 gx = cv::vx_setall_f32(b.gx), iz_min = cv::vx_setall_f32(b.iz_min),
                      iz_max = cv::vx_setall_f32(b.iz_max), lane0 = cv::vx_load(kLaneF),
                      f_step = cv::vx_setall_f32(static_cast<float>(kLanes));
  cv::v_int32 count = cv::vx_setzero_s32();
  std::int32_t kr[3] = {b.k0[0], b.k0[1], b.k0[2]};
  for (int y = b.y0; y <= b.y1; ++y) {
    float* iz_buf = target.depth + static_cast<std::ptrdiff_t>(y) * target.stride;
    std::int32_t* ids = target.triangle_id + static_cast<std::ptrdiff_t>(y) * target.stride;
    const cv::v_float32 iz_row = cv::vx_setall_f32(box_row_iz(b, y));
    cv::v_int32 ka = cv::vx_setall_s32(kr[0]) + k_lane[0], kb = cv::vx_setall_s32(kr[1]) + k_lane[1],
                kc = cv::vx_setall_s32(kr[2]) + k_lane[2];
    cv::v_float32 kf = lane0;
    for (int x = b.x0; x <= b.x1; x += kLanes) {
      cv::v_int32 cover = (ka | kb | kc) > minus_one;
      // Columns past the box are outside the triangle (the exact test says
      // so) unless the image cut the box: then they lie off the image and
      // are masked, so that the last column never spills into the next row.
      if (b.clipped_right && x + kLanes - 1 > b.x1)
        cover = cover & ((cv::vx_setall_s32(x) + lanes) <= last);
      // No branch on coverage: in boxes this small most groups are partly
      // covered and the branch would mispredict; uncovered lanes keep old.
      count = count - cover;
      const cv::v_float32 iz = cv::v_min(cv::v_max(iz_row + gx * kf, iz_min), iz_max);
      const cv::v_float32 old = cv::vx_load(iz_buf + x);
      const cv::v_int32 old_id = cv::vx_load(ids + x);
      const cv::v_float32 pass = (iz > old) & cv::v_reinterpret_as_f32(cover);
      cv::v_store(iz_buf + x, cv::v_select(pass, iz, old));
      cv::v_store(ids + x, cv::v_select(cv::v_reinterpret_as_s32(pass), id, old_id));
      ka = ka + k_step[0];
      kb = kb + k_step[1];
      kc = kc + k_step[2];
      kf = kf + f_step;
    }
    for (int e = 0; e < 3; ++e) kr[e] += b.ky[e];
  }
  counters->fragments += cv::v_reduce_sum(count);
}
#endif

#if ST_HAVE_AVX512
// min(max(v, lo), hi) in every lane (the zero-masking forms with a full
// mask: GCC 12's unmasked ones warn about their undefined source operand).
ST_AVX512 inline __m512 clamp_avx512(__m512 v, __m512 lo, __m512 hi) {
  return _mm512_maskz_min_ps(0xFFFF, _mm512_maskz_max_ps(0xFFFF, v, lo), hi);
}

// The span kernel, 16 pixels a step: the same arithmetic as the others
// (a separate multiply and add: this file is built with -ffp-contract=off;
// x - x0 as an exact float), lanes past x1 masked off in the loads and the
// stores. walk_rows' fill: a struct rather than a lambda, so that its call
// operator carries the target too.
struct FillSpanAvx512 {
  __m512 lane, step, gx, iz_min, iz_max;
  __m512i id;
  const Target* target;
  ST_AVX512 FillSpanAvx512(const Span& s, const Target* target_in) : target(target_in) {
    lane = _mm512_setr_ps(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
    step = _mm512_set1_ps(16.0f);
    gx = _mm512_set1_ps(s.gx);
    iz_min = _mm512_set1_ps(s.iz_min);
    iz_max = _mm512_set1_ps(s.iz_max);
    id = _mm512_set1_epi32(s.id);
  }
  ST_AVX512 inline void operator()(const Span& s, std::ptrdiff_t row) const {
    float* iz_buf = target->depth + row;
    std::int32_t* ids = target->triangle_id + row;
    const __m512 iz0 = _mm512_set1_ps(s.iz0);
    __m512 k = lane;
    for (int x = s.x0; x <= s.x1; x += 16, k = _mm512_add_ps(k, step)) {
      const int n = s.x1 - x + 1;
      const __mmask16 in = n >= 16 ? __mmask16(0xFFFF) : __mmask16((1u << n) - 1);
      const __m512 iz = clamp_avx512(_mm512_add_ps(iz0, _mm512_mul_ps(gx, k)), iz_min, iz_max);
      const __m512 old = _mm512_maskz_loadu_ps(in, iz_buf + x);
      const __mmask16 pass = _mm512_mask_cmp_ps_mask(in, iz, old, _CMP_GT_OS);
      _mm512_mask_storeu_ps(iz_buf + x, pass, iz);
      _mm512_mask_storeu_epi32(ids + x, pass, id);
    }
  }
};

ST_AVX512 void draw_rows_avx512(PreparedTriangle* tri, int y_stop, const Target& target,
                                Span* s, Counters* counters) {
  walk_rows(tri, y_stop, target, s, counters, FillSpanAvx512(*s, &target));
}

// The box kernel, one 16-column step a row (the box is at most
// kSmallBoxPx = 16 columns wide): the exact 32-bit edge tests of
// draw_box_portable for all columns at once, the depth test and the writes
// masked by coverage.
static_assert(kSmallBoxPx <= 16, "the AVX-512 box kernel covers a row in one step");
ST_AVX512 void draw_box_avx512(const BoxSetup& b, const Target& target, Counters* counters) {
  const __m512i lanes = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  const __m512 lane_f = _mm512_setr_ps(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  __m512i k_row[3];
  for (int e = 0; e < 3; ++e)
    k_row[e] = _mm512_add_epi32(_mm512_set1_epi32(b.k0[e]),
                                _mm512_mullo_epi32(lanes, _mm512_set1_epi32(b.kx[e])));
  const __mmask16 columns = __mmask16((1u << (b.x1 - b.x0 + 1)) - 1);
  const __m512 gx_k = _mm512_mul_ps(_mm512_set1_ps(b.gx), lane_f);
  const __m512 iz_min = _mm512_set1_ps(b.iz_min), iz_max = _mm512_set1_ps(b.iz_max);
  const __m512i id = _mm512_set1_epi32(b.id);
  std::int64_t fragments = 0;
  for (int y = b.y0; y <= b.y1; ++y) {
    const std::ptrdiff_t px = static_cast<std::ptrdiff_t>(y) * target.stride + b.x0;
    const __m512i any = _mm512_or_si512(_mm512_or_si512(k_row[0], k_row[1]), k_row[2]);
    const __mmask16 cover = _mm512_mask_cmpge_epi32_mask(columns, any, _mm512_setzero_si512());
    fragments += __builtin_popcount(static_cast<unsigned>(cover));
    const __m512 iz =
        clamp_avx512(_mm512_add_ps(_mm512_set1_ps(box_row_iz(b, y)), gx_k), iz_min, iz_max);
    const __m512 old = _mm512_maskz_loadu_ps(cover, target.depth + px);
    const __mmask16 pass = _mm512_mask_cmp_ps_mask(cover, iz, old, _CMP_GT_OS);
    _mm512_mask_storeu_ps(target.depth + px, pass, iz);
    _mm512_mask_storeu_epi32(target.triangle_id + px, pass, id);
    for (int e = 0; e < 3; ++e) k_row[e] = _mm512_add_epi32(k_row[e], _mm512_set1_epi32(b.ky[e]));
  }
  counters->fragments += fragments;
}

// resolve_row, 16 pixels a step (IEEE division as in the others: the same
// bits); the mask bytes from the covered lanes. Returns where it stopped.
ST_AVX512 int resolve_row_avx512(float* depth, std::uint8_t* mask, int x0, int x1, int* covered) {
  const __m512 one = _mm512_set1_ps(1.0f);
  const __m512i all = _mm512_set1_epi32(-1);
  int n = 0, x = x0;
  for (; x + 15 <= x1; x += 16) {
    const __m512 iz = _mm512_loadu_ps(depth + x);
    const __mmask16 hit = _mm512_cmp_ps_mask(iz, _mm512_setzero_ps(), _CMP_GT_OS);
    _mm512_storeu_ps(depth + x, _mm512_maskz_div_ps(hit, one, iz));
    _mm512_mask_cvtepi32_storeu_epi8(mask + x, 0xFFFF, _mm512_maskz_mov_epi32(hit, all));
    n += __builtin_popcount(static_cast<unsigned>(hit));
  }
  *covered += n;
  return x;
}
#endif

}  // namespace

bool simd_enabled() { return CV_SIMD != 0; }

bool avx512_available() { return cpu_has_avx512f(); }

int resolve_row(float* depth, std::uint8_t* mask, int x0, int x1, bool use_simd, bool use_avx512) {
  int covered = 0;
#if ST_HAVE_AVX512
  if (use_simd && use_avx512) x0 = resolve_row_avx512(depth, mask, x0, x1, &covered);
#else
  (void)use_avx512;
#endif
#if CV_SIMD
  if (use_simd) x0 = resolve_row_simd(depth, mask, x0, x1, &covered);
#else
  (void)use_simd;
#endif
  resolve_tail(depth, mask, x0, x1, &covered);
  return covered;
}

bool prepare(const FixedTriangle& tri, const DepthPlane& plane, std::int32_t id,
             const Target& target, PreparedTriangle* out) {
  if (!setup_edges(tri, target.height, out)) return false;
  out->id = id;
  out->gx = static_cast<float>(plane.gx);
  out->iz_min = plane.iz_min;
  out->iz_max = plane.iz_max;
  out->c = plane.c;
  out->gy = plane.gy;
  out->gx_d = plane.gx;
  return true;
}

void draw_rows(PreparedTriangle* tri, int y_stop, const Target& target, Counters* counters) {
  Span s;
  s.gx = tri->gx;
  s.iz_min = tri->iz_min;
  s.iz_max = tri->iz_max;
  s.id = tri->id;
#if ST_HAVE_AVX512
  if (target.use_simd && target.use_avx512) {
    draw_rows_avx512(tri, y_stop, target, &s, counters);
    return;
  }
#endif
#if CV_SIMD
  if (target.use_simd) {
    const SimdSpanConstants c(s.gx, s.iz_min, s.iz_max, s.id);
    walk_rows(tri, y_stop, target, &s, counters, [&](const Span& span, std::ptrdiff_t row) {
      fill_span_simd(span, c, target.depth + row, target.triangle_id + row);
    });
    return;
  }
#endif
  walk_rows(tri, y_stop, target, &s, counters, [&](const Span& span, std::ptrdiff_t row) {
    fill_span_portable(span, target.depth + row, target.triangle_id + row);
  });
}

bool draw_small(const FixedTriangle& tri, const DepthPlane& plane, std::int32_t id,
                const Target& target, Counters* counters) {
  BoxSetup b;
  if (!setup_box(tri, plane, id, target, &b)) return false;
  if (b.x0 > b.x1 || b.y0 > b.y1) return true;
  mark_box_dirty(b, target);
#if ST_HAVE_AVX512
  if (target.use_simd && target.use_avx512) {
    draw_box_avx512(b, target, counters);
    return true;
  }
#endif
#if CV_SIMD
  if (target.use_simd) {
    draw_box_simd(b, target, counters);
    return true;
  }
#endif
  draw_box_portable(b, target, counters);
  return true;
}

void rasterize(const FixedTriangle& tri, const DepthPlane& plane, std::int32_t id,
               const Target& target, Counters* counters) {
  if (draw_small(tri, plane, id, target, counters)) return;
  PreparedTriangle p;
  if (prepare(tri, plane, id, target, &p)) draw_rows(&p, target.height - 1, target, counters);
}

}  // namespace st::raster
