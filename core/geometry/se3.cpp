#include "core/geometry/se3.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>

namespace st {

Mat3 hat(const Vec3& w) {
  Mat3 m;
  m << 0, -w.z(), w.y(), w.z(), 0, -w.x(), -w.y(), w.x(), 0;
  return m;
}

Mat3 so3_exp(const Vec3& omega) {
  const double theta2 = omega.squaredNorm();
  const Mat3 W = hat(omega);
  if (theta2 < 1e-16) return Mat3::Identity() + W + 0.5 * W * W;
  const double theta = std::sqrt(theta2);
  return Mat3::Identity() + (std::sin(theta) / theta) * W +
         ((1.0 - std::cos(theta)) / theta2) * W * W;
}

Vec3 so3_log(const Mat3& R) {
  // Eigen's AngleAxis handles the theta ~ pi case through the quaternion.
  const Eigen::AngleAxisd aa(Quat(R).normalized());
  double angle = aa.angle();
  Vec3 axis = aa.axis();
  if (angle > M_PI) {
    angle = 2.0 * M_PI - angle;
    axis = -axis;
  }
  return axis * angle;
}

// Left Jacobian of SO(3): t = V(omega) * v.
static Mat3 so3_left_jacobian(const Vec3& omega) {
  const double theta2 = omega.squaredNorm();
  const Mat3 W = hat(omega);
  if (theta2 < 1e-12) return Mat3::Identity() + 0.5 * W + (1.0 / 6.0) * W * W;
  const double theta = std::sqrt(theta2);
  return Mat3::Identity() + ((1.0 - std::cos(theta)) / theta2) * W +
         ((theta - std::sin(theta)) / (theta2 * theta)) * W * W;
}

SE3 SE3::exp(const Vec6& xi) {
  const Vec3 omega = xi.head<3>();
  return SE3(so3_exp(omega), so3_left_jacobian(omega) * xi.tail<3>());
}

Vec6 SE3::log() const {
  const Vec3 omega = so3_log(R_);
  Vec6 xi;
  xi.head<3>() = omega;
  xi.tail<3>() = so3_left_jacobian(omega).inverse() * t_;
  return xi;
}

Mat4 SE3::matrix() const {
  Mat4 m = Mat4::Identity();
  m.topLeftCorner<3, 3>() = R_;
  m.topRightCorner<3, 1>() = t_;
  return m;
}

Mat3 orthonormalize(const Mat3& M) {
  Eigen::JacobiSVD<Mat3> svd(M, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Mat3 D = Mat3::Identity();
  D(2, 2) = (svd.matrixU() * svd.matrixV().transpose()).determinant() < 0 ? -1.0 : 1.0;
  return svd.matrixU() * D * svd.matrixV().transpose();
}

double rotation_angle_deg(const Mat3& R_a, const Mat3& R_b) {
  // Through the log rather than acos(trace): accurate for tiny angles too.
  return so3_log(R_a.transpose() * R_b).norm() * 180.0 / M_PI;
}

PoseDelta pose_delta(const SE3& a, const SE3& b) {
  const SE3 d = a.inverse() * b;
  return {rotation_angle_deg(Mat3::Identity(), d.rotation()), d.translation().norm()};
}

}  // namespace st
