// Surgical smoke: the plume an electrosurgical or ultrasonic instrument
// releases in the insufflated abdomen. The scope's own light scatters back
// from it, so it lays a bright, low-contrast veil over the view, thick in
// billows and thin between them, that drifts and clears within seconds.
// The tracker meets it on real video (it is among the commonest reasons a
// laparoscopic view degrades); the simulator renders it as episodes:
// each one thickens over ~0.4 s (the instrument fires), holds ~1 s and
// clears over ~2.3 s; a new one starts every 5-9 s (at 30 frames/s), so
// clear spells of 1-5 s lie between them.
//
// Model (single scattering, the scope light at the eye): an image pixel
// becomes L (1 - a) + A a, where a = opacity * envelope(frame) *
// density(x, y, frame) is the veil's share and A the airlight, the veil's
// own brightness, taken as 1.3x the frame's mean (linear) brightness: the
// smoke is lit by the same light as the tissue behind it, and reflects a
// little more than the dark liver. density is smooth noise (3 octaves,
// billows about a third of the image wide) that rises and drifts across
// the image from frame to frame. The labels (organ, background,
// instrument) are not changed: the smoke hides the organ's texture, not
// where the organ is.
//
// configure() allocates; apply() allocates nothing.
#pragma once

#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "tools/sim/noise.h"

namespace st::sim {

// Largest opacity accepted (a veil that hides everything shows nothing).
inline constexpr double kMaxSmoke = 0.9;

class SmokeVeil {
 public:
  SmokeVeil() : noise_(1) {}
  // opacity: the veil's share at the thickest point of an episode (0: no
  // smoke, apply() does nothing); width x height: the output image.
  void configure(double opacity, std::uint64_t seed, int width, int height);
  bool enabled() const { return opacity_ > 0.0; }
  // 0..1: how far frame's episode has built up (0 between episodes).
  double envelope(int frame) const;
  // The veil's share at output pixel (x, y) of frame, 0..opacity.
  double share(int frame, double x, double y) const;
  // Blends frame's veil into a linear RGB image (CV_32FC3, the configured size).
  void apply(int frame, cv::Mat& linear);

 private:
  double density(int frame, double x, double y) const;
  double opacity_ = 0.0;
  std::uint64_t seed_ = 1;
  int width_ = 0, height_ = 0;
  Noise3 noise_;
  // The density on a coarse grid (every kStep output pixels), per frame.
  static constexpr int kStep = 8;
  int grid_w_ = 0, grid_h_ = 0;
  std::vector<float> grid_;
};

}  // namespace st::sim
