#include "core/raster/cull.h"

#include <algorithm>

#include "core/raster/triangle.h"

#if ST_HAVE_AVX512
#include <immintrin.h>
#endif

namespace st::raster {
namespace {

// Some pixel centre (integer coordinates) inside the snapped extent lo..hi?
bool covers_pixel_centre(std::int64_t lo, std::int64_t hi, int size) {
  return std::max<std::int64_t>(0, ceil_px(lo)) <= std::min<std::int64_t>(size - 1, floor_px(hi));
}

// r[0] a + r[1] b + r[2] c + t (a rotation row, or a plane with t = r[3]).
inline double affine(const double* r, double a, double b, double c, double t) {
  return r[0] * a + r[1] * b + r[2] * c + t;
}

// The four side bits from `first` on: left, right, top, bottom.
inline unsigned side_bits(double u, double w, double lo, double hi_u, double hi_v, unsigned first) {
  return static_cast<unsigned>(u < lo) << first | static_cast<unsigned>(u > hi_u) << (first + 1) |
         static_cast<unsigned>(w < lo) << (first + 2) | static_cast<unsigned>(w > hi_v) << (first + 3);
}

void transform_portable(const VertexPass& c, const VertexArrays& v) {
  for (int i = 0; i < v.count; ++i) {
    const double mx = v.model_x[i], my = v.model_y[i], mz = v.model_z[i];
    const double x = affine(c.R, mx, my, mz, c.t[0]);
    const double y = affine(c.R + 3, mx, my, mz, c.t[1]);
    const double z = affine(c.R + 6, mx, my, mz, c.t[2]);
    v.x[i] = x;
    v.y[i] = y;
    v.z[i] = z;
    unsigned code = 0;
    if (z >= c.near_mm) {
      const double inv_z = 1.0 / z;
      const double u = c.fx * x * inv_z + c.cx, w = c.fy * y * inv_z + c.cy;
      code = side_bits(u, w, c.guard_lo, c.guard_hi_u, c.guard_hi_v, kOutGuardShift) |
             side_bits(u, w, c.in_lo, c.in_hi_u, c.in_hi_v, kOutRejectShift);
      if (!(code & kOutClipMask)) {
        v.snap_x[i] = snap(u);
        v.snap_y[i] = snap(w);
      }
    } else {
      // Behind the near plane: the side tests still hold as half-spaces
      // through the eye, which is all the trivial reject needs.
      code = kOutNear;
      for (unsigned k = 0; k < 4; ++k)
        if (affine(c.reject_plane[k], x, y, z, c.reject_plane[k][3]) < 0)
          code |= 1u << (kOutRejectShift + k);
    }
    v.outcode[i] = code;
  }
}

void classify_portable(const CullInput& in, int t0, int n, CullBatch* out) {
  for (int k = 0; k < n; ++k) {
    const int t = t0 + k;
    const std::int32_t i0 = in.v0[t], i1 = in.v1[t], i2 = in.v2[t];
    const unsigned c0 = in.outcode[i0], c1 = in.outcode[i1], c2 = in.outcode[i2];
    if (c0 & c1 & c2 & kOutRejectMask) {
      ++out->outside;
      continue;
    }
    const std::uint32_t bit = 1u << k;
    if ((c0 | c1 | c2) & kOutClipMask) {
      out->clip |= bit;
      continue;
    }
    const std::int32_t x0 = in.snap_x[i0], y0 = in.snap_y[i0], x1 = in.snap_x[i1],
                       y1 = in.snap_y[i1], x2 = in.snap_x[i2], y2 = in.snap_y[i2];
    const std::int64_t area = std::int64_t{x1 - x0} * (y2 - y0) - std::int64_t{y1 - y0} * (x2 - x0);
    // Image y points down: a face seen from outside has negative signed area.
    const bool front = area < 0;
    if (area == 0 || (!front && in.cull_backfaces) ||
        !covers_pixel_centre(std::min({x0, x1, x2}), std::max({x0, x1, x2}), in.width) ||
        !covers_pixel_centre(std::min({y0, y1, y2}), std::max({y0, y1, y2}), in.height)) {
      ++out->culled;
      continue;
    }
    out->draw |= bit;
    if (front) out->front |= bit;
  }
}

#if ST_HAVE_AVX512
// GCC 12's AVX-512 intrinsics start from _mm512_undefined_*() and warn that
// it is uninitialised wherever they are inlined (a false positive, GCC bug
// 105593): every lane of those values is overwritten (full masks).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wuninitialized"
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"

// (Helpers are functions, not lambdas: a lambda does not inherit the target.)
// Lanes 8 half .. 8 half + 7 of v, sign-extended to 64 bits.
ST_AVX512 inline __m512i widen_half(__m512i v, int half) {
  return _mm512_cvtepi32_epi64(half ? _mm512_extracti64x4_epi64(v, 1)
                                    : _mm512_extracti64x4_epi64(v, 0));
}

// The signs of a b - c d for 16 int32 lanes, in 64-bit arithmetic
// (|a b| < 2^56): bit i of *negative / *zero for lane i.
ST_AVX512 inline void cross_signs(__m512i a, __m512i b, __m512i c, __m512i d, __mmask16* negative,
                                  __mmask16* zero) {
  unsigned neg = 0, eq = 0;
  for (int half = 0; half < 2; ++half) {
    // _mm512_mul_epi32: the low 32 bits of each 64-bit lane, signed, to 64.
    const __m512i p =
        _mm512_sub_epi64(_mm512_mul_epi32(widen_half(a, half), widen_half(b, half)),
                         _mm512_mul_epi32(widen_half(c, half), widen_half(d, half)));
    neg |= static_cast<unsigned>(_mm512_cmplt_epi64_mask(p, _mm512_setzero_si512())) << 8 * half;
    eq |= static_cast<unsigned>(_mm512_cmpeq_epi64_mask(p, _mm512_setzero_si512())) << 8 * half;
  }
  *negative = static_cast<__mmask16>(neg);
  *zero = static_cast<__mmask16>(eq);
}

ST_AVX512 inline __m512i gather32(__mmask16 m, __m512i idx, const void* base) {
  return _mm512_mask_i32gather_epi32(_mm512_setzero_si512(), m, idx, base, 4);
}

// Some pixel centre inside the snapped extent of a, b, c (covers_pixel_centre).
ST_AVX512 inline __mmask16 covers_avx512(__m512i a, __m512i b, __m512i c, int size) {
  const __m512i lo = _mm512_min_epi32(_mm512_min_epi32(a, b), c);
  const __m512i hi = _mm512_max_epi32(_mm512_max_epi32(a, b), c);
  const __m512i round_up = _mm512_set1_epi32(static_cast<std::int32_t>(kSubpixelScale - 1));
  const __m512i first = _mm512_max_epi32(
      _mm512_setzero_si512(), _mm512_srai_epi32(_mm512_add_epi32(lo, round_up), kSubpixelBits));
  const __m512i last =
      _mm512_min_epi32(_mm512_set1_epi32(size - 1), _mm512_srai_epi32(hi, kSubpixelBits));
  return _mm512_cmple_epi32_mask(first, last);
}

// snap() in 8 double lanes: truncation, then the half-away-from-zero
// correction in exact integer-valued doubles; the result as int32 (exact:
// |px| < 2^19 where it is kept, see kGuardBandPx).
ST_AVX512 inline __m256i snap_avx512(__m512d px) {
  const __m512d s = _mm512_mul_pd(px, _mm512_set1_pd(static_cast<double>(kSubpixelScale)));
  const __m512d i = _mm512_cvtepi32_pd(_mm512_cvttpd_epi32(s));
  const __m512d f = _mm512_sub_pd(s, i);
  const __m512d one = _mm512_set1_pd(1.0);
  __m512d r = _mm512_mask_add_pd(i, _mm512_cmp_pd_mask(f, _mm512_set1_pd(0.5), _CMP_GE_OQ), i, one);
  r = _mm512_mask_sub_pd(r, _mm512_cmp_pd_mask(f, _mm512_set1_pd(-0.5), _CMP_LE_OQ), r, one);
  return _mm512_cvttpd_epi32(r);
}

// Sets bit in the lanes of code selected by m (8 lanes, in 16-lane ops).
ST_AVX512 inline __m512i set_bit(__m512i code, __mmask8 m, unsigned bit) {
  return _mm512_mask_or_epi32(code, m, code, _mm512_set1_epi32(static_cast<std::int32_t>(bit)));
}

// The four side bits from `first` on (left, right, top, bottom: u < lo,
// u > hi_u, w < lo, w > hi_v) in the lanes selected by m.
ST_AVX512 inline __m512i side_bits(__m512i code, __mmask8 m, __m512d u, __m512d w, double lo,
                                   double hi_u, double hi_v, unsigned first) {
  const __m512d low = _mm512_set1_pd(lo);
  code = set_bit(code, _mm512_mask_cmp_pd_mask(m, u, low, _CMP_LT_OQ), 1u << first);
  code = set_bit(code, _mm512_mask_cmp_pd_mask(m, u, _mm512_set1_pd(hi_u), _CMP_GT_OQ),
                 1u << (first + 1));
  code = set_bit(code, _mm512_mask_cmp_pd_mask(m, w, low, _CMP_LT_OQ), 1u << (first + 2));
  return set_bit(code, _mm512_mask_cmp_pd_mask(m, w, _mm512_set1_pd(hi_v), _CMP_GT_OQ),
                 1u << (first + 3));
}

// r[0] a + r[1] b + r[2] c + t, evaluated left to right as in the scalar code.
ST_AVX512 inline __m512d affine_row(const double* r, __m512d a, __m512d b, __m512d c, double t) {
  return _mm512_add_pd(
      _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(_mm512_set1_pd(r[0]), a),
                                  _mm512_mul_pd(_mm512_set1_pd(r[1]), b)),
                    _mm512_mul_pd(_mm512_set1_pd(r[2]), c)),
      _mm512_set1_pd(t));
}

// 8 floats (the lanes of live) widened to doubles.
ST_AVX512 inline __m512d load_widened(const float* p, __mmask8 live) {
  return _mm512_cvtps_pd(_mm512_castps512_ps256(_mm512_maskz_loadu_ps(live, p)));
}

// transform_portable, 8 vertices a step: the same operations in the same
// order (this file is built without floating-point contraction), so the
// same bits; both branches of the near-plane test computed, then selected.
ST_AVX512 void transform_avx512(const VertexPass& c, const VertexArrays& v) {
  for (int i = 0; i < v.count; i += 8) {
    const int left = v.count - i;
    const __mmask8 live = left >= 8 ? __mmask8(0xFF) : __mmask8((1u << left) - 1);
    const __m512d mx = load_widened(v.model_x + i, live), my = load_widened(v.model_y + i, live),
                  mz = load_widened(v.model_z + i, live);
    const __m512d x = affine_row(c.R, mx, my, mz, c.t[0]);
    const __m512d y = affine_row(c.R + 3, mx, my, mz, c.t[1]);
    const __m512d z = affine_row(c.R + 6, mx, my, mz, c.t[2]);
    _mm512_mask_storeu_pd(v.x + i, live, x);
    _mm512_mask_storeu_pd(v.y + i, live, y);
    _mm512_mask_storeu_pd(v.z + i, live, z);
    const __mmask8 ahead = _mm512_mask_cmp_pd_mask(live, z, _mm512_set1_pd(c.near_mm), _CMP_GE_OQ);
    const __mmask8 behind = live & static_cast<__mmask8>(~ahead);
    // In front of the near plane: project, guard band and reject bits.
    const __m512d inv_z = _mm512_maskz_div_pd(ahead, _mm512_set1_pd(1.0), z);
    const __m512d u = _mm512_add_pd(
        _mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(c.fx), x), inv_z), _mm512_set1_pd(c.cx));
    const __m512d w = _mm512_add_pd(
        _mm512_mul_pd(_mm512_mul_pd(_mm512_set1_pd(c.fy), y), inv_z), _mm512_set1_pd(c.cy));
    __m512i code = _mm512_setzero_si512();
    code = side_bits(code, ahead, u, w, c.guard_lo, c.guard_hi_u, c.guard_hi_v, kOutGuardShift);
    code = side_bits(code, ahead, u, w, c.in_lo, c.in_hi_u, c.in_hi_v, kOutRejectShift);
    // Behind it: near, and the reject planes through the eye.
    code = set_bit(code, behind, kOutNear);
    for (unsigned k = 0; k < 4; ++k) {
      const double* p = c.reject_plane[k];
      const __m512d d = affine_row(p, x, y, z, p[3]);
      code = set_bit(code, _mm512_mask_cmp_pd_mask(behind, d, _mm512_setzero_pd(), _CMP_LT_OQ),
                     1u << (kOutRejectShift + k));
    }
    _mm512_mask_storeu_epi32(v.outcode + i, live, code);
    const __mmask8 snapped = ahead & static_cast<__mmask8>(_mm512_mask_testn_epi32_mask(
                                         0xFF, code, _mm512_set1_epi32(kOutClipMask)));
    _mm512_mask_storeu_epi32(v.snap_x + i, snapped, _mm512_castsi256_si512(snap_avx512(u)));
    _mm512_mask_storeu_epi32(v.snap_y + i, snapped, _mm512_castsi256_si512(snap_avx512(w)));
  }
}

// classify_portable for 16 triangles at once: the vertex data gathered
// lane by lane, the same integer tests.
ST_AVX512 void classify_avx512(const CullInput& in, int t0, int n, CullBatch* out) {
  const __mmask16 live = n >= kCullBatch ? __mmask16(0xFFFF) : __mmask16((1u << n) - 1);
  const __m512i i0 = _mm512_maskz_loadu_epi32(live, in.v0 + t0);
  const __m512i i1 = _mm512_maskz_loadu_epi32(live, in.v1 + t0);
  const __m512i i2 = _mm512_maskz_loadu_epi32(live, in.v2 + t0);
  const __m512i c0 = gather32(live, i0, in.outcode), c1 = gather32(live, i1, in.outcode),
                c2 = gather32(live, i2, in.outcode);
  const __mmask16 outside = _mm512_mask_test_epi32_mask(
      live, _mm512_and_si512(_mm512_and_si512(c0, c1), c2), _mm512_set1_epi32(kOutRejectMask));
  const __mmask16 inside = live & static_cast<__mmask16>(~outside);
  const __mmask16 clip = _mm512_mask_test_epi32_mask(
      inside, _mm512_or_si512(_mm512_or_si512(c0, c1), c2), _mm512_set1_epi32(kOutClipMask));
  const __mmask16 snapped = inside & static_cast<__mmask16>(~clip);
  out->clip = clip;
  out->outside = __builtin_popcount(static_cast<unsigned>(outside));
  if (snapped == 0) return;  // all outside or clipped (a view of part of the organ)
  const __m512i x0 = gather32(snapped, i0, in.snap_x), x1 = gather32(snapped, i1, in.snap_x),
                x2 = gather32(snapped, i2, in.snap_x);
  const __m512i y0 = gather32(snapped, i0, in.snap_y), y1 = gather32(snapped, i1, in.snap_y),
                y2 = gather32(snapped, i2, in.snap_y);
  const __m512i dx1 = _mm512_sub_epi32(x1, x0), dy2 = _mm512_sub_epi32(y2, y0);
  const __m512i dy1 = _mm512_sub_epi32(y1, y0), dx2 = _mm512_sub_epi32(x2, x0);
  __mmask16 front, flat;
  cross_signs(dx1, dy2, dy1, dx2, &front, &flat);
  const __mmask16 covered =
      covers_avx512(x0, x1, x2, in.width) & covers_avx512(y0, y1, y2, in.height);
  const __mmask16 facing = in.cull_backfaces ? front : __mmask16(0xFFFF);
  const __mmask16 draw = snapped & static_cast<__mmask16>(~flat) & facing & covered;
  out->draw = draw;
  out->front = draw & front;
  out->culled = __builtin_popcount(static_cast<unsigned>(snapped & static_cast<__mmask16>(~draw)));
}
#pragma GCC diagnostic pop
#endif

}  // namespace

void transform_vertices(const VertexPass& pass, const VertexArrays& v, bool use_avx512) {
#if ST_HAVE_AVX512
  if (use_avx512) {
    transform_avx512(pass, v);
    return;
  }
#else
  (void)use_avx512;
#endif
  transform_portable(pass, v);
}

void classify(const CullInput& in, int t0, int n, bool use_avx512, CullBatch* out) {
  *out = {};
#if ST_HAVE_AVX512
  if (use_avx512) {
    classify_avx512(in, t0, n, out);
    return;
  }
#else
  (void)use_avx512;
#endif
  classify_portable(in, t0, n, out);
}

}  // namespace st::raster
