// ImageMotion: the 2D motion of the whole view between consecutive frames,
// a shift plus an in-plane rotation (roll about the optical axis), from
// small blurred images (the "small blurry image" idea of PTAM's relocaliser
// and rotation predictor): each frame is box-averaged to 1/8 size and
// blurred once more; the current one is aligned to the previous one by an
// integer search of the shift around a guess, a coarse search of the roll,
// then Gauss-Newton on (shift, roll) (ESM-style mean gradient), only where
// both frames are inside the valid (field-stop) mask.
//
// Why: motion blur that ruins FAST corners barely changes these images, so
// the motion still comes out when the scope turns fast, where the
// constant-velocity prediction is tens of pixels off. The roll matters: a
// scope swung away from the organ (or turned in the surgeon's hand) rolls
// by several degrees a frame, which moves the image edges by tens of pixels
// while its centre barely moves. The tracker turns the motion into a
// rotation prior.
//
// configure() allocates; update() allocates nothing. Tracking thread.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image/image.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

// A scene point at x (level-0 pixels) in the previous frame is at
// centre + R(roll_rad) (x - centre) + shift_px in the current one (R turns
// +x towards +y; centre is given to update()).
struct ViewMotion {
  Vec2 shift_px = Vec2::Zero();
  double roll_rad = 0.0;
};

class ImageMotion {
 public:
  static constexpr int kShrink = 8;  // level-0 pixels per small-image pixel

  Status configure(int width, int height);
  // Forgets the previous frame (the next update() only stores).
  void reset() { have_previous_ = false; }
  // Makes luma the new reference. When there was a previous frame, writes
  // the image motion previous -> current about centre_px (level-0 pixels,
  // see ViewMotion) starting the search at guess, and returns true if the
  // alignment converged on enough valid pixels. valid may be empty (every
  // pixel valid) or coarser than luma (the ValidMaskBuilder mask at
  // 1/downscale): it is sampled in its own pixels. The roll is measured
  // only when it differs from the guess's by more than about 0.75 degrees
  // (otherwise the guess's roll is returned): below that, parallax between
  // near and far parts of the view biases a whole-image fit as much.
  bool update(GrayView luma, GrayView valid, const Vec2& centre_px, const ViewMotion& guess, ViewMotion* motion);

 private:
  void shrink(GrayView luma, GrayView valid, float* image, std::uint8_t* mask);
  double ssd_at(int dx, int dy, int stride, int* n) const;
  double search(int cx, int cy, int radius, int step, int stride, Vec2* t) const;
  double ssd_rolled(const Vec2& t, double roll, const Vec2& centre, int stride) const;
  bool refine_shift(Vec2* t) const;
  bool refine_roll(const Vec2& centre, Vec2* t, double* roll) const;

  int w_ = 0, h_ = 0;
  bool have_previous_ = false;
  std::vector<float> prev_, cur_, scratch_;
  std::vector<std::uint8_t> prev_mask_, cur_mask_;
  std::vector<std::uint16_t> column_sums_;  // shrink(): one block row, level-0 width
};

}  // namespace st
