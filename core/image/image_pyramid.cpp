#include "core/image/image_pyramid.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include <opencv2/core/hal/intrin.hpp>

namespace st {
namespace {

// Gaussian sigma 2 sampled at 0..3 and scaled to sum 256 (exact in 16 bits:
// 255 * 256 = 65280).
constexpr int kBlurW0 = 54, kBlurW1 = 49, kBlurW2 = 34, kBlurW3 = 18;

// Source index and weight (of index+1, out of 128) for a bilinear resize
// with pixel centres aligned: s = (d + 0.5) * ratio - 0.5.
void make_axis_table(int dst_n, int src_n, std::vector<std::int32_t>& idx,
                     std::vector<std::uint8_t>& w) {
  idx.assign(static_cast<std::size_t>(dst_n), 0);
  w.assign(static_cast<std::size_t>(dst_n), 0);
  const double ratio = static_cast<double>(src_n) / dst_n;
  for (int d = 0; d < dst_n; ++d) {
    const double s = (d + 0.5) * ratio - 0.5;
    int i0 = static_cast<int>(std::floor(s));
    int wi = static_cast<int>(std::lround((s - i0) * 128.0));
    if (wi == 128) { ++i0; wi = 0; }
    if (i0 < 0) { i0 = 0; wi = 0; }
    if (i0 >= src_n - 1) { i0 = std::max(src_n - 2, 0); wi = src_n > 1 ? 128 : 0; }
    idx[static_cast<std::size_t>(d)] = i0;
    w[static_cast<std::size_t>(d)] = static_cast<std::uint8_t>(wi);
  }
}

#if CV_SIMD128
// The 7-tap weighted sum of 16 pixels, taps load(0)..load(6) (symmetric
// about tap 3), rounded and stored as u8. Shared by both blur passes.
template <class Load>
inline void blur7_store(std::uint8_t* out, Load load) {
  const cv::v_uint16x8 w0 = cv::v_setall_u16(kBlurW0), w1 = cv::v_setall_u16(kBlurW1),
                       w2 = cv::v_setall_u16(kBlurW2), w3 = cv::v_setall_u16(kBlurW3);
  cv::v_uint16x8 lo[7], hi[7];
  for (int i = 0; i < 7; ++i) cv::v_expand(load(i), lo[i], hi[i]);
  cv::v_uint16x8 sl = cv::v_mul_wrap(lo[3], w0), sh = cv::v_mul_wrap(hi[3], w0);
  sl = cv::v_add_wrap(sl, cv::v_mul_wrap(cv::v_add_wrap(lo[2], lo[4]), w1));
  sh = cv::v_add_wrap(sh, cv::v_mul_wrap(cv::v_add_wrap(hi[2], hi[4]), w1));
  sl = cv::v_add_wrap(sl, cv::v_mul_wrap(cv::v_add_wrap(lo[1], lo[5]), w2));
  sh = cv::v_add_wrap(sh, cv::v_mul_wrap(cv::v_add_wrap(hi[1], hi[5]), w2));
  sl = cv::v_add_wrap(sl, cv::v_mul_wrap(cv::v_add_wrap(lo[0], lo[6]), w3));
  sh = cv::v_add_wrap(sh, cv::v_mul_wrap(cv::v_add_wrap(hi[0], hi[6]), w3));
  cv::v_store(out, cv::v_rshr_pack<8>(sl, sh));
}
#endif

// Vertical 7-tap pass: rows r[0..6] -> tmp (u8, rounded).
void blur_vertical(const std::uint8_t* const r[7], std::uint8_t* out, int width) {
  int x = 0;
#if CV_SIMD128
  for (; x + 16 <= width; x += 16) {
    blur7_store(out + x, [&](int i) { return cv::v_load(r[i] + x); });
  }
  if (x < width && width >= 16) {  // tail: one block overlapping the last one
    x = width - 16;
    blur7_store(out + x, [&](int i) { return cv::v_load(r[i] + x); });
    x = width;
  }
#endif
  for (; x < width; ++x) {
    const int s = kBlurW0 * r[3][x] + kBlurW1 * (r[2][x] + r[4][x]) +
                  kBlurW2 * (r[1][x] + r[5][x]) + kBlurW3 * (r[0][x] + r[6][x]);
    out[x] = static_cast<std::uint8_t>((s + 128) >> 8);
  }
}

// Horizontal 7-tap pass: p points at a row padded by 3 replicated pixels on
// both sides (p[-3] .. p[width + 2] valid).
void blur_horizontal(const std::uint8_t* p, std::uint8_t* out, int width) {
  int x = 0;
#if CV_SIMD128
  for (; x + 16 <= width; x += 16) {
    blur7_store(out + x, [&](int i) { return cv::v_load(p + x + i - 3); });
  }
  if (x < width && width >= 16) {  // tail: one block overlapping the last one
    x = width - 16;
    blur7_store(out + x, [&](int i) { return cv::v_load(p + x + i - 3); });
    x = width;
  }
#endif
  for (; x < width; ++x) {
    const int s = kBlurW0 * p[x] + kBlurW1 * (p[x - 1] + p[x + 1]) +
                  kBlurW2 * (p[x - 2] + p[x + 2]) + kBlurW3 * (p[x - 3] + p[x + 3]);
    out[x] = static_cast<std::uint8_t>((s + 128) >> 8);
  }
}

}  // namespace

void gaussian_blur7(GrayView src, ImageView<std::uint8_t> dst, std::uint8_t* tmp) {
  const int w = src.width, h = src.height;
  std::uint8_t* padded = tmp + 3;
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* rows[7];
    for (int i = 0; i < 7; ++i) rows[i] = src.row(std::clamp(y + i - 3, 0, h - 1));
    blur_vertical(rows, padded, w);
    for (int i = 1; i <= 3; ++i) {
      padded[-i] = padded[0];
      padded[w - 1 + i] = padded[w - 1];
    }
    blur_horizontal(padded, dst.row(y), w);
  }
}

Status ImagePyramid::configure(int width, int height, int levels, float scale_factor) {
  if (width < 32 || height < 32 || width > kMaxImageWidth || height > kMaxImageHeight)
    return make_error("ImagePyramid: image size " + std::to_string(width) + "x" +
                      std::to_string(height) + " outside [32, " + std::to_string(kMaxImageWidth) +
                      "]");
  if (levels < 1 || levels > kMaxPyramidLevels)
    return make_error("ImagePyramid: levels " + std::to_string(levels) + " outside [1, " +
                      std::to_string(kMaxPyramidLevels) + "]");
  if (!(scale_factor > 1.0f && scale_factor <= 2.0f))
    return make_error("ImagePyramid: scale_factor must be in (1, 2]");
  width_ = width;
  height_ = height;
  levels_ = levels;
  for (int k = 0; k < levels; ++k) {
    scale_[k] = static_cast<float>(std::pow(static_cast<double>(scale_factor), k));
    const int w = std::max(1, static_cast<int>(std::lround(width / static_cast<double>(scale_[k]))));
    const int h = std::max(1, static_cast<int>(std::lround(height / static_cast<double>(scale_[k]))));
    levels_img_[k].allocate(w, h);
    if (k > 0) {
      make_axis_table(w, levels_img_[k - 1].width(), tables_[k].x0, tables_[k].wx);
      make_axis_table(h, levels_img_[k - 1].height(), tables_[k].y0, tables_[k].wy);
      tables_[k].wpair.assign(static_cast<std::size_t>(2 * w), 0);
      for (int i = 0; i < w; ++i) {
        tables_[k].wpair[static_cast<std::size_t>(2 * i)] = static_cast<std::int16_t>(128 - tables_[k].wx[static_cast<std::size_t>(i)]);
        tables_[k].wpair[static_cast<std::size_t>(2 * i + 1)] = static_cast<std::int16_t>(tables_[k].wx[static_cast<std::size_t>(i)]);
      }
    }
  }
  smooth_.allocate(width, height);
  row_tmp_.assign(static_cast<std::size_t>(width) + 16, 0);
  blur_tmp_.assign(static_cast<std::size_t>(width) + 16, 0);
  denoise_row_.assign(static_cast<std::size_t>(width) + 16, 0);
  return Status::Ok();
}

void ImagePyramid::resize_level(int k) {
  const GrayView src = levels_img_[k - 1].cview();
  const ImageView<std::uint8_t> dst = levels_img_[k].view();
  const ResizeTables& t = tables_[k];
  std::uint16_t* tmp = row_tmp_.data();
  for (int y = 0; y < dst.height; ++y) {
    const std::uint8_t* r0 = src.row(t.y0[static_cast<std::size_t>(y)]);
    const std::uint8_t* r1 = src.row(std::min(t.y0[static_cast<std::size_t>(y)] + 1, src.height - 1));
    const int wy = t.wy[static_cast<std::size_t>(y)];
    int x = 0;
#if CV_SIMD128
    const cv::v_uint16x8 a = cv::v_setall_u16(static_cast<std::uint16_t>(128 - wy));
    const cv::v_uint16x8 b = cv::v_setall_u16(static_cast<std::uint16_t>(wy));
    for (; x + 16 <= src.width; x += 16) {
      cv::v_uint16x8 l0, h0, l1, h1;
      cv::v_expand(cv::v_load(r0 + x), l0, h0);
      cv::v_expand(cv::v_load(r1 + x), l1, h1);
      cv::v_store(tmp + x, cv::v_add_wrap(cv::v_mul_wrap(l0, a), cv::v_mul_wrap(l1, b)));
      cv::v_store(tmp + x + 8, cv::v_add_wrap(cv::v_mul_wrap(h0, a), cv::v_mul_wrap(h1, b)));
    }
#endif
    for (; x < src.width; ++x)
      tmp[x] = static_cast<std::uint16_t>(r0[x] * (128 - wy) + r1[x] * wy);
    horizontal_blend(tmp, t, dst.row(y), dst.width);
  }
}

// Horizontal bilinear pass of one vertically blended row (u16, <= 255 * 128):
// 8 output pixels per dot product of (left, right) pairs with (128 - w, w).
void ImagePyramid::horizontal_blend(const std::uint16_t* tmp, const ResizeTables& t,
                                    std::uint8_t* out, int width) {
  const std::int32_t* x0 = t.x0.data();
  const std::uint8_t* wx = t.wx.data();
  int i = 0;
#if CV_SIMD128
  const std::int16_t* wpair = t.wpair.data();
  const cv::v_int32x4 half = cv::v_setall_s32(8192);
  // (tmp[x0], tmp[x0 + 1]) as one 32-bit load each, assembled in registers:
  // going through a stack array would make every vector load wait on four
  // narrower stores (no store-to-load forwarding).
  const auto pair = [tmp](std::int32_t x) {
    std::uint32_t v;
    std::memcpy(&v, tmp + x, sizeof v);
    return v;
  };
  for (; i + 16 <= width; i += 16) {
    const std::int32_t* xi = x0 + i;
    cv::v_int32x4 s[4];
    for (int q = 0; q < 4; ++q) {
      const cv::v_uint32x4 pairs(pair(xi[4 * q]), pair(xi[4 * q + 1]), pair(xi[4 * q + 2]),
                                 pair(xi[4 * q + 3]));
      const cv::v_int16x8 w = cv::v_load(wpair + 2 * i + 8 * q);
      s[q] = cv::v_shr<14>(cv::v_dotprod(cv::v_reinterpret_as_s16(pairs), w) + half);
    }
    cv::v_store(out + i, cv::v_pack_u(cv::v_pack(s[0], s[1]), cv::v_pack(s[2], s[3])));
  }
#endif
  for (; i < width; ++i) {
    const std::uint32_t v = tmp[x0[i]] * static_cast<std::uint32_t>(128 - wx[i]) +
                            tmp[x0[i] + 1] * static_cast<std::uint32_t>(wx[i]);
    out[i] = static_cast<std::uint8_t>((v + 8192u) >> 14);
  }
}

bool ImagePyramid::build_levels(GrayView image, bool denoise) {
  if (image.empty() || image.width != width_ || image.height != height_) return false;
  const ImageView<std::uint8_t> l0 = levels_img_[0].view();
  if (denoise) {
    denoise_level0(image);
  } else {
    for (int y = 0; y < height_; ++y)
      std::memcpy(l0.row(y), image.row(y), static_cast<std::size_t>(width_));
  }
  for (int k = 1; k < levels_; ++k) resize_level(k);
  return true;
}

// Level 0 = image through [1 2 1]^T [1 2 1] / 16, rounded, edges
// replicated: per row the vertical sums (at most 1020) into denoise_row_
// with one replicated column each side, then the horizontal pass.
void ImagePyramid::denoise_level0(GrayView image) {
  const ImageView<std::uint8_t> l0 = levels_img_[0].view();
  std::uint16_t* v = denoise_row_.data() + 1;  // v[-1] and v[width_] are the edge columns
  const int w = width_;
  for (int y = 0; y < height_; ++y) {
    const std::uint8_t* a = image.row(std::max(0, y - 1));
    const std::uint8_t* b = image.row(y);
    const std::uint8_t* c = image.row(std::min(height_ - 1, y + 1));
    int x = 0;
#if CV_SIMD128
    for (; x + 8 <= w; x += 8) {
      const cv::v_uint16x8 vb = cv::v_load_expand(b + x);
      cv::v_store(v + x, cv::v_add_wrap(cv::v_add_wrap(cv::v_load_expand(a + x), cv::v_load_expand(c + x)),
                                        cv::v_add_wrap(vb, vb)));
    }
#endif
    for (; x < w; ++x) v[x] = static_cast<std::uint16_t>(a[x] + 2 * b[x] + c[x]);
    v[-1] = v[0];
    v[w] = v[w - 1];
    std::uint8_t* o = l0.row(y);
    x = 0;
#if CV_SIMD128
    const cv::v_uint16x8 eight = cv::v_setall_u16(8);
    for (; x + 8 <= w; x += 8) {
      const cv::v_uint16x8 m = cv::v_load(v + x);
      // At most 4 * 1020 + 8: fits 16 bits.
      const cv::v_uint16x8 sum = cv::v_add_wrap(cv::v_add_wrap(cv::v_load(v + x - 1), cv::v_load(v + x + 1)),
                                                cv::v_add_wrap(cv::v_add_wrap(m, m), eight));
      cv::v_pack_store(o + x, cv::v_shr<4>(sum));
    }
#endif
    for (; x < w; ++x) o[x] = static_cast<std::uint8_t>((v[x - 1] + 2 * v[x] + v[x + 1] + 8) >> 4);
  }
}

void ImagePyramid::smooth_level(int k) {
  gaussian_blur7(levels_img_[k].cview(), smooth_view(k), blur_tmp_.data());
}

// Same passes as gaussian_blur7, restricted to runs of consecutive marked
// tiles of a tile row: the vertical pass covers the run's columns plus 3 on
// each side (replicated at the level's edges, as the whole-level blur does),
// so the result is identical.
void ImagePyramid::smooth_tiles(int k, const std::uint8_t* tiles, int tiles_x) {
  const GrayView src = levels_img_[k].cview();
  const ImageView<std::uint8_t> dst = smooth_view(k);
  const int w = src.width, h = src.height;
  const int n_tx = std::min(tiles_x, (w + kSmoothTilePx - 1) / kSmoothTilePx);
  std::uint8_t* p_base = blur_tmp_.data() + 3;  // p_base[i] = column x0 + i of the run
  for (int ty = 0; ty * kSmoothTilePx < h; ++ty) {
    const std::uint8_t* trow = tiles + static_cast<std::ptrdiff_t>(ty) * tiles_x;
    for (int tx = 0; tx < n_tx;) {
      if (!trow[tx]) {
        ++tx;
        continue;
      }
      int tx_end = tx + 1;
      while (tx_end < n_tx && trow[tx_end]) ++tx_end;
      const int x0 = tx * kSmoothTilePx, x1 = std::min(tx_end * kSmoothTilePx, w);
      tx = tx_end;
      const int cx0 = std::max(x0 - 3, 0), cx1 = std::min(x1 + 3, w);
      const int y1 = std::min((ty + 1) * kSmoothTilePx, h);
      for (int y = ty * kSmoothTilePx; y < y1; ++y) {
        const std::uint8_t* rows[7];
        for (int i = 0; i < 7; ++i) rows[i] = src.row(std::clamp(y + i - 3, 0, h - 1)) + cx0;
        blur_vertical(rows, p_base + (cx0 - x0), cx1 - cx0);
        if (x0 == 0)
          for (int i = 1; i <= 3; ++i) p_base[-i] = p_base[0];
        if (x1 == w)
          for (int i = 1; i <= 3; ++i) p_base[w - 1 - x0 + i] = p_base[w - 1 - x0];
        blur_horizontal(p_base, dst.row(y) + x0, x1 - x0);
      }
    }
  }
}

}  // namespace st
