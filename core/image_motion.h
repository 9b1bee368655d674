// ImageMotion: the 2D shift of the whole view between consecutive frames,
// from small blurred images (the "small blurry image" idea of PTAM's
// relocaliser and rotation predictor): each frame is box-averaged to 1/8
// size and blurred once more; the current one is aligned to the previous
// one by an integer search around a guess and then Gauss-Newton on a
// translation (ESM-style mean gradient), only where both frames are inside
// the valid (field-stop) mask.
//
// Why: motion blur that ruins FAST corners barely changes these images, so
// the shift still comes out when the scope turns fast, where the
// constant-velocity prediction is tens of pixels off. The tracker turns the
// shift into a rotation prior.
//
// configure() allocates; update() allocates nothing. Tracking thread.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image.h"
#include "core/result.h"
#include "core/se3.h"

namespace st {

class ImageMotion {
 public:
  static constexpr int kShrink = 8;  // level-0 pixels per small-image pixel

  Status configure(int width, int height);
  // Forgets the previous frame (the next update() only stores).
  void reset() { have_previous_ = false; }
  // Makes luma the new reference. When there was a previous frame, writes
  // the image motion previous -> current (level-0 pixels: a scene point at
  // x in the previous frame is at x + shift now) starting the search at
  // guess_px, and returns true if the alignment converged on enough valid
  // pixels. valid may be empty (every pixel valid) or coarser than luma
  // (the ValidMaskBuilder mask at 1/downscale): it is sampled in its own
  // pixels.
  bool update(GrayView luma, GrayView valid, const Vec2& guess_px, Vec2* shift_px);

 private:
  void shrink(GrayView luma, GrayView valid, float* image, std::uint8_t* mask);
  double ssd_at(int dx, int dy, int stride, int* n) const;
  double search(int cx, int cy, int radius, int step, int stride, Vec2* t) const;
  bool refine(Vec2* t) const;

  int w_ = 0, h_ = 0;
  bool have_previous_ = false;
  std::vector<float> prev_, cur_, scratch_;
  std::vector<std::uint8_t> prev_mask_, cur_mask_;
  std::vector<std::uint16_t> column_sums_;  // shrink(): one block row, level-0 width
};

}  // namespace st
