// Camera model: ideal pinhole + OpenCV radial-tangential distortion
// (k1 k2 p1 p2 [k3 [k4 k5 k6]]; 8 coefficients is OpenCV's rational form).
// Pixel centres are at integer coordinates (OpenCV convention). Keypoints
// are undistorted once; everything downstream uses the ideal Pinhole.
#pragma once

#include <array>

#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

struct Pinhole {
  double fx = 0, fy = 0, cx = 0, cy = 0;
  int width = 0, height = 0;

  Vec2 project(const Vec3& p_camera) const {
    return {fx * p_camera.x() / p_camera.z() + cx, fy * p_camera.y() / p_camera.z() + cy};
  }
  // The point at depth z (mm along the optical axis) seen at pixel px.
  Vec3 unproject(const Vec2& px, double z) const {
    return {(px.x() - cx) / fx * z, (px.y() - cy) / fy * z, z};
  }
  // The same camera for an image scaled by s (s = 0.5: half size). With
  // pixel centres at integers, x' = (x + 0.5) * s - 0.5.
  Pinhole scaled(double s, int new_width, int new_height) const { return scaled(s, s, new_width, new_height); }
  // Scaled by sx across and sy down (an image resampled to another aspect's rounding).
  Pinhole scaled(double sx, double sy, int new_width, int new_height) const {
    return {fx * sx, fy * sy, (cx + 0.5) * sx - 0.5, (cy + 0.5) * sy - 0.5, new_width, new_height};
  }
  bool in_image(const Vec2& px, double border = 0.0) const {
    return px.x() >= border && px.y() >= border && px.x() <= width - 1 - border &&
           px.y() <= height - 1 - border;
  }
  // Horizontal and vertical field of view in degrees.
  double hfov_deg() const;
  double vfov_deg() const;
};

struct Distortion {
  std::array<double, 8> k{};  // k1 k2 p1 p2 k3 k4 k5 k6
  int count = 0;              // 0, 4, 5 or 8

  bool is_zero() const;
  // Normalised ideal coordinates -> normalised distorted coordinates.
  Vec2 distort(const Vec2& xn) const;
  // Same, with the 2x2 Jacobian d(distorted)/d(ideal).
  Vec2 distort(const Vec2& xn, Eigen::Matrix2d* J) const;
};

struct UndistortOptions {
  int max_iterations = 30;
  double tolerance_px = 1e-9;  // convergence: reprojection residual in pixels
};

class CameraModel {
 public:
  CameraModel() = default;
  CameraModel(const Pinhole& K, const Distortion& d) : K_(K), d_(d) {}

  // fx, fy > 0 and finite, at most kMaxFocalPerSide times the image's
  // larger side (a field of view over 0.6 deg) and within kMaxFocalAspect
  // of each other, principal point inside the image, distortion count
  // 0/4/5/8 with finite values, image size positive and below caps, and a
  // distortion that maps the image one to one (it does not fold over
  // anywhere between the principal point and the image's edge).
  static Status validate(const Pinhole& K, const Distortion& d);
  static constexpr double kMaxFocalPerSide = 100.0;
  static constexpr double kMaxFocalAspect = 4.0;

  const Pinhole& pinhole() const { return K_; }
  const Distortion& distortion() const { return d_; }

  // Camera-frame point -> distorted pixel. z must be > 0.
  Vec2 project(const Vec3& p_camera) const;
  // Ideal (undistorted) pixel -> distorted pixel.
  Vec2 distort_pixel(const Vec2& ideal_px) const;
  // Distorted pixel -> ideal pixel by Newton iteration on the distortion
  // map. Returns false if it did not converge (then *ideal_px is the best
  // estimate): far outside the image, strong distortion folds over.
  bool undistort_pixel(const Vec2& distorted_px, Vec2* ideal_px,
                       const UndistortOptions& opt = {}) const;

 private:
  Pinhole K_;
  Distortion d_;
};

}  // namespace st
