#include "core/image/occluder_mask.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/base/capacity.h"
#include "core/image/mask_morphology.h"

#include <opencv2/core/hal/intrin.hpp>

namespace st {

Status OccluderMaskBuilder::configure(const OccluderMaskConfig& c, int width, int height) {
  if (width < 2 || height < 2 || width > kMaxImageWidth || height > kMaxImageHeight)
    return make_error("OccluderMaskBuilder: frame size " + std::to_string(width) + "x" + std::to_string(height) +
                      " outside [2, " + std::to_string(kMaxImageWidth) + "]x[2, " +
                      std::to_string(kMaxImageHeight) + "]");
  if (!(c.max_chroma_ratio >= 0.f && c.max_chroma_ratio < 1.f))
    return make_error("OccluderMaskConfig.max_chroma_ratio must be in [0, 1)");
  if (c.max_chroma < 0 || c.max_chroma > 127)
    return make_error("OccluderMaskConfig.max_chroma must be in [0, 127]");
  if (c.black_luma < 0 || c.black_luma > 255 || c.min_luma < 0 || c.min_luma > 255 || c.max_luma < 0 ||
      c.max_luma > 256)
    return make_error("OccluderMaskConfig: black_luma and min_luma must be in [0, 255], max_luma in [0, 256]");
  if (c.open_radius < 0 || c.open_radius > 16 || c.margin_px < 0 || c.margin_px > 64)
    return make_error("OccluderMaskConfig: open_radius must be in [0, 16] chroma pixels, margin_px in [0, 64]");
  config_ = c;
  width_ = width;
  height_ = height;
  mask_w_ = (width + 1) / 2;
  mask_h_ = (height + 1) / 2;
  const std::size_t n = static_cast<std::size_t>(mask_w_) * static_cast<std::size_t>(mask_h_);
  candidates_buf_.assign(n, 0);
  eroded_.assign(n, 0);
  mask_.assign(n, 0);
  morph_.configure(mask_w_, mask_h_);
  const double r2 = static_cast<double>(c.max_chroma_ratio) * static_cast<double>(c.max_chroma_ratio);
  ratio2_q16_ = static_cast<std::uint32_t>(std::lround(r2 * 65536.0));  // < 65536: a 16-bit factor
  max_chroma2_ = c.max_chroma * c.max_chroma;
  min_luma_ = std::max(c.min_luma, c.black_luma);
  candidates_ = 0;
  return Status::Ok();
}

// The colour test of chroma pixels [x0, x1) of one row (the reference; the
// SIMD path computes the same integers). With m the block's mean luma:
//   du^2 + dv^2 <= max_chroma^2, m >= min_luma, block max < max_luma, and
//   (du^2 + dv^2) * 65536 <= round(ratio^2 * 65536) * (m - black)^2.
int OccluderMaskBuilder::test_span(const RowPointers& p, int x0, int x1) const {
  const int full_w = width_ / 2;  // chroma columns whose 2x2 block lies inside the frame
  int count = 0;
  for (int x = x0; x < x1; ++x) {
    const int du = p.u[x] - 128, dv = p.v[x] - 128;
    const int c2 = du * du + dv * dv;
    const int xr = x < full_w ? 2 * x + 1 : 2 * x;  // odd width: last column twice
    const int a = p.r0[2 * x], b = p.r0[xr], c = p.r1[2 * x], d = p.r1[xr];
    const int mean = (a + b + c + d + 2) >> 2;
    const int mx = std::max(std::max(a, b), std::max(c, d));
    const auto e = static_cast<std::uint32_t>(std::max(mean - config_.black_luma, 0));
    const bool neutral = c2 <= max_chroma2_ && mean >= min_luma_ && mx < config_.max_luma &&
                         (static_cast<std::uint32_t>(c2) << 16) <= ratio2_q16_ * (e * e);
    p.out[x] = neutral ? 255 : 0;
    count += neutral;
  }
  return count;
}

#if CV_SIMD128
namespace {

struct Limits {  // the test's constants (see the header's integer form)
  int black_luma, min_luma, max_luma, max_chroma, max_chroma2;
  std::uint32_t ratio2_q16;
};

// The test for the 16 chroma pixels at x (their 2x2 blocks inside the
// frame), into out (0 / 255, also returned).
cv::v_uint8x16 test_16(const std::uint8_t* r0, const std::uint8_t* r1, const std::uint8_t* u, const std::uint8_t* v,
                       std::uint8_t* out, int x, const Limits& c) {
  using namespace cv;
  const v_uint8x16 centre = v_setall_u8(128);
  const v_uint8x16 clamp = v_setall_u8(static_cast<std::uint8_t>(c.max_chroma + 1));
  // |du|, |dv| clamped to max_chroma + 1 (<= 128): the squares fit 16 bits
  // and a clamped pixel still fails the max_chroma test.
  const v_uint8x16 du = v_min(v_absdiff(v_load(u + x), centre), clamp);
  const v_uint8x16 dv = v_min(v_absdiff(v_load(v + x), centre), clamp);
  if (!v_check_any(v_max(du, dv) < clamp)) {  // all coloured: tissue, the common case
    v_store(out + x, v_setzero_u8());
    return v_setzero_u8();
  }
  v_uint16x8 du_l, du_h, dv_l, dv_h;
  v_expand(du, du_l, du_h);
  v_expand(dv, dv_l, dv_h);
  const v_uint16x8 c2[2] = {v_mul_wrap(du_l, du_l) + v_mul_wrap(dv_l, dv_l),
                            v_mul_wrap(du_h, du_h) + v_mul_wrap(dv_h, dv_h)};
  v_uint8x16 a0, b0, a1, b1;  // even / odd columns of both luma rows
  v_load_deinterleave(r0 + 2 * x, a0, b0);
  v_load_deinterleave(r1 + 2 * x, a1, b1);
  v_uint16x8 l[4], h[4];
  v_expand(a0, l[0], h[0]);
  v_expand(b0, l[1], h[1]);
  v_expand(a1, l[2], h[2]);
  v_expand(b1, l[3], h[3]);
  const v_uint16x8 two = v_setall_u16(2);
  const v_uint16x8 mean[2] = {v_shr<2>(l[0] + l[1] + l[2] + l[3] + two), v_shr<2>(h[0] + h[1] + h[2] + h[3] + two)};
  const v_uint16x8 black = v_setall_u16(static_cast<std::uint16_t>(c.black_luma));
  const v_uint16x8 min_luma = v_setall_u16(static_cast<std::uint16_t>(c.min_luma));
  const v_uint16x8 max_c2 = v_setall_u16(static_cast<std::uint16_t>(c.max_chroma2));
  const v_uint16x8 ratio2 = v_setall_u16(static_cast<std::uint16_t>(c.ratio2_q16));
  v_uint16x8 pass[2];
  for (int k = 0; k < 2; ++k) {
    const v_uint16x8 e = mean[k] - black;  // saturating: max(mean - black, 0)
    v_uint32x4 lim_l, lim_h, c_l, c_h;
    v_mul_expand(v_mul_wrap(e, e), ratio2, lim_l, lim_h);  // e^2 <= 65025 fits 16 bits
    v_expand(c2[k], c_l, c_h);
    const v_uint16x8 ratio_ok = v_pack(v_reinterpret_as_u32(v_shl<16>(c_l) <= lim_l) >> 16,
                                       v_reinterpret_as_u32(v_shl<16>(c_h) <= lim_h) >> 16);
    pass[k] = ratio_ok & (c2[k] <= max_c2) & (mean[k] >= min_luma);
  }
  v_uint8x16 neutral = v_pack(pass[0] >> 8, pass[1] >> 8);  // 0xffff -> 0xff
  if (c.max_luma <= 255) {
    const v_uint8x16 max_luma = v_setall_u8(static_cast<std::uint8_t>(c.max_luma));
    neutral = neutral & (v_max(v_max(a0, b0), v_max(a1, b1)) < max_luma);
  }
  v_store(out + x, neutral);
  return neutral;
}

}  // namespace
#endif

int OccluderMaskBuilder::test_row_simd(const RowPointers& p, int* x_end) const {
  int x = 0, count = 0;
#if CV_SIMD128
  const Limits limits{config_.black_luma, min_luma_, config_.max_luma, config_.max_chroma, max_chroma2_, ratio2_q16_};
  // Per lane, how many of the row's chunks passed (<= 4096 / 32 < 256).
  const cv::v_uint8x16 one = cv::v_setall_u8(1);
  cv::v_uint8x16 passed = cv::v_setzero_u8();
  for (; x + 16 <= width_ / 2; x += 16)  // blocks 2x .. 2x + 31 of both luma rows exist
    passed = cv::v_add_wrap(passed, test_16(p.r0, p.r1, p.u, p.v, p.out, x, limits) & one);
  cv::v_uint16x8 passed_l, passed_h;
  cv::v_expand(passed, passed_l, passed_h);
  count = static_cast<int>(cv::v_reduce_sum(passed_l + passed_h));
#else
  (void)p;
#endif
  *x_end = x;
  return count;
}

// Colour test per chroma pixel into candidates_buf_ (0 / 255), counted, and
// the band of rows that holds them. 16 pixels per SIMD step where available
// (the same integers as test_span).
void OccluderMaskBuilder::mark_candidates(GrayView luma, GrayView u, GrayView v) {
  int count = 0;
  first_row_ = mask_h_;
  last_row_ = -1;
  for (int y = 0; y < mask_h_; ++y) {
    const int count_before = count;
    const RowPointers p{luma.row(2 * y), luma.row(std::min(2 * y + 1, height_ - 1)),  // odd height: last row twice
                        u.row(y), v.row(y), candidates_buf_.data() + static_cast<std::ptrdiff_t>(y) * mask_w_};
    int x = 0;
    count += test_row_simd(p, &x);
    count += test_span(p, x, mask_w_);
    if (count > count_before) {
      first_row_ = std::min(first_row_, y);
      last_row_ = y;
    }
  }
  candidates_ = count;
}

GrayView OccluderMaskBuilder::build(GrayView luma, GrayView u, GrayView v) {
  candidates_ = 0;
  if (mask_w_ == 0 || luma.empty() || u.empty() || v.empty()) return GrayView();
  if (luma.width != width_ || luma.height != height_ || u.width != mask_w_ || u.height != mask_h_ ||
      v.width != mask_w_ || v.height != mask_h_)
    return GrayView();
  mark_candidates(luma, u, v);
  if (candidates_ == 0) {  // the common case on tissue alone: nothing to clean
    std::fill(mask_.begin(), mask_.end(), 0);
    return mask();
  }
  // Opening then margin: erode by r, dilate by r + margin (square structuring
  // elements: two dilations are one by the sum of their radii). Only the
  // band of rows that holds candidates, widened by r + margin, can be set;
  // the band includes >= r empty rows beyond the candidates (or the frame's
  // edge), so the erosion inside it is the whole frame's.
  const int margin = (config_.margin_px + 1) / 2;  // frame pixels -> chroma pixels, rounded up
  const int reach = config_.open_radius + margin;
  const int y0 = std::max(first_row_ - reach, 0), y1 = std::min(last_row_ + reach, mask_h_ - 1);
  const int rows = y1 - y0 + 1;
  const std::ptrdiff_t off = static_cast<std::ptrdiff_t>(y0) * mask_w_;
  std::fill(mask_.begin(), mask_.begin() + off, 0);
  std::fill(mask_.begin() + off + static_cast<std::ptrdiff_t>(rows) * mask_w_, mask_.end(), 0);
  const MorphScratch scratch = morph_.scratch(mask_w_, rows);
  const GrayView cand(candidates_buf_.data() + off, mask_w_, rows, mask_w_);
  const ImageView<std::uint8_t> out(mask_.data() + off, mask_w_, rows, mask_w_);
  if (config_.open_radius > 0) {
    const ImageView<std::uint8_t> eroded(eroded_.data(), mask_w_, rows, mask_w_);
    morph_square(cand, -config_.open_radius, eroded, scratch);
    morph_square(eroded, reach, out, scratch);
  } else {
    morph_square(cand, margin, out, scratch);
  }
  return mask();
}

int OccluderMaskBuilder::flagged_pixels() const {
  if (candidates_ == 0) return 0;
  int flagged = 0;
  for (std::uint8_t m : mask_) flagged += m != 0;
  return flagged;
}

int remove_occluders(GrayView valid, GrayView occluder, ImageView<std::uint8_t> out) {
  const int w = std::min(valid.width, out.width), h = std::min(valid.height, out.height);
  int removed = 0;
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* in = valid.row(y);
    std::uint8_t* o = out.row(y);
    const bool has_row = y < occluder.height && !occluder.empty();
    const std::uint8_t* occ = has_row ? occluder.row(y) : nullptr;
    const int wo = has_row ? std::min(w, occluder.width) : 0;
    for (int x = 0; x < wo; ++x) {
      removed += (occ[x] != 0) & (in[x] != 0);
      o[x] = occ[x] ? 0 : in[x];
    }
    for (int x = wo; x < w; ++x) o[x] = in[x];
  }
  return removed;
}

}  // namespace st
