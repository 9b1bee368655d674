// FAST thresholds that follow the light and the tissue's contrast. FAST
// tests intensity differences, and every difference shrinks in a dim frame
// (TrackerConfig::fast_reference_luma) or under a veil of surgical smoke or
// on flat tissue (fast_reference_contrast): the frame's thresholds are
// scaled down by the smaller of the two ratios, so that such a frame gives
// the features of the same scene lit brighter or seen clearly
// (docs/design-notes.md, "Dim light" and "Smoke and flat tissue"). Pure;
// no allocation.
#pragma once

#include "core/image/image.h"
#include "core/image/valid_mask.h"

namespace st {

struct FastThresholdScale {
  float scale = 1.f;          // in (0, 1]
  bool low_contrast = false;  // the contrast, not the luma, set the scale
};

class FastThresholdScaler {
 public:
  // reference_luma <= 16 (video black) or reference_contrast <= 0 turns
  // that rule off.
  void configure(double reference_luma, double reference_contrast);
  // The scale of this frame: for the luma, the median block mean over the
  // valid mask and (if given) the organ mask above video black (16), over
  // the reference's; for the contrast, organ_contrast() over the
  // reference's; the smaller, at most 1. 1 when both are off, or when
  // valid is empty or no pixel can be measured.
  FastThresholdScale measure(GrayView luma, GrayView organ, GrayView valid, const ValidMaskBuilder& valid_mask) const;
  // The organ's texture contrast (8-bit luma units): the median, over a
  // 16-px grid of places inside valid and (if given) organ, of
  // |B(x+4, y) - B(x, y)| + |B(x, y+4) - B(x, y)|, B the mean of the 4x4
  // block at (x, y). Block means keep the sensor noise out (a 16th of its
  // variance), so what is measured is the tissue's texture. The masks may
  // be of another size than luma (they are sampled). -1 when no place
  // qualifies.
  static double organ_contrast(GrayView luma, GrayView organ, GrayView valid);
  // How much of the organ's pixel-level contrast is sensor noise: at the
  // places of organ_contrast(), the median over the places of the mean
  // |I(x+1, y) - I(x, y)| + |I(x, y+1) - I(x, y)| over the 4x4 block, over
  // organ_contrast(). White noise alone gives about 4 (its pixel
  // differences against its 4x4 block means' differences); texture that
  // varies more slowly than a pixel gives 1 or less (a smooth ramp 0.25;
  // measured tissue in docs/design-notes.md, "Noisy tissue").
  // -1 when no place qualifies; where the blocks do not differ at all, 1e3
  // if the pixels do (all noise) and 0 if not (a flat image).
  static double organ_noise_ratio(GrayView luma, GrayView organ, GrayView valid);

 private:
  static void measure_places(GrayView luma, GrayView organ, GrayView valid, double* contrast, double* fine);
  double reference_luma_ = 0, reference_contrast_ = 0;
};

}  // namespace st
