// 2D-3D correspondences for pose estimation: borrowed, structure-of-arrays
// views into buffers the caller owns (the tracker's match arrays). Nothing
// here allocates; the views must outlive the solver call that reads them.
#pragma once

#include <cmath>

#include "core/geometry/se3.h"

namespace st {

struct Correspondences {
  const Vec3* p_model = nullptr;        // model-frame points, mm
  const Vec2* px_ideal = nullptr;       // observed ideal (undistorted) pixels
  const double* information = nullptr;  // 1/sigma^2 per observation (1/px^2); nullptr: all 1
  int count = 0;

  double info(int i) const { return information ? information[i] : 1.0; }
  // Finite point and pixel, finite positive information: usable at all.
  bool valid(int i) const {
    const double w = info(i);
    return p_model[i].allFinite() && px_ideal[i].allFinite() && std::isfinite(w) && w > 0;
  }
};

// Information weight 1/sigma^2 of a keypoint detected at pyramid octave
// `octave` when the pixel noise at level 0 is 1 px and every level scales
// by `scale_factor` (sigma = scale_factor^octave, ORB-SLAM's convention).
inline double octave_information(int octave, double scale_factor = 1.2) {
  const double sigma = std::pow(scale_factor, static_cast<double>(octave));
  return 1.0 / (sigma * sigma);
}

// Chi-square quantile, 2 degrees of freedom, 95%: the ORB-SLAM inlier test
// information * |r|^2 < kChi2Inlier2Dof for a 2D reprojection residual r.
inline constexpr double kChi2Inlier2Dof = 5.991;

}  // namespace st
