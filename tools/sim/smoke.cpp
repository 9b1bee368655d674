#include "tools/sim/smoke.h"

#include <algorithm>
#include <cmath>

#include "tools/sim/rng.h"

namespace st::sim {
namespace {

// Episode shape, in frames (30 frames/s): build-up, hold, clearing; and the
// spacing of episode starts.
constexpr double kRise = 12, kHold = 30, kClear = 70;
constexpr double kFirstStart = 20, kFirstJitter = 40, kGap = 150, kGapJitter = 120;
constexpr float kAirlightGain = 1.3f;

double smoothstep(double t) {
  t = std::clamp(t, 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

}  // namespace

void SmokeVeil::configure(double opacity, std::uint64_t seed, int width, int height) {
  opacity_ = std::clamp(opacity, 0.0, kMaxSmoke);
  seed_ = seed;
  width_ = width;
  height_ = height;
  noise_ = Noise3(mix_seed(seed, 0x5E0CE));
  grid_w_ = (width + kStep - 1) / kStep + 1;
  grid_h_ = (height + kStep - 1) / kStep + 1;
  grid_.assign(static_cast<std::size_t>(grid_w_) * static_cast<std::size_t>(grid_h_), 0.f);
}

double SmokeVeil::envelope(int frame) const {
  if (!enabled() || frame < 0) return 0.0;
  Rng rng(mix_seed(seed_, 0xE915));
  double start = kFirstStart + kFirstJitter * rng.uniform(), e = 0.0;
  while (start <= frame) {
    const double t = frame - start;
    const double rise = smoothstep(t / kRise), clear = 1.0 - smoothstep((t - kRise - kHold) / kClear);
    e = std::max(e, std::min(rise, clear));
    start += kGap + kGapJitter * rng.uniform();
  }
  return e;
}

double SmokeVeil::density(int frame, double x, double y) const {
  // Billows about a third of the image wide; the plume rises and drifts.
  const double scale = 3.0 / std::max(width_, 1);
  const double f = frame;
  const float n = noise_.fbm(static_cast<float>(x * scale + 0.006 * f), static_cast<float>(y * scale + 0.015 * f),
                             static_cast<float>(0.01 * f + 7.3), 3);
  return std::clamp(0.45 + 0.9 * static_cast<double>(n), 0.0, 1.0);
}

double SmokeVeil::share(int frame, double x, double y) const {
  const double e = envelope(frame);
  return e > 0.0 ? opacity_ * e * density(frame, x, y) : 0.0;
}

void SmokeVeil::apply(int frame, cv::Mat& linear) {
  const double e = envelope(frame);
  if (e <= 0.0 || linear.type() != CV_32FC3 || linear.cols != width_ || linear.rows != height_) return;
  for (int j = 0; j < grid_h_; ++j)
    for (int i = 0; i < grid_w_; ++i)
      grid_[static_cast<std::size_t>(j) * grid_w_ + i] =
          static_cast<float>(opacity_ * e * density(frame, i * kStep, j * kStep));
  // The airlight: the frame's mean brightness (every 8th pixel), a little raised.
  double sum = 0;
  int n = 0;
  for (int y = 0; y < height_; y += kStep) {
    const auto* row = linear.ptr<cv::Vec3f>(y);
    for (int x = 0; x < width_; x += kStep, ++n) sum += static_cast<double>(row[x][0] + row[x][1] + row[x][2]) / 3.0;
  }
  const float airlight = kAirlightGain * static_cast<float>(n > 0 ? sum / n : 0.0);
  const float inv_step = 1.0f / kStep;
  for (int y = 0; y < height_; ++y) {
    auto* row = linear.ptr<cv::Vec3f>(y);
    const int gy = y / kStep;
    const float fy = static_cast<float>(y - gy * kStep) * inv_step;
    const float* g0 = grid_.data() + static_cast<std::size_t>(gy) * grid_w_;
    const float* g1 = g0 + grid_w_;
    for (int x = 0; x < width_; ++x) {
      const int gx = x / kStep;
      const float fx = static_cast<float>(x - gx * kStep) * inv_step;
      const float a = (1 - fy) * ((1 - fx) * g0[gx] + fx * g0[gx + 1]) + fy * ((1 - fx) * g1[gx] + fx * g1[gx + 1]);
      for (int k = 0; k < 3; ++k) row[x][k] += a * (airlight - row[x][k]);
    }
  }
}

}  // namespace st::sim
