// ValidMaskBuilder: where in a laparoscope frame features may come from.
// Two things are not tissue features and are removed:
//  - the black field-stop border outside the scope's circular image, whose
//    edge is a perfect static corner line (it moves with the camera, not the
//    organ): found per frame as, for every row, the span between the first
//    and last non-black pixel, eroded by border_margin_px;
//  - saturated specular highlights, which move with the light: pixels at or
//    above max(highlight_min, frame maximum - highlight_band), dilated by
//    highlight_dilate_px.
// The mask is built at 1/downscale of the frame (non-zero = valid) and is
// passed to OrbExtractor::extract, which scales it.
//
// configure() allocates; build() allocates nothing. Tracking thread.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image/image.h"
#include "core/image/mask_morphology.h"
#include "core/base/result.h"

namespace st {

struct ValidMaskConfig {
  int downscale = 2;             // 1, 2 or 4: mask resolution relative to the frame
  int black_offset = 12;         // "black" = below the frame's black level + this
  int black_max = 48;            // black level estimates above this mean: no border in the frame
  int border_margin_px = 8;      // field-stop erosion, frame pixels
  int highlight_min = 200;       // never call anything darker than this a highlight
  int highlight_band = 10;       // highlight = within this of the frame's maximum
  int highlight_dilate_px = 6;   // highlight dilation, frame pixels
};

class ValidMaskBuilder {
 public:
  Status configure(const ValidMaskConfig& config, int width, int height);
  // Builds the mask of frame (width x height as configured). Returns an empty
  // view if the frame size does not match. The view stays valid until the
  // next build().
  GrayView build(GrayView frame);

  GrayView mask() const { return GrayView(mask_.data(), mask_w_, mask_h_, mask_w_); }
  // Median of the last frame's block means (mean luma per mask pixel) over
  // every second mask pixel each way that is set in `within` (mask size)
  // and, when not empty, in `organ` (any size, sampled at the same place).
  // -1 when no such pixel, or `within` is not of the mask's size.
  int median_block_mean(GrayView within, GrayView organ) const;
  int black_level() const { return black_level_; }        // last frame, luma
  int highlight_threshold() const { return highlight_thr_; }  // last frame, luma
  int highlight_pixels() const { return highlight_pixels_; }  // at mask resolution, before dilation

 private:
  void downsample(GrayView frame);
  void downsample2(GrayView frame);
  void field_stop_spans();
  ValidMaskConfig config_;
  int width_ = 0, height_ = 0, mask_w_ = 0, mask_h_ = 0;
  std::vector<std::uint8_t> mean_, max_;        // per mask pixel: block mean and max
  std::vector<std::int32_t> first_, last_;      // per mask row: non-black span
  std::vector<std::int32_t> efirst_, elast_;    // eroded spans
  std::vector<std::uint8_t> sat_, sat_dil_;
  MorphBuffers morph_;
  std::vector<std::uint8_t> mask_;
  int black_level_ = 0, highlight_thr_ = 0, highlight_pixels_ = 0;
};

}  // namespace st
