#include "core/mapping/ba_residuals.h"

#include <cmath>

#include "core/geometry/reprojection.h"

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

// The same residual as reprojection_residual() (core/geometry/reprojection.h), with
// the Jacobians written out by rows: d r / d p_camera has rows
// g0 = a (1, 0, -xn), g1 = b (0, 1, -yn) (a = sqrt_info fx / z, b likewise),
// so the point Jacobian g R and the translation columns g A of the pose
// Jacobian need no full products, and the left Jacobian's block structure
// Jl = [A 0; Q A] (A = Jl of SO3) halves the 2x6 * 6x6 product (the
// innermost kernel of BA: every residual, every evaluation).
bool reprojection_cost(const Pinhole& K, const Vec2& px_ideal, double sqrt_info, double min_depth_mm,
                       const PoseLinearization& pose, const double* f, double* r, double* J_pose, double* J_point) {
  const Mat3& R = pose.T_camera_model.rotation();
  const Vec3 p = R * Vec3(f[0], f[1], f[2]) + pose.T_camera_model.translation();
  if (!(p.z() > min_depth_mm) || !std::isfinite(p.z())) return false;
  const double inv_z = 1.0 / p.z();
  const double xn = p.x() * inv_z, yn = p.y() * inv_z;
  r[0] = sqrt_info * (K.fx * xn + K.cx - px_ideal.x());
  r[1] = sqrt_info * (K.fy * yn + K.cy - px_ideal.y());
  const double a = sqrt_info * K.fx * inv_z, b = sqrt_info * K.fy * inv_z;
  if (J_point) {
    for (int k = 0; k < 3; ++k) {
      J_point[k] = a * (R(0, k) - xn * R(2, k));
      J_point[3 + k] = b * (R(1, k) - yn * R(2, k));
    }
  }
  if (!J_pose) return true;
  // Rotation columns of the left-perturbation Jacobian: g (-hat(p)).
  const double w0[3] = {-a * xn * p.y(), a * (p.z() + xn * p.x()), -a * p.y()};
  const double w1[3] = {-b * (p.z() + yn * p.y()), b * yn * p.x(), b * p.x()};
  if (pose.at_origin) {
    for (int k = 0; k < 3; ++k) {
      J_pose[k] = w0[k];
      J_pose[6 + k] = w1[k];
    }
    J_pose[3] = a, J_pose[4] = 0, J_pose[5] = -a * xn;
    J_pose[9] = 0, J_pose[10] = b, J_pose[11] = -b * yn;
    return true;
  }
  const Mat6& Jl = pose.left_jacobian;  // [A 0; Q A]
  for (int k = 0; k < 3; ++k) {
    // Translation rows of g times the k-th columns of A and Q.
    const double gA0 = a * (Jl(3, 3 + k) - xn * Jl(5, 3 + k)), gA1 = b * (Jl(4, 3 + k) - yn * Jl(5, 3 + k));
    const double gQ0 = a * (Jl(3, k) - xn * Jl(5, k)), gQ1 = b * (Jl(4, k) - yn * Jl(5, k));
    const double wA0 = w0[0] * Jl(0, k) + w0[1] * Jl(1, k) + w0[2] * Jl(2, k);
    const double wA1 = w1[0] * Jl(0, k) + w1[1] * Jl(1, k) + w1[2] * Jl(2, k);
    J_pose[k] = wA0 + gQ0;
    J_pose[6 + k] = wA1 + gQ1;
    J_pose[3 + k] = gA0;
    J_pose[9 + k] = gA1;
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
