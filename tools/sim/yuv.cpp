#include "tools/sim/yuv.h"

#include <algorithm>
#include <cmath>

namespace st::sim {
namespace {

inline std::uint8_t to_u8(float v) { return static_cast<std::uint8_t>(std::clamp(v + 0.5f, 0.0f, 255.0f)); }

}  // namespace

void rgb_to_yuv420_jpeg(const cv::Mat& rgb, ImageView<std::uint8_t> y, ImageView<std::uint8_t> u,
                        ImageView<std::uint8_t> v) {
  const int W = rgb.cols, H = rgb.rows;
  for (int r = 0; r < H; ++r) {
    const auto* in = rgb.ptr<cv::Vec3b>(r);
    std::uint8_t* out = y.row(r);
    for (int c = 0; c < W; ++c)
      out[c] = to_u8(0.299f * in[c][0] + 0.587f * in[c][1] + 0.114f * in[c][2]);
  }
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
