// Organ texture from a real photograph: the fine structure of tissue that
// nobody designed (`scopetrack-sim --texture FILE.y4m`), instead of the
// procedural speckle, lobule spots and vessels calibrated on it.
//
// The photo's sensor noise is smoothed away (kDenoiseSigmaPx) and its own
// lighting taken out: highlights (and their glow) are filled from their
// surroundings, and each pixel is
// divided by a wide Gaussian mean (sigma kIlluminationSigmaPx), which
// leaves the relative albedo variation (clamped to kMinRatio..kMaxRatio).
// Where the photo has a scope's black field stop, only the largest square
// inside the lit disc is used. The renderer's light, shading and specular
// highlights then act on it like on any albedo.
//
// Mapped onto the organ in its own frame (mm), so it sticks to the surface:
// triplanar projection (the three axis-aligned planar maps, blended by the
// surface normal's components to the 4th power), px_per_mm photo pixels per
// mm, mirrored at the crop's edges so that tiles meet without a seam.
// Tool code: allocates freely.
#pragma once

#include <filesystem>
#include <memory>

#include <opencv2/core.hpp>

#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st::sim {

class PhotoTexture {
 public:
  static constexpr double kIlluminationSigmaPx = 40.0;
  static constexpr float kMinRatio = 0.3f, kMaxRatio = 1.7f;
  // Highlights: luma at or above kHighlightLevel and kHighlightMarginPx
  // around (their glow), filled by a Gaussian of kFillSigmaPx.
  static constexpr int kHighlightLevel = 200, kHighlightMarginPx = 8;
  static constexpr double kFillSigmaPx = 16.0, kDenoiseSigmaPx = 1.5;
  static constexpr double kDefaultPxPerMm = 4.0;

  // The first frame of a Y4M file (luma only). Errors: unreadable or not
  // Y4M, no frame, or a lit region under 64 x 64 pixels.
  static Result<std::shared_ptr<const PhotoTexture>> load(const std::filesystem::path& y4m,
                                                         double px_per_mm = kDefaultPxPerMm);
  // From an 8-bit luma image (what load() reads).
  static Result<std::shared_ptr<const PhotoTexture>> from_luma(const cv::Mat& luma, double px_per_mm);

  // Relative albedo (kMinRatio..kMaxRatio, 1 on average) at a model point
  // with the given (unit or not) surface normal.
  float ratio_at(const Vec3f& p_mm, const Vec3f& normal) const;
  // The crop of the photo in use (its pixels) and the ratio image over it.
  const cv::Rect& crop() const { return crop_; }
  const cv::Mat& ratio() const { return ratio_; }

 private:
  float sample(float u_px, float v_px) const;
  cv::Rect crop_;
  cv::Mat ratio_;  // CV_32F, crop size
  double px_per_mm_ = kDefaultPxPerMm;
};

}  // namespace st::sim
