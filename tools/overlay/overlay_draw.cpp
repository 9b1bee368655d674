#include "tools/overlay/overlay_draw.h"

#include <algorithm>
#include <cmath>

namespace st::overlay {

namespace {
std::uint8_t clamp_u8(double v) { return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0l, 255l)); }
}  // namespace

Yuv to_yuv(Rgb c) {
  const double r = c.r, g = c.g, b = c.b;
  return {0.299 * r + 0.587 * g + 0.114 * b, 128.0 - 0.168736 * r - 0.331264 * g + 0.5 * b,
          128.0 + 0.5 * r - 0.418688 * g - 0.081312 * b};
}

void OverlayLayer::reset(int width, int height) {
  bgra_.create(height, width, CV_8UC4);
  clear();
}

void OverlayLayer::clear() { bgra_.setTo(cv::Scalar::all(0)); }

cv::Scalar OverlayLayer::scalar(Rgb c, double alpha) {
  return cv::Scalar(c.b, c.g, c.r, std::clamp(alpha, 0.0, 1.0) * 255.0);
}

void OverlayLayer::set(int x, int y, Rgb c, double alpha) {
  if (x < 0 || y < 0 || x >= bgra_.cols || y >= bgra_.rows) return;
  bgra_.at<cv::Vec4b>(y, x) = cv::Vec4b(c.b, c.g, c.r, clamp_u8(alpha * 255.0));
}

void OverlayLayer::composite(ImageView<std::uint8_t> y, ImageView<std::uint8_t> u,
                             ImageView<std::uint8_t> v) const {
  for (int cy = 0; cy < u.height; ++cy) {
    for (int cx = 0; cx < u.width; ++cx) {
      double a_sum = 0, u_sum = 0, v_sum = 0;
      int n = 0;
      for (int py = 2 * cy; py < std::min(2 * cy + 2, y.height); ++py) {
        for (int px = 2 * cx; px < std::min(2 * cx + 2, y.width); ++px) {
          ++n;
          const cv::Vec4b p = bgra_.at<cv::Vec4b>(py, px);
          if (p[3] == 0) continue;
          const double a = p[3] / 255.0;
          const Yuv c = to_yuv({p[2], p[1], p[0]});
          y(px, py) = clamp_u8((1 - a) * y(px, py) + a * c.y);
          a_sum += a;
          u_sum += a * c.u;
          v_sum += a * c.v;
        }
      }
      if (a_sum <= 0) continue;
      // The block's chroma moves towards the drawn colour by its mean alpha.
      const double a_block = a_sum / n;
      u(cx, cy) = clamp_u8((1 - a_block) * u(cx, cy) + a_block * (u_sum / a_sum));
      v(cx, cy) = clamp_u8((1 - a_block) * v(cx, cy) + a_block * (v_sum / a_sum));
    }
  }
}

void draw_silhouette(ImageView<const std::int32_t> labels, Rgb colour, int half_width, OverlayLayer* layer) {
  const int r = std::max(1, half_width);
  for (int y = 0; y < labels.height; ++y) {
    for (int x = 0; x < labels.width; ++x) {
      const bool organ = labels(x, y) >= 0;
      bool edge = false;
      // Another side within r pixels along a row or a column.
      for (int k = 1; k <= r && !edge; ++k) {
        const int nx[4] = {x - k, x + k, x, x}, ny[4] = {y, y, y - k, y + k};
        for (int j = 0; j < 4 && !edge; ++j)
          edge = labels.contains(nx[j], ny[j]) && (labels(nx[j], ny[j]) >= 0) != organ;
      }
      if (edge) layer->set(x, y, colour, 1.0);
    }
  }
}

void draw_wireframe(ImageView<const std::int32_t> labels, Rgb colour, double alpha, OverlayLayer* layer) {
  for (int y = 0; y + 1 < labels.height; ++y) {
    for (int x = 0; x + 1 < labels.width; ++x) {
      const std::int32_t id = labels(x, y);
      if (id < 0) continue;
      const std::int32_t right = labels(x + 1, y), down = labels(x, y + 1);
      if ((right >= 0 && right != id) || (down >= 0 && down != id)) layer->set(x, y, colour, alpha);
    }
  }
}

}  // namespace st::overlay
