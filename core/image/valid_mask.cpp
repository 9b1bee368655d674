#include "core/image/valid_mask.h"

#include <algorithm>
#include <array>
#include <bit>
#include <string>

#include "core/base/histogram_rank.h"
#include "core/image/mask_morphology.h"

#include <opencv2/core/hal/intrin.hpp>

namespace st {

Status ValidMaskBuilder::configure(const ValidMaskConfig& c, int width, int height) {
  if (c.downscale != 1 && c.downscale != 2 && c.downscale != 4)
    return make_error("ValidMaskConfig.downscale must be 1, 2 or 4");
  if (width < 16 || height < 16 || width > 4096 || height > 4096)
    return make_error("ValidMaskBuilder: frame size " + std::to_string(width) + "x" +
                      std::to_string(height) + " outside [16, 4096]");
  if (c.border_margin_px < 0 || c.highlight_dilate_px < 0 || c.black_offset < 0 ||
      c.highlight_band < 0 || c.highlight_min < 0 || c.highlight_min > 255)
    return make_error("ValidMaskConfig: margins, offsets and bands must be >= 0, highlight_min <= 255");
  config_ = c;
  width_ = width;
  height_ = height;
  mask_w_ = width / c.downscale;
  mask_h_ = height / c.downscale;
  const std::size_t n = static_cast<std::size_t>(mask_w_) * mask_h_;
  mean_.assign(n, 0);
  max_.assign(n, 0);
  sat_.assign(n, 0);
  sat_dil_.assign(n, 0);
  morph_.configure(mask_w_, mask_h_);
  mask_.assign(n, 0);
  for (auto* v : {&first_, &last_, &efirst_, &elast_}) v->assign(static_cast<std::size_t>(mask_h_), 0);
  return Status::Ok();
}

// Block mean (for black) and block max (for saturation) at mask resolution.
void ValidMaskBuilder::downsample(GrayView frame) {
  const int d = config_.downscale;
  const int area = d * d;
  if (d == 2) {
    downsample2(frame);
    return;
  }
  for (int my = 0; my < mask_h_; ++my) {
    std::uint8_t* mean = mean_.data() + static_cast<std::ptrdiff_t>(my) * mask_w_;
    std::uint8_t* mx = max_.data() + static_cast<std::ptrdiff_t>(my) * mask_w_;
    for (int x = 0; x < mask_w_; ++x) {
      int sum = 0, m = 0;
      for (int dy = 0; dy < d; ++dy) {
        const std::uint8_t* r = frame.row(my * d + dy) + x * d;
        for (int dx = 0; dx < d; ++dx) {
          sum += r[dx];
          m = std::max<int>(m, r[dx]);
        }
      }
      mean[x] = static_cast<std::uint8_t>((sum + area / 2) / area);
      mx[x] = static_cast<std::uint8_t>(m);
    }
  }
}

// The common 2x2 case, 16 mask pixels at a time where SIMD is available.
void ValidMaskBuilder::downsample2(GrayView frame) {
  for (int my = 0; my < mask_h_; ++my) {
    const std::uint8_t* r0 = frame.row(2 * my);
    const std::uint8_t* r1 = frame.row(2 * my + 1);
    std::uint8_t* mean = mean_.data() + static_cast<std::ptrdiff_t>(my) * mask_w_;
    std::uint8_t* mx = max_.data() + static_cast<std::ptrdiff_t>(my) * mask_w_;
    int x = 0;
#if CV_SIMD128
    const cv::v_uint16x8 two = cv::v_setall_u16(2);
    for (; x + 16 <= mask_w_; x += 16) {
      cv::v_uint8x16 a0, b0, a1, b1;  // even / odd columns of both rows
      cv::v_load_deinterleave(r0 + 2 * x, a0, b0);
      cv::v_load_deinterleave(r1 + 2 * x, a1, b1);
      cv::v_store(mx + x, cv::v_max(cv::v_max(a0, b0), cv::v_max(a1, b1)));
      cv::v_uint16x8 l[4], h[4];
      cv::v_expand(a0, l[0], h[0]);
      cv::v_expand(b0, l[1], h[1]);
      cv::v_expand(a1, l[2], h[2]);
      cv::v_expand(b1, l[3], h[3]);
      const cv::v_uint16x8 sl = l[0] + l[1] + l[2] + l[3] + two, sh = h[0] + h[1] + h[2] + h[3] + two;
      cv::v_store(mean + x, cv::v_pack(cv::v_shr<2>(sl), cv::v_shr<2>(sh)));
    }
#endif
    for (; x < mask_w_; ++x) {
      const int a = r0[2 * x], b = r0[2 * x + 1], c = r1[2 * x], e = r1[2 * x + 1];
      mean[x] = static_cast<std::uint8_t>((a + b + c + e + 2) >> 2);
      mx[x] = static_cast<std::uint8_t>(std::max(std::max(a, b), std::max(c, e)));
    }
  }
}

// Per row: first and last non-black mask pixel, then erosion of the spans by
// the margin in both directions (a row's span shrinks to the intersection of
// its neighbours' spans, moved inwards).
void ValidMaskBuilder::field_stop_spans() {
  // Black level: 2nd percentile of block means (the border is a large share
  // of a scope frame; if the frame has none, the level is dark tissue and
  // black_max stops us from cutting it).
  std::array<int, 256> hist{};
  for (std::uint8_t v : mean_) ++hist[v];
  const int level = histogram_rank(hist, static_cast<long long>(mean_.size() / 50));
  black_level_ = level;
  const bool has_border = level <= config_.black_max;
  const int thr = level + config_.black_offset;
  for (int y = 0; y < mask_h_; ++y) {
    const std::uint8_t* r = mean_.data() + static_cast<std::ptrdiff_t>(y) * mask_w_;
    int f = 0, l = mask_w_ - 1;
    if (has_border) {
      // The image starts where kRun mask pixels in a row are not black:
      // isolated compression noise in the border does not count.
      constexpr int kRun = 4;
      int run = 0;
      for (f = 0; f < mask_w_ && run < kRun; ++f) run = r[f] > thr ? run + 1 : 0;
      f = run == kRun ? f - kRun : mask_w_;
      run = 0;
      for (l = mask_w_ - 1; l >= f && run < kRun; --l) run = r[l] > thr ? run + 1 : 0;
      l = run == kRun ? l + kRun : -1;
    }
    first_[static_cast<std::size_t>(y)] = f;
    last_[static_cast<std::size_t>(y)] = l;  // empty row: last < first
  }
  const int m = has_border ? (config_.border_margin_px + config_.downscale - 1) / config_.downscale : 0;
  for (int y = 0; y < mask_h_; ++y) {
    int f = 0, l = mask_w_ - 1;
    for (int yy = y - m; yy <= y + m; ++yy) {
      if (yy < 0 || yy >= mask_h_) {
        if (has_border) { f = mask_w_; l = -1; }  // beyond the frame counts as border
        continue;
      }
      f = std::max(f, first_[static_cast<std::size_t>(yy)] + m);
      l = std::min(l, last_[static_cast<std::size_t>(yy)] - m);
    }
    efirst_[static_cast<std::size_t>(y)] = f;
    elast_[static_cast<std::size_t>(y)] = l;
  }
}

GrayView ValidMaskBuilder::build(GrayView frame) {
  if (frame.empty() || frame.width != width_ || frame.height != height_) return GrayView();
  downsample(frame);
  field_stop_spans();
  std::uint8_t frame_max = 0;
  for (std::uint8_t v : max_) frame_max = std::max(frame_max, v);
  highlight_thr_ = std::max(config_.highlight_min, frame_max - config_.highlight_band);
  // Saturated pixels, and the band of rows holding any: highlights are
  // small, so only that band (plus the dilation radius) is dilated.
  const std::uint8_t thr = static_cast<std::uint8_t>(std::min(highlight_thr_, 255));
  highlight_pixels_ = 0;
  int sat_y0 = mask_h_, sat_y1 = -1;
  for (int y = 0; y < mask_h_; ++y) {
    const std::uint8_t* mx = max_.data() + static_cast<std::ptrdiff_t>(y) * mask_w_;
    std::uint8_t* sat = sat_.data() + static_cast<std::ptrdiff_t>(y) * mask_w_;
    int count = 0;
    int x = 0;
#if CV_SIMD128
    const cv::v_uint8x16 thr_v = cv::v_setall_u8(thr);
    // 16 mask pixels per compare (the scalar loop was ~10% of build()).
    for (; x + 16 <= mask_w_; x += 16) {
      const cv::v_uint8x16 s = cv::v_load(mx + x) >= thr_v;
      cv::v_store(sat + x, s);
      count += std::popcount(static_cast<unsigned>(cv::v_signmask(s)));
    }
#endif
    for (; x < mask_w_; ++x) {
      sat[x] = mx[x] >= thr ? 255 : 0;
      count += sat[x] & 1;
    }
    highlight_pixels_ += count;
    if (count) {
      sat_y0 = std::min(sat_y0, y);
      sat_y1 = y;
    }
  }
  const int r = (config_.highlight_dilate_px + config_.downscale - 1) / config_.downscale;
  std::fill(sat_dil_.begin(), sat_dil_.end(), 0);
  if (sat_y1 >= 0) {
    // Rows outside [y0, y1] are empty, so dilating the band alone is exact.
    const int y0 = std::max(sat_y0 - r, 0), y1 = std::min(sat_y1 + r, mask_h_ - 1);
    const std::ptrdiff_t off = static_cast<std::ptrdiff_t>(y0) * mask_w_;
    const int rows = y1 - y0 + 1;
    const MorphScratch scratch = morph_.scratch(mask_w_, rows);
    morph_square(GrayView(sat_.data() + off, mask_w_, rows), r,
                 ImageView<std::uint8_t>(sat_dil_.data() + off, mask_w_, rows), scratch);
  }
  for (int y = 0; y < mask_h_; ++y) {
    std::uint8_t* out = mask_.data() + static_cast<std::ptrdiff_t>(y) * mask_w_;
    const std::uint8_t* sat = sat_dil_.data() + static_cast<std::ptrdiff_t>(y) * mask_w_;
    const int f = std::clamp(efirst_[static_cast<std::size_t>(y)], 0, mask_w_);
    const int l = std::clamp(elast_[static_cast<std::size_t>(y)] + 1, f, mask_w_);  // valid: [f, l)
    std::fill(out, out + f, 0);
    for (int x = f; x < l; ++x) out[x] = static_cast<std::uint8_t>(~sat[x]);  // sat is 0 or 255
    std::fill(out + l, out + mask_w_, 0);
  }
  return mask();
}

int ValidMaskBuilder::median_block_mean(GrayView within, GrayView organ) const {
  if (within.width != mask_w_ || within.height != mask_h_ || mask_w_ == 0) return -1;
  std::array<int, 256> hist{};
  long long n = 0;
  for (int y = 0; y < mask_h_; y += 2) {
    const std::uint8_t* m = mean_.data() + static_cast<std::ptrdiff_t>(y) * mask_w_;
    const std::uint8_t* v = within.row(y);
    const std::uint8_t* o = organ.empty() ? nullptr : organ.row(y * organ.height / mask_h_);
    for (int x = 0; x < mask_w_; x += 2) {
      if (!v[x] || (o && !o[x * organ.width / mask_w_])) continue;
      ++hist[m[x]];
      ++n;
    }
  }
  return n > 0 ? histogram_rank(hist, n / 2) : -1;
}

}  // namespace st
