#include "core/features/fast9.h"

#include <algorithm>
#include <bit>
#include <cstring>
#include <string>

#include <opencv2/core/hal/intrin.hpp>

namespace st {
namespace {

// Bresenham circle of radius 3, clockwise from the top.
constexpr int kCircleDx[16] = {0, 1, 2, 3, 3, 3, 2, 1, 0, -1, -2, -3, -3, -3, -2, -1};
constexpr int kCircleDy[16] = {-3, -3, -2, -1, 0, 1, 2, 3, 3, 3, 2, 1, 0, -1, -2, -3};

// max over the 16 arcs of 9 of the arc's minimum of d (d has 25 entries:
// the 16 circle values followed by the first 9 again).
int best_arc_min(const int* d) {
  int m2[24], m4[22], m8[18];
  for (int i = 0; i < 24; ++i) m2[i] = std::min(d[i], d[i + 1]);
  for (int i = 0; i < 22; ++i) m4[i] = std::min(m2[i], m2[i + 2]);
  for (int i = 0; i < 18; ++i) m8[i] = std::min(m4[i], m4[i + 4]);
  int best = 0;
  for (int i = 0; i < 16; ++i) best = std::max(best, std::min(m8[i], d[i + 8]));
  return best;
}

#if CV_SIMD128
// best_arc_min for 16 pixels q[0..15]: circle differences d(i) =
// (circle ^ flip) - (centre ^ flip), saturated at 0, the arcs wrap around.
// A 9-arc is three 3-arcs: the 16 minima of 3 are kept (16 registers, the
// differences are reloaded from L1 instead of held), then 2 x 16 minima and
// 15 maxima; fewer live vectors than a 2-4-8 tree, so fewer spills on SSE2.
inline cv::v_uint8x16 best_arc_min_simd(const std::uint8_t* q, const std::ptrdiff_t* off,
                                        cv::v_uint8x16 flip, cv::v_uint8x16 centre_flipped) {
  const auto d = [&](int i) { return (cv::v_load(q + off[i & 15]) ^ flip) - centre_flipped; };
  cv::v_uint8x16 m3[16];
  cv::v_uint8x16 a = d(0), b = d(1);
  for (int i = 0; i < 16; ++i) {
    const cv::v_uint8x16 c = d(i + 2);
    m3[i] = cv::v_min(cv::v_min(a, b), c);
    a = b;
    b = c;
  }
  cv::v_uint8x16 best = cv::v_setzero_u8();
  for (int i = 0; i < 16; ++i)
    best = cv::v_max(best, cv::v_min(cv::v_min(m3[i], m3[(i + 3) & 15]), m3[(i + 6) & 15]));
  return best;
}
#endif

}  // namespace

int fast9_score(GrayView image, int x, int y) {
  const std::uint8_t* p = image.row(y) + x;
  const int c = p[0];
  int bright[25], dark[25];
  for (int i = 0; i < 25; ++i) {
    const int k = i & 15;
    const int v = p[kCircleDy[k] * image.stride + kCircleDx[k]];
    bright[i] = v - c;
    dark[i] = c - v;
  }
  return std::max(best_arc_min(bright), best_arc_min(dark));
}

Status Fast9Detector::configure(int max_width) {
  if (max_width < 8 || max_width > 65535)
    return make_error("Fast9Detector: max_width " + std::to_string(max_width) + " outside [8, 65535]");
  max_width_ = max_width;
  score_rows_.assign(static_cast<std::size_t>(max_width) * 3, 0);
  corner_xs_.assign(static_cast<std::size_t>(max_width) * 3, 0);
  return Status::Ok();
}

#if CV_SIMD128
namespace {

// Scores 16 pixels q[0..15] (lanes outside lane_keep ignored); appends
// corners (score > threshold) to scores/xs. The cheap pre-test (a 9-arc holds
// two neighbouring compass pixels {0, 4, 8, 12}) picks each lane's polarity:
// a lane that can only be a dark corner is scored on inverted intensities
// (x ^ 0xFF), so one pass scores both kinds of lanes. Only if some lane could
// be both is the dark polarity scored again for all lanes. The score of a
// lane is max(bright, dark); a polarity failing its pre-test is <= threshold,
// so leaving it out never changes a corner's score.
CV_ALWAYS_INLINE void score_block16(const std::uint8_t* q, const std::ptrdiff_t* off, int threshold,
                                    int x, unsigned lane_keep, std::uint8_t* scores,
                                    std::uint16_t* xs, int* n) {
  const cv::v_uint8x16 tv = cv::v_setall_u8(static_cast<std::uint8_t>(threshold));
  const cv::v_uint8x16 v = cv::v_load(q);
  const cv::v_uint8x16 hi = v + tv, lo = v - tv;  // saturating
  const cv::v_uint8x16 c0 = cv::v_load(q + off[0]), c4 = cv::v_load(q + off[4]);
  const cv::v_uint8x16 c8 = cv::v_load(q + off[8]), c12 = cv::v_load(q + off[12]);
  // (c0 > hi | c8 > hi) & (c4 > hi | c12 > hi) as one comparison of
  // min(max(c0, c8), max(c4, c12)) with hi, kept as a saturating difference
  // (non-zero = passes): fewer operations on the path most blocks leave by.
  const cv::v_uint8x16 zero = cv::v_setzero_u8();
  const cv::v_uint8x16 over = cv::v_min(cv::v_max(c0, c8), cv::v_max(c4, c12)) - hi;
  const cv::v_uint8x16 under = lo - cv::v_max(cv::v_min(c0, c8), cv::v_min(c4, c12));
  if (cv::v_signmask((over | under) == zero) == 0xFFFF) return;
  // Second pre-test, on the 8 even circle pixels: a 9-arc holds 4 or 5
  // consecutive ones, so a corner needs 4 consecutive even pixels all above
  // hi (or all below lo). Halves the blocks scored in full at the strict
  // threshold, and picks each lane's polarity more tightly.
  const cv::v_uint8x16 e[8] = {c0, cv::v_load(q + off[2]),  c4,  cv::v_load(q + off[6]),
                               c8, cv::v_load(q + off[10]), c12, cv::v_load(q + off[14])};
  cv::v_uint8x16 lo2[8], hi2[8];  // min / max of even neighbours (i, i + 1)
  for (int i = 0; i < 8; ++i) {
    lo2[i] = cv::v_min(e[i], e[(i + 1) & 7]);
    hi2[i] = cv::v_max(e[i], e[(i + 1) & 7]);
  }
  cv::v_uint8x16 best_low = zero, best_high = cv::v_setall_u8(255);
  for (int i = 0; i < 8; ++i) {
    best_low = cv::v_max(best_low, cv::v_min(lo2[i], lo2[(i + 2) & 7]));
    best_high = cv::v_min(best_high, cv::v_max(hi2[i], hi2[(i + 2) & 7]));
  }
  const cv::v_uint8x16 over4 = best_low - hi, under4 = lo - best_high;
  if (cv::v_signmask((over4 | under4) == zero) == 0xFFFF) return;
  const cv::v_uint8x16 bright = ~(over4 == zero), dark = ~(under4 == zero);
  // Lanes that can only be dark: inverted.
  const cv::v_uint8x16 flip = dark & ~bright;
  cv::v_uint8x16 score = best_arc_min_simd(q, off, flip, v ^ flip);
  if (cv::v_check_any(bright & dark)) {
    const cv::v_uint8x16 all = cv::v_setall_u8(255);
    score = cv::v_max(score, best_arc_min_simd(q, off, all, v ^ all));
  }
  // A lane is a corner iff its score exceeds the threshold.
  unsigned mask = static_cast<unsigned>(cv::v_signmask(score > tv)) & lane_keep;
  if (!mask) return;
  alignas(16) std::uint8_t lane_score[16];
  cv::v_store_aligned(lane_score, score);
  while (mask) {
    const int lane = std::countr_zero(mask);
    mask &= mask - 1;
    scores[x + lane] = lane_score[lane];
    xs[(*n)++] = static_cast<std::uint16_t>(x + lane);
  }
}

}  // namespace
#endif

void Fast9Detector::score_row(GrayView image, int y, int threshold, int x_begin, int x_end,
                              const std::uint8_t* allowed, int allowed_chunks, std::uint8_t* scores,
                              std::uint16_t* xs, int* n) {
  const std::uint8_t* p = image.row(y);
  int x = x_begin;
#if CV_SIMD128
  std::ptrdiff_t off[16];
  for (int i = 0; i < 16; ++i) off[i] = kCircleDy[i] * image.stride + kCircleDx[i];
  while (x + 16 <= x_end) {
    if (allowed) {
      const int c = x >> 4;
      std::uint64_t closed8 = 1;
      if (c + 8 <= allowed_chunks) std::memcpy(&closed8, allowed + c, sizeof closed8);
      if (closed8 == 0) {
        // Chunks c..c+7 all closed (the relaxed passes leave most chunks
        // closed): jump to the first block reaching chunk c + 8.
        x += ((16 * (c + 8) - 15 - x) + 15) / 16 * 16;
        continue;
      }
      if (!(allowed[c] | allowed[(x + 15) >> 4])) {
        x += 16;
        continue;
      }
    }
    score_block16(p + x, off, threshold, x, 0xFFFFu, scores, xs, n);
    x += 16;
  }
  // Tail: one overlapping block ending at x_end, only the lanes not yet seen.
  if (x < x_end && x_end - 16 >= x_begin) {
    const int xb = x_end - 16;
    unsigned keep = 0;
    for (int lane = x - xb; lane < 16; ++lane)
      if (!allowed || allowed[(xb + lane) >> 4]) keep |= 1u << lane;
    if (keep) score_block16(p + xb, off, threshold, xb, keep, scores, xs, n);
    x = x_end;
  }
#endif
  for (; x < x_end; ++x) {
    if (allowed && !allowed[x >> 4]) continue;
    const int s = fast9_score(image, x, y);
    if (s > threshold) {
      scores[x] = static_cast<std::uint8_t>(s);
      xs[(*n)++] = static_cast<std::uint16_t>(x);
    }
  }
}

int Fast9Detector::detect(GrayView image, int threshold, int border, const std::uint8_t* allowed,
                          int allowed_stride, FastCorner* out, int capacity) {
  border = std::max(border, 3);
  threshold = std::clamp(threshold, 0, 254);
  const int w = image.width, h = image.height;
  if (w > max_width_ || w < 2 * border + 1 || h < 2 * border + 1) return 0;
  std::uint8_t* srow[3];
  std::uint16_t* xrow[3];
  int nrow[3] = {0, 0, 0};
  for (int i = 0; i < 3; ++i) {
    srow[i] = score_rows_.data() + static_cast<std::size_t>(i) * max_width_;
    xrow[i] = corner_xs_.data() + static_cast<std::size_t>(i) * max_width_;
    std::memset(srow[i], 0, static_cast<std::size_t>(w));
  }
  int count = 0;
  // Row y is scored into slot 2; the suppression runs on slot 1 (row y - 1)
  // against slots 0 and 2; then the slots rotate.
  for (int y = border; y <= h - border; ++y) {
    if (y < h - border) {
      const std::uint8_t* arow = allowed ? allowed + static_cast<std::ptrdiff_t>(y) * allowed_stride : nullptr;
      score_row(image, y, threshold, border, w - border, arow, allowed_stride, srow[2], xrow[2],
                &nrow[2]);
    }
    const std::uint8_t *up = srow[0], *mid = srow[1], *dn = srow[2];
    for (int i = 0; i < nrow[1] && count < capacity; ++i) {
      const int x = xrow[1][i];
      const int s = mid[x];
      // Strict against earlier neighbours, non-strict against later ones:
      // exactly one pixel of a plateau survives.
      if (s <= up[x - 1] || s <= up[x] || s <= up[x + 1] || s <= mid[x - 1]) continue;
      if (s < mid[x + 1] || s < dn[x - 1] || s < dn[x] || s < dn[x + 1]) continue;
      out[count++] = FastCorner{static_cast<std::uint16_t>(x), static_cast<std::uint16_t>(y - 1),
                                static_cast<std::uint8_t>(s)};
    }
    // Rotate: clear the oldest slot's corners and reuse it for the next row.
    for (int i = 0; i < nrow[0]; ++i) srow[0][xrow[0][i]] = 0;
    std::uint8_t* s0 = srow[0];
    std::uint16_t* x0 = xrow[0];
    srow[0] = srow[1]; xrow[0] = xrow[1]; nrow[0] = nrow[1];
    srow[1] = srow[2]; xrow[1] = xrow[2]; nrow[1] = nrow[2];
    srow[2] = s0; xrow[2] = x0; nrow[2] = 0;
  }
  return count;
}

}  // namespace st
