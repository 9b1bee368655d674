#include "core/geometry/camera.h"

#include <algorithm>
#include <cmath>

#include "core/base/capacity.h"

namespace st {

double Pinhole::hfov_deg() const {
  return (std::atan((cx + 0.5) / fx) + std::atan((width - 0.5 - cx) / fx)) * 180.0 / M_PI;
}
double Pinhole::vfov_deg() const {
  return (std::atan((cy + 0.5) / fy) + std::atan((height - 0.5 - cy) / fy)) * 180.0 / M_PI;
}

bool Distortion::is_zero() const {
  for (int i = 0; i < count; ++i)
    if (k[i] != 0.0) return false;
  return true;
}

Vec2 Distortion::distort(const Vec2& xn) const { return distort(xn, nullptr); }

Vec2 Distortion::distort(const Vec2& xn, Eigen::Matrix2d* J) const {
  const double k1 = k[0], k2 = k[1], p1 = k[2], p2 = k[3];
  const double k3 = count >= 5 ? k[4] : 0.0;
  const double k4 = count == 8 ? k[5] : 0.0, k5 = count == 8 ? k[6] : 0.0,
               k6 = count == 8 ? k[7] : 0.0;
  const double x = xn.x(), y = xn.y();
  const double r2 = x * x + y * y, r4 = r2 * r2, r6 = r4 * r2;
  const double num = 1.0 + k1 * r2 + k2 * r4 + k3 * r6;
  const double den = 1.0 + k4 * r2 + k5 * r4 + k6 * r6;
  const double radial = num / den;
  const Vec2 out(x * radial + 2.0 * p1 * x * y + p2 * (r2 + 2.0 * x * x),
                 y * radial + p1 * (r2 + 2.0 * y * y) + 2.0 * p2 * x * y);
  if (J) {
    const double dnum_dr2 = k1 + 2.0 * k2 * r2 + 3.0 * k3 * r4;
    const double dden_dr2 = k4 + 2.0 * k5 * r2 + 3.0 * k6 * r4;
    const double dradial_dr2 = (dnum_dr2 * den - num * dden_dr2) / (den * den);
    const double drx = dradial_dr2 * 2.0 * x, dry = dradial_dr2 * 2.0 * y;
    (*J)(0, 0) = radial + x * drx + 2.0 * p1 * y + p2 * 6.0 * x;
    (*J)(0, 1) = x * dry + 2.0 * p1 * x + p2 * 2.0 * y;
    (*J)(1, 0) = y * drx + p1 * 2.0 * x + 2.0 * p2 * y;
    (*J)(1, 1) = radial + y * dry + p1 * 6.0 * y + 2.0 * p2 * x;
  }
  return out;
}

namespace {

// The lens model must map the ideal image onto the captured one without
// folding over: where it folds, a pixel has two ideal positions (or none)
// and undistorted keypoints land anywhere, so poses come out confidently
// wrong. Rays are walked out from the principal point in the ideal
// normalised plane, one pixel at a time, until the distorted point has
// left the image: along the way the map must keep its orientation
// (det J > 0) and carry the point outwards (J u . u > 0). A ray that never
// leaves the image within a 170-degree field of view folds as well.
// Each ray steps one ideal pixel along its own direction, and at most
// kMaxSteps times: fuzz_sequence_yaml found fy = 6e13 px with a 1/max(fx, fy)
// step along the x axis, ~1e14 steps, a hang. A step coarser than a pixel
// needs a ray of more than kMaxSteps pixels to 170 degrees, i.e. a focal
// length above ~1700 px along it; the image's edge comes long before.
Status check_no_fold(const Pinhole& K, const Distortion& d) {
  if (d.count == 0 || d.is_zero()) return Status::Ok();
  constexpr int kRays = 72;
  constexpr double kMaxRadius = 11.4;  // tan(85 deg): a 170-degree field of view
  constexpr double kMarginPx = 2.0;
  constexpr int kMaxSteps = 20000;
  for (int i = 0; i < kRays; ++i) {
    const double angle = 2.0 * M_PI * i / kRays;
    const Vec2 u(std::cos(angle), std::sin(angle));
    const double step = std::max(1.0 / std::hypot(K.fx * u.x(), K.fy * u.y()), kMaxRadius / kMaxSteps);
    bool left_image = false;
    for (double r = 0.0; r <= kMaxRadius && !left_image; r += step) {
      Eigen::Matrix2d J;
      const Vec2 xd = d.distort(r * u, &J);
      const Vec2 px(K.fx * xd.x() + K.cx, K.fy * xd.y() + K.cy);
      if (!px.allFinite() || !J.allFinite() || !(J.determinant() > 0.0) ||
          !((J * u).dot(u) > 0.0)) {
        const double from_centre_px = r * std::max(K.fx, K.fy);
        return make_error("the distortion coefficients fold the image over " +
                          std::to_string(static_cast<int>(from_centre_px)) +
                          " px from the principal point (direction " +
                          std::to_string(static_cast<int>(angle * 180.0 / M_PI)) +
                          " deg): not a lens. Check the order (OpenCV: k1 k2 p1 p2 k3 [k4 k5 "
                          "k6]) and that the calibration belongs to this image size");
      }
      left_image = px.x() < -kMarginPx || px.y() < -kMarginPx ||
                   px.x() > K.width - 1 + kMarginPx || px.y() > K.height - 1 + kMarginPx;
    }
    if (!left_image)
      return make_error("the distortion coefficients never reach the image's edge within a "
                        "170-degree field of view (direction " +
                        std::to_string(static_cast<int>(angle * 180.0 / M_PI)) +
                        " deg): not a lens this image could come from");
  }
  return Status::Ok();
}

}  // namespace

Status CameraModel::validate(const Pinhole& K, const Distortion& d) {
  if (K.width <= 0 || K.height <= 0 || K.width > kMaxImageWidth || K.height > kMaxImageHeight)
    return make_error("image size " + std::to_string(K.width) + "x" + std::to_string(K.height) +
                      " is outside 1x1.." + std::to_string(kMaxImageWidth) + "x" +
                      std::to_string(kMaxImageHeight));
  if (!std::isfinite(K.fx) || !std::isfinite(K.fy) || K.fx <= 0 || K.fy <= 0)
    return make_error("focal lengths must be finite and positive (fx=" + std::to_string(K.fx) +
                      ", fy=" + std::to_string(K.fy) + ")");
  // No scope sees less than a degree, and no sensor's pixels are four times
  // taller than wide: such numbers are a typo or another camera's file.
  const double side = std::max(K.width, K.height);
  if (K.fx > kMaxFocalPerSide * side || K.fy > kMaxFocalPerSide * side)
    return make_error("focal lengths fx=" + std::to_string(K.fx) + ", fy=" + std::to_string(K.fy) +
                      " px give a field of view under 0.6 deg on a " + std::to_string(K.width) + "x" +
                      std::to_string(K.height) + " image: not a laparoscope's calibration");
  if (K.fy > kMaxFocalAspect * K.fx || K.fx > kMaxFocalAspect * K.fy)
    return make_error("focal lengths fx=" + std::to_string(K.fx) + ", fy=" + std::to_string(K.fy) +
                      " differ by more than " + std::to_string(static_cast<int>(kMaxFocalAspect)) +
                      "x: not one camera's pixels");
  if (!std::isfinite(K.cx) || !std::isfinite(K.cy) || K.cx < 0 || K.cy < 0 ||
      K.cx > K.width - 1 || K.cy > K.height - 1)
    return make_error("principal point (" + std::to_string(K.cx) + ", " + std::to_string(K.cy) +
                      ") is not inside the " + std::to_string(K.width) + "x" +
                      std::to_string(K.height) + " image");
  if (d.count != 0 && d.count != 4 && d.count != 5 && d.count != 8)
    return make_error("distortion must have 4, 5 or 8 coefficients, got " +
                      std::to_string(d.count));
  for (int i = 0; i < d.count; ++i)
    if (!std::isfinite(d.k[i])) return make_error("distortion coefficient " + std::to_string(i) +
                                                  " is not finite");
  return check_no_fold(K, d);
}

Vec2 CameraModel::project(const Vec3& p_camera) const {
  const Vec2 xn(p_camera.x() / p_camera.z(), p_camera.y() / p_camera.z());
  const Vec2 xd = d_.count ? d_.distort(xn) : xn;
  return {K_.fx * xd.x() + K_.cx, K_.fy * xd.y() + K_.cy};
}

Vec2 CameraModel::distort_pixel(const Vec2& ideal_px) const {
  if (d_.count == 0) return ideal_px;
  const Vec2 xn((ideal_px.x() - K_.cx) / K_.fx, (ideal_px.y() - K_.cy) / K_.fy);
  const Vec2 xd = d_.distort(xn);
  return {K_.fx * xd.x() + K_.cx, K_.fy * xd.y() + K_.cy};
}

bool CameraModel::undistort_pixel(const Vec2& distorted_px, Vec2* ideal_px,
                                  const UndistortOptions& opt) const {
  const Vec2 target((distorted_px.x() - K_.cx) / K_.fx, (distorted_px.y() - K_.cy) / K_.fy);
  if (d_.count == 0 || d_.is_zero()) {
    *ideal_px = distorted_px;
    return true;
  }
  // Newton on f(x) = distort(x) - target, started at the target.
  Vec2 x = target;
  const double tol_n = opt.tolerance_px / std::max(K_.fx, K_.fy);
  for (int it = 0; it < opt.max_iterations; ++it) {
    Eigen::Matrix2d J;
    const Vec2 r = d_.distort(x, &J) - target;
    if (!r.allFinite()) break;
    if (r.norm() < tol_n) {
      *ideal_px = Vec2(K_.fx * x.x() + K_.cx, K_.fy * x.y() + K_.cy);
      return true;
    }
    const double det = J.determinant();
    if (!(std::abs(det) > 1e-12)) break;  // fold of the distortion map
    x -= J.inverse() * r;
  }
  *ideal_px = Vec2(K_.fx * x.x() + K_.cx, K_.fy * x.y() + K_.cy);
  Eigen::Matrix2d J;
  const Vec2 r = d_.distort(x, &J) - target;
  return r.allFinite() && r.norm() < tol_n && J.determinant() > 0;
}

}  // namespace st
