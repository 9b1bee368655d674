#include "tools/sim/breathing.h"

#include <algorithm>
#include <cmath>

#include "tools/sim/mesh_ops.h"

namespace st::sim {

BreathingField::BreathingField(const Mesh& rest, double amplitude_mm) : amplitude_mm_(amplitude_mm) {
  if (!(amplitude_mm > 0.0) || rest.vertex_count() == 0) {
    amplitude_mm_ = 0.0;
    return;
  }
  const Box box = bounding_box(rest);
  centre_ = box.centre();
  inv_half_ = (0.5 * box.size()).cwiseMax(1e-6).cwiseInverse();
  double largest = 0.0;
  for (int i = 0; i < rest.vertex_count(); ++i) largest = std::max(largest, shape(rest.vertex(i)).norm());
  scale_ = largest > 0.0 ? amplitude_mm / largest : 0.0;
  fit_rigid(rest);
}

// Least squares over the vertices: offset(p) ~ t + w x (p - c), c their
// centroid. With r = p - c the two decouple (sum r = 0): t is the mean
// offset, and w solves sum (|r|^2 I - r r^T) w = sum r x (offset - t).
void BreathingField::fit_rigid(const Mesh& rest) {
  const int n = rest.vertex_count();
  Vec3 c = Vec3::Zero(), t = Vec3::Zero();
  for (int i = 0; i < n; ++i) {
    c += rest.vertex(i);
    t += offset(rest.vertex(i));
  }
  c /= n;
  t /= n;
  Mat3 A = Mat3::Zero();
  Vec3 b = Vec3::Zero();
  for (int i = 0; i < n; ++i) {
    const Vec3 r = rest.vertex(i) - c;
    A += r.squaredNorm() * Mat3::Identity() - r * r.transpose();
    b += r.cross(offset(rest.vertex(i)) - t);
  }
  centroid_ = c;
  fit_translation_ = t;
  fit_rotation_ = A.ldlt().solve(b);
  if (!fit_rotation_.allFinite()) fit_rotation_.setZero();  // a degenerate (flat, one-point) organ
}

SE3 BreathingField::rigid_motion(double phase) const {
  if (!enabled()) return SE3::Identity();
  // p -> c + phase t + R (p - c), R = exp(phase w).
  const Mat3 R = so3_exp(phase * fit_rotation_);
  return SE3(R, centroid_ + phase * fit_translation_ - R * centroid_);
}

Vec3 BreathingField::bend(const Vec3& p_rest) const {
  if (!enabled()) return Vec3::Zero();
  return offset(p_rest) - fit_translation_ - fit_rotation_.cross(p_rest - centroid_);
}

double BreathingField::phase(double t_s) { return 0.5 - 0.5 * std::cos(2.0 * M_PI * t_s / kBreathingPeriodS); }

// In box-normalised coordinates q (-1..1 per axis): a push along the model
// z axis (the CT's cranio-caudal axis) that is strongest at one end and
// falls off quadratically across the organ (the shape bends), plus a
// smaller sideways shear that grows along z. Smooth everywhere.
Vec3 BreathingField::shape(const Vec3& p) const {
  const Vec3 q = (p - centre_).cwiseProduct(inv_half_);
  const double push = 1.0 + 0.35 * q.x() - 0.3 * (q.x() * q.x() + q.y() * q.y()) + 0.2 * q.z();
  return Vec3(0.3 * q.z() + 0.1 * std::sin(1.5 * q.y()), 0.2 * std::sin(1.2 * q.x()) * q.z(), push);
}

Vec3 BreathingField::offset(const Vec3& p_rest) const {
  if (!enabled()) return Vec3::Zero();
  return scale_ * shape(p_rest);
}

void BreathingField::displace(const Mesh& rest, double phase_share, Mesh* out) const {
  for (int i = 0; i < rest.vertex_count(); ++i) {
    const Vec3 p = rest.vertex(i) + phase_share * offset(rest.vertex(i));
    out->x[i] = static_cast<float>(p.x());
    out->y[i] = static_cast<float>(p.y());
    out->z[i] = static_cast<float>(p.z());
  }
}

}  // namespace st::sim
