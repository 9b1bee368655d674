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
    const int r0 = 2 * r, r1 = std::min(2 * r + 1, H - 1);
    for (int c = 0; c < (W + 1) / 2; ++c) {
      const int c0 = 2 * c, c1 = std::min(2 * c + 1, W - 1);
      float R = 0, G = 0, B = 0;
      for (const cv::Vec3b& p : {rgb.at<cv::Vec3b>(r0, c0), rgb.at<cv::Vec3b>(r0, c1),
                                 rgb.at<cv::Vec3b>(r1, c0), rgb.at<cv::Vec3b>(r1, c1)}) {
        R += p[0];
        G += p[1];
        B += p[2];
      }
      R *= 0.25f;
      G *= 0.25f;
      B *= 0.25f;
      u(c, r) = to_u8(128.0f - 0.168736f * R - 0.331264f * G + 0.5f * B);
      v(c, r) = to_u8(128.0f + 0.5f * R - 0.418688f * G - 0.081312f * B);
    }
  }
}

}  // namespace st::sim
