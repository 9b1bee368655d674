// Rigid transforms on fixed-size Eigen types.
// Naming: T_a_b maps points of frame b into frame a: x_a = T_a_b * x_b.
// Tangent vectors are Vec6 = [omega (rotation, rad); v (translation, mm)] and
// updates are applied on the left: T <- exp(delta) * T.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace st {

using Vec2 = Eigen::Vector2d;
using Vec3 = Eigen::Vector3d;
using Vec4 = Eigen::Vector4d;
using Vec6 = Eigen::Matrix<double, 6, 1>;
using Mat3 = Eigen::Matrix3d;
using Mat4 = Eigen::Matrix4d;
using Mat6 = Eigen::Matrix<double, 6, 6>;
using Vec2f = Eigen::Vector2f;
using Vec3f = Eigen::Vector3f;
using Quat = Eigen::Quaterniond;

Mat3 hat(const Vec3& w);
Mat3 so3_exp(const Vec3& omega);
Vec3 so3_log(const Mat3& R);  // R must be a rotation; |result| in [0, pi]

class SE3 {
 public:
  SE3() : R_(Mat3::Identity()), t_(Vec3::Zero()) {}
  SE3(const Mat3& R, const Vec3& t) : R_(R), t_(t) {}
  SE3(const Quat& q, const Vec3& t) : R_(q.normalized().toRotationMatrix()), t_(t) {}

  static SE3 Identity() { return SE3(); }
  static SE3 exp(const Vec6& xi);
  Vec6 log() const;

  const Mat3& rotation() const { return R_; }
  const Vec3& translation() const { return t_; }
  Mat3& rotation() { return R_; }
  Vec3& translation() { return t_; }
  Quat quaternion() const { return Quat(R_).normalized(); }
  Mat4 matrix() const;

  SE3 inverse() const { return SE3(R_.transpose(), -(R_.transpose() * t_)); }
  SE3 operator*(const SE3& o) const { return SE3(R_ * o.R_, R_ * o.t_ + t_); }
  Vec3 operator*(const Vec3& p) const { return R_ * p + t_; }
  Vec3f operator*(const Vec3f& p) const { return (R_ * p.cast<double>() + t_).cast<float>(); }

  bool all_finite() const { return R_.allFinite() && t_.allFinite(); }

 private:
  Mat3 R_;
  Vec3 t_;
};

// Nearest rotation (SVD, det +1) to a matrix that should be a rotation.
Mat3 orthonormalize(const Mat3& M);
// Angle of R_a^T R_b in degrees.
double rotation_angle_deg(const Mat3& R_a, const Mat3& R_b);
// Angle of the relative rotation and distance of the relative translation.
struct PoseDelta {
  double angle_deg;
  double distance_mm;
};
PoseDelta pose_delta(const SE3& a, const SE3& b);

}  // namespace st
