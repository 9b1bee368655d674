#include "core/ba_residuals.h"

#include <cmath>

#include "core/reprojection.h"

namespace st {

namespace {

// ad(xi) for xi = [omega; v] acting on left perturbations: [hat(omega) 0; hat(v) hat(omega)].
Mat6 se3_ad(const Vec6& xi) {
  Mat6 A = Mat6::Zero();
  const Mat3 W = hat(xi.head<3>());
  A.block<3, 3>(0, 0) = W;
  A.block<3, 3>(3, 3) = W;
  A.block<3, 3>(3, 0) = hat(xi.tail<3>());
  return A;
}

}  // namespace

Mat6 se3_left_jacobian(const Vec6& xi) {
  const Mat6 A = se3_ad(xi);
  Mat6 J = Mat6::Identity(), term = Mat6::Identity();
  // term_n = A^n / (n+1)!; stop when it no longer changes J in double.
  for (int n = 1; n < 64; ++n) {
    term = (A * term) / static_cast<double>(n + 1);
    J += term;
    if (term.cwiseAbs().maxCoeff() <= 1e-17 * J.cwiseAbs().maxCoeff()) break;
  }
  return J;
}

void pose_linearization(const SE3& T0_camera_model, const double* delta, PoseLinearization* out) {
  Vec6 d;
  for (int k = 0; k < 6; ++k) d[k] = delta[k];
  out->at_origin = d.isZero(0.0);
  if (out->at_origin) {
    out->T_camera_model = T0_camera_model;
    out->left_jacobian.setIdentity();
    return;
  }
  out->T_camera_model = SE3::exp(d) * T0_camera_model;
  out->left_jacobian = se3_left_jacobian(d);
}

bool reprojection_cost(const Pinhole& K, const Vec2& px_ideal, double sqrt_info, double min_depth_mm,
                       const SE3& T0_camera_model, const double* delta, const double* f, double* r, double* J_pose,
                       double* J_point) {
  PoseLinearization pose;
  pose_linearization(T0_camera_model, delta, &pose);
  return reprojection_cost(K, px_ideal, sqrt_info, min_depth_mm, pose, f, r, J_pose, J_point);
}

bool reprojection_cost(const Pinhole& K, const Vec2& px_ideal, double sqrt_info, double min_depth_mm,
                       const PoseLinearization& pose, const double* f, double* r, double* J_pose, double* J_point) {
  const SE3& T = pose.T_camera_model;
  const Vec3 p_model(f[0], f[1], f[2]);
  Vec2 e;
  Mat26 J;
  if (!reprojection_residual(K, T, p_model, px_ideal, min_depth_mm, &e, (J_pose || J_point) ? &J : nullptr))
    return false;
  r[0] = sqrt_info * e[0];
  r[1] = sqrt_info * e[1];
  if (J_pose) {
    Eigen::Map<Mat26r> Jp(J_pose);
    if (pose.at_origin)
      Jp = sqrt_info * J;
    else
      Jp.noalias() = (sqrt_info * J) * pose.left_jacobian;
  }
  if (J_point) {
    // d r / d f = d project / d p_camera * R; the v columns of the left
    // Jacobian are exactly d project / d p_camera.
    Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> Jf(J_point);
    Jf.noalias() = (sqrt_info * J.rightCols<3>()) * T.rotation();
  }
  return true;
}

bool shape_cost(const ClosestPointIndex& surface, double sqrt_w, const double* f, double* r, double* J) {
  const Vec3 p(f[0], f[1], f[2]);
  SurfacePoint s;
  if (!surface.closest(p, &s)) return false;
  for (int k = 0; k < 3; ++k) r[k] = sqrt_w * (p[k] - s.p_model[k]);
  if (J) {
    Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> Js(J);
    Js = sqrt_w * s.residual_jacobian();
  }
  return true;
}

bool shape_plane(const ClosestPointIndex& surface, const Vec3& f0, ShapePlane* plane) {
  SurfacePoint s;
  if (!surface.closest(f0, &s)) return false;
  plane->foot = s.p_model;
  plane->normal = s.face_normal;
  if (s.feature != SurfaceFeature::kFace && s.distance_mm > 1e-9) {
    plane->normal = (f0 - s.p_model) / s.distance_mm;
    if (plane->normal.dot(s.face_normal) < 0) plane->normal = -plane->normal;  // keep the outward sense
  }
  return true;
}

void plane_cost(const ShapePlane& plane, double sqrt_w, const double* f, double* r, double* J) {
  const Vec3 d(f[0] - plane.foot.x(), f[1] - plane.foot.y(), f[2] - plane.foot.z());
  r[0] = sqrt_w * plane.normal.dot(d);
  r[1] = 0.0;
  if (J) {
    for (int k = 0; k < 3; ++k) {
      J[k] = sqrt_w * plane.normal[k];
      J[3 + k] = 0.0;
    }
  }
}

}  // namespace st
