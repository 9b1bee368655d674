#include "tools/sim/yuv.h"

#include <algorithm>
#include <cmath>

#include <opencv2/core/hal/intrin.hpp>

namespace st::sim {
namespace {

inline std::uint8_t to_u8(float v) { return static_cast<std::uint8_t>(std::clamp(v + 0.5f, 0.0f, 255.0f)); }

// Luma of one row. Sixteen pixels at a time with OpenCV's universal
// intrinsics (SSE2 / NEON): the same float operations in the same order as
// the scalar tail, so both give the same bytes.
void luma_row(const cv::Vec3b* in, int W, std::uint8_t* out) {
  int c = 0;
#if CV_SIMD128
  const cv::v_float32x4 kr = cv::v_setall_f32(0.299f), kg = cv::v_setall_f32(0.587f), kb = cv::v_setall_f32(0.114f);
  const cv::v_float32x4 half = cv::v_setall_f32(0.5f), zero = cv::v_setzero_f32(), top = cv::v_setall_f32(255.0f);
  // Channel k of pixels 4q..4q+3 as floats.
  auto quarter = [](const cv::v_uint8x16& v, int q) {
    cv::v_uint16x8 lo16, hi16;
    cv::v_expand(v, lo16, hi16);
    cv::v_uint32x4 a, b;
    cv::v_expand(q < 2 ? lo16 : hi16, a, b);
    return cv::v_cvt_f32(cv::v_reinterpret_as_s32(q % 2 == 0 ? a : b));
  };
  for (; c + 16 <= W; c += 16) {
    cv::v_uint8x16 r, g, b;
    cv::v_load_deinterleave(&in[c][0], r, g, b);
    cv::v_int32x4 y[4];
    for (int q = 0; q < 4; ++q)
      y[q] = cv::v_trunc(
          cv::v_min(cv::v_max(kr * quarter(r, q) + kg * quarter(g, q) + kb * quarter(b, q) + half, zero), top));
    cv::v_store(out + c, cv::v_pack_u(cv::v_pack(y[0], y[1]), cv::v_pack(y[2], y[3])));
  }
#endif
  for (; c < W; ++c) out[c] = to_u8(0.299f * in[c][0] + 0.587f * in[c][1] + 0.114f * in[c][2]);
}

}  // namespace

void rgb_to_yuv420_jpeg(const cv::Mat& rgb, ImageView<std::uint8_t> y, ImageView<std::uint8_t> u,
                        ImageView<std::uint8_t> v) {
  const int W = rgb.cols, H = rgb.rows;
  for (int r = 0; r < H; ++r) luma_row(rgb.ptr<cv::Vec3b>(r), W, y.row(r));
  for (int r = 0; r < (H + 1) / 2; ++r) {
    const auto* row0 = rgb.ptr<cv::Vec3b>(2 * r);
    const auto* row1 = rgb.ptr<cv::Vec3b>(std::min(2 * r + 1, H - 1));
    std::uint8_t* out_u = u.row(r);
    std::uint8_t* out_v = v.row(r);
    for (int c = 0; c < (W + 1) / 2; ++c) {
      const int c0 = 2 * c, c1 = std::min(2 * c + 1, W - 1);
      const float R = 0.25f * static_cast<float>(row0[c0][0] + row0[c1][0] + row1[c0][0] + row1[c1][0]);
      const float G = 0.25f * static_cast<float>(row0[c0][1] + row0[c1][1] + row1[c0][1] + row1[c1][1]);
      const float B = 0.25f * static_cast<float>(row0[c0][2] + row0[c1][2] + row1[c0][2] + row1[c1][2]);
      out_u[c] = to_u8(128.0f - 0.168736f * R - 0.331264f * G + 0.5f * B);
      out_v[c] = to_u8(128.0f + 0.5f * R - 0.418688f * G - 0.081312f * B);
    }
  }
}

}  // namespace st::sim
