// The window bundle adjustment's own solver: Levenberg-Marquardt on the
// reduced camera system, the points eliminated block by block (Schur
// complement), the reduced system solved by a dense Cholesky. It minimises
// exactly what the Ceres form (core/mapping_ceres/ceres_form.cpp) hands to
// ceres::Solve: the residuals of core/mapping/ba_residuals.h (Huber on the
// whitened reprojection, Huber on the shape residual, the pose prior, the
// optional common focal scale), with the same 6-dim left pose deltas.
//
// The damping and stopping follow Ceres' trust-region LM as the Ceres form
// configures it (no Jacobi scaling, monotonic steps): the LM diagonal is
// diag(J^T J) clamped to [1e-6, 1e32] and divided by the trust-region
// radius (start 1e4); a step is kept when the cost fell by more than 1e-3
// of the model's decrease, the radius then grown by
// 1 / max(1/3, 1 - (2 rho - 1)^3), else shrunk by a factor that doubles on
// each rejection in a row. Stops: the iteration and time limits, the
// function (1e-6), parameter (1e-8) and gradient (1e-10) tolerances, and
// the relative gradient stop of BundleAdjusterOptions. So the same window
// and start give the Ceres form's solution to round-off.
//
// Shape of ceres/tiny_solver.h: plain Options and Summary, every workspace
// sized in configure() from the window's maxima (keyframes, points,
// observations); set-up and solve() allocate nothing and make no virtual
// calls. The reduced system is at most (6 max_keyframes + 1)^2 doubles (the
// +1: the focal scale). Thread: one solver per thread (the mapping
// thread); the closest-point index is only read.
#pragma once

#include <cstdint>
#include <vector>

#include <Eigen/Core>

#include "core/base/result.h"
#include "core/geometry/camera.h"
#include "core/geometry/se3.h"
#include "core/mapping/ba_residuals.h"
#include "core/mesh/closest_point.h"

namespace st {

struct SchurSolverOptions {
  int max_iterations = 10;
  double max_time_s = 0.05;                   // needs now_ns; without a clock only the iterations bound
  double relative_gradient_tolerance = 1e-4;  // BundleAdjusterOptions' stop; 0: off
  // Ceres' defaults, kept so that results agree with the Ceres form.
  double function_tolerance = 1e-6;
  double parameter_tolerance = 1e-8;
  double gradient_tolerance = 1e-10;
  double initial_radius = 1e4, max_radius = 1e16, min_radius = 1e-32;
  double min_lm_diagonal = 1e-6, max_lm_diagonal = 1e32;
  double min_relative_decrease = 1e-3;
  int max_invalid_steps = 5;
  std::int64_t (*now_ns)() = nullptr;  // injected clock (core/ has none)
};

struct SchurSolverSummary {
  bool usable = false;  // the start evaluated and no numerical failure
  int iterations = 0;   // as Ceres counts them: the start is iteration 0
  double initial_cost = 0, final_cost = 0;
  int residuals = 0, parameters = 0;  // scalar rows (the plane residual as 2, as in Ceres) and unknowns
  double solver_ms = 0;               // 0 without a clock
};

// The residuals' constants, shared by every solve of a BundleAdjuster.
struct SchurResidualConfig {
  Pinhole K;
  double min_depth_mm = 1.0;
  double reprojection_huber = 1.0;  // on whitened pixels
  double sqrt_w_shape = 0.0;
  double shape_huber = 1.0;         // on the shape residual (sqrt(w_shape) mm)
  const ClosestPointIndex* surface = nullptr;  // for ShapeKind::kExact
};

class SchurSolver {
 public:
  enum class ShapeKind : std::uint8_t { kNone, kPlane, kExact };

  // Sizes every workspace (allocates). Each maximum >= 1, max_keyframes
  // at most kMaxKeyframes.
  static constexpr int kMaxKeyframes = 4096;
  Status configure(int max_keyframes, int max_points, int max_observations);

  // Problem set-up, in this order; allocates nothing. Indices are the
  // job's: keyframes 0..keyframe_count-1, points 0..point_count-1 (a point
  // not active is no parameter and must have no observation).
  bool begin(const SchurResidualConfig& residuals, int keyframe_count, int point_count, bool free_focal);
  void set_keyframe(int keyframe, const SE3& T0_camera_model, bool held);
  void set_point(int point, const double* p_model, bool active, ShapeKind shape, const ShapePlane& plane);
  bool add_observation(int keyframe, int point, const Vec2& px_ideal, double info);
  // r = weight .* (delta + e0) on a free keyframe's delta (BundleAdjuster's pose prior).
  void set_prior(int keyframe, const Vec6& e0, const Vec6& weight);

  bool solve(const SchurSolverOptions& options, SchurSolverSummary* summary);

  // The solution (the start where solve() did not move it).
  Vec6 pose_delta(int keyframe) const;
  Vec3 point(int i) const { return x_point_[static_cast<std::size_t>(i)]; }
  double focal_scale() const { return x_focal_; }

 private:
  // 32 bytes: the largest of the solver's per-observation arrays after the
  // linearization.
  struct Observation {
    Vec2 px = Vec2::Zero();
    double sqrt_info = 1;
    std::int32_t point = 0;
    std::int16_t keyframe = 0, column = -1;  // column: reduced system offset, -1 held
  };
  // One observation's corrected (Huber-scaled) residual and Jacobians at
  // x, stored transposed: a row-major 2 x n Jacobian as reprojection_cost()
  // writes it is a column-major n x 2, whose columns are the packets the
  // 6x6 and 3x3 products below run on. Kept small: it is streamed through
  // at every evaluation and step.
  struct Linearization {
    Eigen::Matrix<double, 6, 2> G;  // J_pose^T
    Eigen::Matrix<double, 3, 2> H;  // J_point^T
    Vec2 r, J_focal;
  };

  enum class IterationEnd { kContinue, kConverged, kFailure };
  struct Iteration {
    IterationEnd end = IterationEnd::kContinue;
    bool success = false;  // the step was accepted
    double cost = 0;       // as Ceres reports the iteration's cost
  };
  struct LmState {
    double radius = 1e4, decrease = 2.0;
    bool new_diagonal = true, any_success = false;
    int invalid_steps = 0;
    double cost = 0, gradient_max_norm = 0, start_gradient_max_norm = 0;
  };
  Iteration iterate(const SchurSolverOptions& o, LmState* s);
  bool keep_going(const SchurSolverOptions& o, const LmState& s, int iteration, bool success,
                  std::int64_t t0_ns) const;
  bool prepare();
  bool sort_observations();
  bool evaluate(bool candidate, bool linearize, double* cost);
  bool evaluate_observations(bool candidate, bool linearize, double* cost);
  bool evaluate_shapes(bool candidate, bool linearize, double* cost);
  double evaluate_prior(bool candidate, bool linearize);
  void clear_normal_equations();
  double gradient_max_norm() const;
  double free_norm(double focal, const std::vector<Vec6>& pose, const std::vector<Vec3>& point) const;
  double parameter_norm() const;
  double step_norm() const;
  bool compute_step(double radius, bool new_diagonal, const SchurSolverOptions& o);
  void eliminate_point(int p);
  bool back_substitute();
  double model_cost_change() const;
  void make_candidate();
  void accept_candidate();
  double elapsed_s(std::int64_t t0_ns, const SchurSolverOptions& o) const;

  SchurResidualConfig res_;
  int max_keyframes_ = 0, max_points_ = 0, max_observations_ = 0;
  int keyframe_count_ = 0, point_count_ = 0, observation_count_ = 0, columns_ = 0, active_count_ = 0;
  bool free_focal_ = false, configured_ = false, set_up_ = false;
  double mu_ = 0;  // 1 / trust-region radius: the LM diagonal's factor
  double point_model_change_ = 0;  // the points' residuals' part of model_cost_change(), from back_substitute()
  int prior_keyframe_ = -1;
  Vec6 prior_e0_ = Vec6::Zero(), prior_w_ = Vec6::Ones();

  // Per keyframe.
  std::vector<SE3> T0_;
  std::vector<std::int32_t> column_;
  std::vector<Vec6> x_pose_, cand_pose_, step_pose_;
  std::vector<PoseLinearization> lin_pose_;
  // J^T J of the pose block: the pose prior's part; the observations' part
  // is added where the points are eliminated (eliminate_point()), where
  // each observation's Jacobian is read anyway, and only its diagonal is
  // summed at the evaluation (the LM diagonal). An evaluation that ends
  // the solve then forms no pose block.
  std::vector<Mat6> U_;
  std::vector<Vec6> U_obs_diag_;
  std::vector<Vec6> g_pose_, diag_pose_;
  std::vector<Vec6> U_focal_;  // J_focal^T J_pose
  // Per point.
  std::vector<std::uint8_t> active_;
  std::vector<std::int32_t> active_points_;
  std::vector<ShapeKind> shape_;
  std::vector<ShapePlane> plane_;
  std::vector<Vec3> x_point_, cand_point_, step_point_, g_point_, diag_point_;
  std::vector<Mat3> V_, V_inv_;
  std::vector<Vec3> W_focal_;  // J_point^T J_focal summed over the point's observations
  std::vector<Vec3> shape_r_;  // corrected shape residual (the plane's in row 0, the rest 0)
  std::vector<Mat3> shape_J_;  // and its Jacobian
  std::vector<std::int32_t> first_obs_;  // per point: its observations in obs_ (point_count_ + 1)
  // Per observation: as added, sorted by point in place by prepare()
  // (order_: each one's place, a scratch of the sort).
  std::vector<Observation> obs_;
  std::vector<std::int32_t> order_;
  std::vector<Linearization> lin_obs_;
  // Focal scale (one more reduced column when free).
  double x_focal_ = 1, cand_focal_ = 1, step_focal_ = 0, g_focal_ = 0, U_ff_ = 0, diag_focal_ = 0;
  // The reduced system's 6x6 keyframe blocks while the points are
  // eliminated (block (a, b), a >= b, at a * free keyframes + b): fixed-size
  // and contiguous, copied into S_ for the Cholesky.
  std::vector<Mat6> S_blocks_;
  int free_keyframes_ = 0;
  // Reduced camera system (lower triangle), right-hand side and step.
  Eigen::MatrixXd S_;
  Eigen::VectorXd rhs_;
};

}  // namespace st
