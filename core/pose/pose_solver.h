// Robust 6-DoF camera pose from 2D-3D correspondences: a fixed-size
// Levenberg-Marquardt in the shape of Ceres' tiny_solver.h (plain Options /
// Summary structs, workspace members reused across solves), with Huber loss
// and ORB-SLAM-style outlier rejection rounds (chi2 test, 2 DoF, 95%).
//
// The 6x6 normal equations J^T W J and J^T W r are accumulated residual by
// residual in fixed-size types; nothing is allocated in solve(). The only
// per-observation state (inlier flags) is sized once in configure().
//
// Parameterisation: T_camera_model is updated on the left,
// T <- exp(delta) * T, delta = [omega (rad); v (mm)] (se3.h). Residuals are
// r = project(T * p_model) - px_ideal in pixels, whitened by the
// observation's information (1/sigma^2, sigma = 1.2^octave px).
//
// Threading: one PoseSolver per thread (the tracking thread owns one).
#pragma once

#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "core/geometry/camera.h"
#include "core/pose/correspondences.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

enum class PoseStatus : std::uint8_t {
  kConverged,       // pose written; LM met a tolerance in the last round
  kNotConverged,    // pose written (cost only decreased) but the last round hit max_iterations
  kNotConfigured,   // configure() was not called or failed
  kTooManyPoints,   // count above the configured capacity
  kTooFewPoints,    // fewer usable (finite, positive-information) correspondences than min_inliers
  kNonFiniteInput,  // the initial pose or the camera is not finite / fx, fy <= 0
  kPointsBehindCamera,  // at the initial pose fewer than min_inliers points lie in front of the
                        // camera
  kTooFewInliers,       // after a rejection round fewer than min_inliers inliers remain
  kNumericalFailure,    // normal equations not solvable or a non-finite value appeared
};
const char* to_string(PoseStatus s);

struct PoseSolverOptions {
  int max_iterations = 10;  // LM iterations per round (ORB-SLAM: 10)
  int rounds = 4;           // outlier-rejection rounds, 1..4 (ORB-SLAM: 4)
  // Huber threshold on the whitened residual norm sqrt(info) * |r|: pixels
  // at octave 0. sqrt(5.991) makes every chi2 inlier a quadratic residual.
  double huber_delta = 2.447651936;
  double chi2_threshold = kChi2Inlier2Dof;  // inlier: info * |r|^2 < this
  int min_inliers = 6;                      // below: kTooFewPoints / kTooFewInliers
  double min_depth_mm = 0.1;                // in front of the camera: z > this
  // |cost change| < this * cost: converged. With cost ~ N (chi2 ~ 2 per
  // point), 1e-5 leaves a pose error of ~1e-5 N in chi2 units, far below the
  // statistical 6 (6 DoF); 1e-8 cost 28% more iterations for no accuracy
  // change in the bench (scopetrack-bench pose variants).
  double function_tolerance = 1e-5;
  double gradient_tolerance = 1e-10;         // max |J^T W r| < this: converged
  double step_tolerance = 1e-9;              // |delta| < this * (1 + |t|): converged
  double initial_trust_region_radius = 1e4;  // LM: initial damping 1 / radius
};

struct PoseSolverSummary {
  PoseStatus status = PoseStatus::kNotConfigured;
  int num_correspondences = 0;      // count given
  int num_valid = 0;                // finite input with positive information
  int num_inliers = 0;              // chi2 inliers at the final pose
  int rounds = 0;                   // rejection rounds run
  int iterations = 0;               // LM iterations over all rounds
  double initial_cost = -1;         // 1/2 sum rho(chi2) over the first round's active set
  double final_cost = -1;           // same over the last round's active set
  double rms_reprojection_px = -1;  // unweighted RMS |r| over the final inliers
  // J^T Info J over the final inliers at the final pose, in the tangent
  // [omega (rad); v (mm)] of the left perturbation; its inverse is the pose
  // covariance when 1 px is the level-0 noise sigma.
  Mat6 hessian = Mat6::Zero();
  Mat6 covariance = Mat6::Zero();
  bool covariance_valid = false;
  // Quality: sqrt of the largest eigenvalue of the rotation block (deg) and
  // of the v block (mm). For a left perturbation the camera centre in the
  // model frame moves by -R^T v, so the latter is the camera position sigma.
  double sigma_rotation_deg = -1;
  double sigma_position_mm = -1;

  bool pose_written() const {
    return status == PoseStatus::kConverged || status == PoseStatus::kNotConverged;
  }
};

class PoseSolver {
 public:
  using Options = PoseSolverOptions;
  using Summary = PoseSolverSummary;

  // Sizes the per-observation buffers (allocates). max_correspondences in
  // [1, kMaxKeypoints]; options.rounds in [1, 4], max_iterations >= 1.
  Status configure(int max_correspondences, const Options& opt = {});

  // Refines *T_camera_model from its initial value. Writes the pose only when
  // summary->pose_written(); otherwise *T_camera_model is unchanged. Fills
  // *summary (may be nullptr) and inliers(). No allocation, no exceptions.
  // Returns summary.pose_written().
  bool solve(const Correspondences& c, const Pinhole& K, SE3* T_camera_model, Summary* summary);

  // Inlier flags (1 = inlier) of the last solve(), one per correspondence.
  std::span<const std::uint8_t> inliers() const {
    return {inlier_.data(), static_cast<std::size_t>(last_count_)};
  }
  const Options& options() const { return options_; }
  int capacity() const { return static_cast<int>(inlier_.size()); }

 private:
  struct Linearization {
    Mat6 H;       // J^T W J (Huber-weighted)
    Vec6 g;       // J^T W r
    double cost;  // 1/2 sum rho
  };
  enum class RoundEnd : std::uint8_t { kConverged, kMaxIterations, kFailed };

  int count_usable(const Correspondences& c, const Pinhole& K, const SE3& T);
  bool linearize(const Correspondences& c, const Pinhole& K, const SE3& T,
                 Linearization* out) const;
  RoundEnd run_round(const Correspondences& c, const Pinhole& K, SE3* T, Summary* s);
  int classify(const Correspondences& c, const Pinhole& K, const SE3& T, bool* changed);
  bool update_linearization(const Correspondences& c, const Pinhole& K, const SE3& T, int i,
                            double sign);
  void fill_quality(const Correspondences& c, const Pinhole& K, const SE3& T, Summary* s) const;

  Options options_;
  std::vector<std::uint8_t> valid_;   // finite input, positive information
  std::vector<std::uint8_t> inlier_;  // active set of the current round / result
  int last_count_ = 0;
  bool configured_ = false;
  // Workspace reused across iterations (tiny_solver style).
  Linearization lin_{}, lin_trial_{};
  bool lin_current_ = false;  // lin_ holds the linearisation at the current pose and active set
};

}  // namespace st
