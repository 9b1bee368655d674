// The residuals of bundle adjustment (paper Eq. 4) and the pose manifold
// they live on, as plain functions: the Schur solver evaluates them, and
// the Ceres form (core/mapping_ceres/ceres_form.cpp) wraps them in Ceres
// cost functions (kept out of this header: Ceres' headers bring glog's
// CHECK macros, which would clash with users' own, e.g. doctest's).
//
// Pose block: a 6-vector delta = [omega (rad); v (mm)] around the pose T0
// handed over in the job (T_camera_model, core/mapping/ba_job.h), the pose being
// exp(delta) * T0 (left update, as everywhere in the project: se3.h). A plain
// Euclidean block, so Ceres needs no manifold: no 2x7 ambient Jacobian per
// residual and no 7x6 PlusJacobian product (that plumbing cost ~15% of a
// solve). The Jacobian in delta is the left-perturbation Jacobian at
// exp(delta) * T0 (core/geometry/reprojection.h) times se3_left_jacobian(delta).
//
// Reprojection: sqrt(info) * (project(T * f) - q), info = 1/sigma^2 of the
// keypoint's octave, so one Huber threshold (on whitened pixels) serves
// every pyramid level.
// Shape, two forms of |f - D(f)| (D the closest mesh point):
// - exact: sqrt(w_shape) * (f - D(f)) with D queried at every evaluation.
//   Its Jacobian is the exact derivative of f - D(f): the projector onto
//   the normal space of the mesh feature holding D(f) (n n^T on a face).
// - plane (the default in BA): sqrt(w_shape) * n . (f - D0), with the foot
//   point D0 = D(f0) and the normal n taken once per solve at the start
//   value f0; Jacobian sqrt(w_shape) n^T. A window moves points by a
//   fraction of a mm, far below the organ's radius of curvature, so the
//   tangent plane is the surface to first order, one closest-point query
//   per point and solve instead of one per evaluation (the bench: 2x
//   faster). The residual is padded with a zero second row so that every
//   residual of a point has 2 rows: Ceres then uses its fixed-size Schur
//   eliminator (2, 3, 6) instead of the dynamic one.
// Why not "D(f) locally constant" with Jacobian I: that adds a tangential
// stiffness pinning the point to its old foot point, which fights the
// reprojection terms that should slide it along the surface; both forms
// here penalise only the off-surface component.
//
// All functions allocate nothing; any thread.
#pragma once

#include "core/geometry/camera.h"
#include "core/mesh/closest_point.h"
#include "core/geometry/se3.h"

namespace st {

using Mat26r = Eigen::Matrix<double, 2, 6, Eigen::RowMajor>;

// Left Jacobian of the SE3 exponential: exp(xi + d) = exp(Jl(xi) d) exp(xi)
// to first order in d; Jl(0) = I. Series sum ad(xi)^n / (n+1)! (it
// converges for every xi; BA's deltas are a few mrad, so a handful of terms).
Mat6 se3_left_jacobian(const Vec6& xi);

// What every residual of one pose block needs from its 6 parameters (the
// delta) and the block's linearization point T0 (the pose handed over):
// T = exp(delta) * T0 and Jl(delta). BA computes it once per pose and
// evaluation (core/mapping/bundle_adjustment.cpp) instead of once per residual.
struct PoseLinearization {
  SE3 T_camera_model;
  Mat6 left_jacobian = Mat6::Identity();
  bool at_origin = true;  // delta == 0: left_jacobian is I, the product is skipped
};
void pose_linearization(const SE3& T0_camera_model, const double* delta, PoseLinearization* out);

// Whitened reprojection residual r (2) of point f (3) in the pose
// exp(delta) * T0, with the Jacobians J_pose (2 x 6 in delta, row-major) and
// J_point (2 x 3), each optional. False when the point is not in front
// (depth <= min_depth_mm).
bool reprojection_cost(const Pinhole& K, const Vec2& px_ideal, double sqrt_info, double min_depth_mm,
                       const SE3& T0_camera_model, const double* delta, const double* f, double* r, double* J_pose,
                       double* J_point);
// The same with the pose block's linearization already computed.
bool reprojection_cost(const Pinhole& K, const Vec2& px_ideal, double sqrt_info, double min_depth_mm,
                       const PoseLinearization& pose, const double* f, double* r, double* J_pose, double* J_point);

// Shape residual r (3) = sqrt_w (f - D(f)) and J (3 x 3, row-major, optional).
// False when the index cannot answer (not configured, non-finite f).
bool shape_cost(const ClosestPointIndex& surface, double sqrt_w, const double* f, double* r, double* J);

// Tangent plane of the mesh at the closest point to f0: the foot point and
// the unit normal (the face normal, or the direction f0 - foot when the
// foot is on an edge or vertex and f0 is off the surface).
struct ShapePlane {
  Vec3 foot = Vec3::Zero();
  Vec3 normal = Vec3::UnitZ();
};
bool shape_plane(const ClosestPointIndex& surface, const Vec3& f0, ShapePlane* plane);
// r (2) = [sqrt_w n . (f - foot), 0], J (2 x 3, row-major, optional).
void plane_cost(const ShapePlane& plane, double sqrt_w, const double* f, double* r, double* J);

}  // namespace st
