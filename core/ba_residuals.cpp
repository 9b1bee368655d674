#include "core/ba_residuals.h"

#include <cmath>

#include "core/ba_job.h"
#include "core/reprojection.h"

namespace st {

namespace {

// d q' / d omega at omega = 0 for q' = q(omega) * q (4 x 3, rows x y z w):
// 0.5 * [w I - hat(v); -v^T]. Its columns are orthogonal with norm 0.5.
Eigen::Matrix<double, 4, 3> quaternion_left_jacobian(const double* q) {
  const Vec3 v(q[0], q[1], q[2]);
  const double w = q[3];
  Eigen::Matrix<double, 4, 3> A;
  A.topRows<3>() = 0.5 * (w * Mat3::Identity() - hat(v));
  A.row(3) = -0.5 * v.transpose();
  return A;
}

}  // namespace

bool se3_plus(const double* x, const double* delta, double* x_plus_delta) {
  Vec6 d;
  for (int k = 0; k < 6; ++k) d[k] = delta[k];
  const SE3 T = SE3::exp(d) * pose_from_params(x);
  if (!T.all_finite()) return false;
  pose_to_params(T, x_plus_delta);
  // Keep the hemisphere of x: a sign flip is the same rotation but would
  // make finite differences of the ambient vector jump.
  const double dot = x[0] * x_plus_delta[0] + x[1] * x_plus_delta[1] + x[2] * x_plus_delta[2] + x[3] * x_plus_delta[3];
  if (dot < 0)
    for (int k = 0; k < 4; ++k) x_plus_delta[k] = -x_plus_delta[k];
  return true;
}

bool se3_minus(const double* y, const double* x, double* y_minus_x) {
  const Vec6 d = (pose_from_params(y) * pose_from_params(x).inverse()).log();
  for (int k = 0; k < 6; ++k) y_minus_x[k] = d[k];
  return d.allFinite();
}

Mat76 se3_plus_jacobian(const double* x) {
  // q' = q(omega) q; t' = exp(omega) t + v: dt'/domega = -hat(t), dt'/dv = I.
  Mat76 J = Mat76::Zero();
  J.block<4, 3>(0, 0) = quaternion_left_jacobian(x);
  J.block<3, 3>(4, 0) = -hat(Vec3(x[4], x[5], x[6]));
  J.block<3, 3>(4, 3) = Mat3::Identity();
  return J;
}

Mat67 se3_minus_jacobian(const double* x) {
  // omega = 4 A^T dq (A^T A = I / 4 for a unit quaternion), v = dt + hat(t) omega.
  const Eigen::Matrix<double, 3, 4> Ainv = 4.0 * quaternion_left_jacobian(x).transpose();
  Mat67 M = Mat67::Zero();
  M.block<3, 4>(0, 0) = Ainv;
  M.block<3, 4>(3, 0) = hat(Vec3(x[4], x[5], x[6])) * Ainv;
  M.block<3, 3>(3, 4) = Mat3::Identity();
  return M;
}

void pose_linearization(const double* x, PoseLinearization* out) {
  out->T_camera_model = pose_from_params(x);
  out->minus_jacobian = se3_minus_jacobian(x);
}

bool reprojection_cost(const Pinhole& K, const Vec2& px_ideal, double sqrt_info, double min_depth_mm,
                       const double* x, const double* f, double* r, double* J_pose, double* J_point) {
  PoseLinearization pose;
  pose_linearization(x, &pose);
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
    Eigen::Map<Eigen::Matrix<double, 2, 7, Eigen::RowMajor>> Jp(J_pose);
    Jp.noalias() = (sqrt_info * J) * pose.minus_jacobian;
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
