#include "core/raster_cull.h"

#include <algorithm>

#include "core/raster_triangle.h"

#if ST_RASTER_AVX512
#include <immintrin.h>
#endif

namespace st::raster {
namespace {

// Some pixel centre (integer coordinates) inside the snapped extent lo..hi?
bool covers_pixel_centre(std::int32_t lo, std::int32_t hi, int size) {
  const std::int32_t first = std::max<std::int32_t>(0, (lo + (kSubpixelScale - 1)) >> kSubpixelBits);
  const std::int32_t last = std::min<std::int32_t>(size - 1, hi >> kSubpixelBits);
  return first <= last;
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

#if ST_RASTER_AVX512
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

void classify(const CullInput& in, int t0, int n, bool use_avx512, CullBatch* out) {
  *out = {};
#if ST_RASTER_AVX512
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
