// Reprojection residual of a model point in an ideal pinhole camera and its
// Jacobian w.r.t. a left perturbation of the pose, T <- exp(delta) * T with
// delta = [omega (rad); v (mm)] (se3.h). Header-only: it is the innermost
// kernel of the pose LM and of bundle adjustment. No allocation.
#pragma once

#include <cmath>

#include "core/geometry/camera.h"
#include "core/geometry/se3.h"

namespace st {

using Mat26 = Eigen::Matrix<double, 2, 6>;

// A pinhole the residual can use: finite, positive focal lengths.
inline bool pinhole_is_usable(const Pinhole& K) {
  return std::isfinite(K.fx) && std::isfinite(K.fy) && std::isfinite(K.cx) && std::isfinite(K.cy) &&
         K.fx > 0 && K.fy > 0;
}

// r = project(T_camera_model * p_model) - px_observed, in pixels. Returns
// false (and leaves r, J untouched) when the point is not in front of the
// camera: depth below min_depth_mm or not finite.
// With p = T * p_model = (x, y, z), xn = x/z, yn = y/z, the derivative of
// exp(delta) * p is [-hat(p) | I], and d(project)/dp is
// [fx/z 0 -fx x/z^2; 0 fy/z -fy y/z^2]; their product is written out below.
inline bool reprojection_residual(const Pinhole& K, const SE3& T_camera_model, const Vec3& p_model,
                                  const Vec2& px_observed, double min_depth_mm, Vec2* r, Mat26* J) {
  const Vec3 p = T_camera_model.rotation() * p_model + T_camera_model.translation();
  if (!(p.z() > min_depth_mm) || !std::isfinite(p.z())) return false;
  const double inv_z = 1.0 / p.z();
  const double xn = p.x() * inv_z, yn = p.y() * inv_z;
  (*r)[0] = K.fx * xn + K.cx - px_observed.x();
  (*r)[1] = K.fy * yn + K.cy - px_observed.y();
  if (J) {
    (*J) << -K.fx * xn * yn, K.fx * (1.0 + xn * xn), -K.fx * yn, K.fx * inv_z, 0.0,
        -K.fx * xn * inv_z,  //
        -K.fy * (1.0 + yn * yn), K.fy * xn * yn, K.fy * xn, 0.0, K.fy * inv_z, -K.fy * yn * inv_z;
  }
  return true;
}

}  // namespace st
