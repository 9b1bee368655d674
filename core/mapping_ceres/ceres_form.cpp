#include "core/mapping_ceres/ceres_form.h"

#include <ceres/ceres.h>

#include <cmath>
#include <limits>
#include <memory>
#include <vector>

#include "core/geometry/reprojection.h"

namespace st {

namespace {


// The linearization of one pose block, recomputed only when the block's
// delta changes: Ceres evaluates all ~1000 residuals of a pose at the same
// values, so exp(delta) * T0 and the left Jacobian of exp are computed once
// per pose and evaluation instead of once per residual. Mutable from the
// const Evaluate(): safe because the solver runs single-threaded.
class PoseCache {
 public:
  void reset(const SE3& T0_camera_model) {
    T0_ = T0_camera_model;
    delta_[0] = std::numeric_limits<double>::quiet_NaN();  // NaN != anything: recompute
    held_.T_camera_model = T0_camera_model;
  }
  // The linearization at delta = 0, for a held pose (not a parameter block).
  const PoseLinearization& held() const { return held_; }
  const PoseLinearization& at(const double* delta) const {
    bool same = true;
    for (int k = 0; k < 6; ++k) same = same && delta_[k] == delta[k];
    if (!same) {
      for (int k = 0; k < 6; ++k) delta_[k] = delta[k];
      pose_linearization(T0_, delta, &lin_);
    }
    return lin_;
  }
  const SE3& T0() const { return T0_; }

 private:
  SE3 T0_;
  mutable double delta_[6] = {std::numeric_limits<double>::quiet_NaN()};
  mutable PoseLinearization lin_;
  PoseLinearization held_;  // identity left Jacobian, at_origin
};

// Reprojection residual of one observation. The pose of a held keyframe
// (fixed, or the gauge keyframe) is not a parameter block: the residual then
// has the point as its only block (the same rows and point Jacobian; Ceres
// gathers, checks and skips one block less per residual and evaluation, and
// the held poses are not in the problem at all). The block sizes are set
// per solve into a vector reserved at construction: no allocation.
class ReprojectionCost final : public ceres::CostFunction {
 public:
  ReprojectionCost() {
    set_num_residuals(2);
    mutable_parameter_block_sizes()->reserve(3);  // [pose,] point[, focal scale]
  }
  void set(const Pinhole& K, const Vec2& px_ideal, double info, double min_depth_mm, const PoseCache* pose,
           bool held, bool focal = false) {
    pose_ = pose;
    K_ = K;
    px_ = px_ideal;
    sqrt_info_ = std::sqrt(info);
    min_depth_mm_ = min_depth_mm;
    held_ = held;
    focal_ = focal;
    std::vector<std::int32_t>& sizes = *mutable_parameter_block_sizes();
    sizes.clear();
    if (!held) sizes.push_back(6);
    sizes.push_back(3);
    if (focal) sizes.push_back(1);
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    const auto evaluate = [&](const Pinhole& K) {
      if (held_)
        return reprojection_cost(K, px_, sqrt_info_, min_depth_mm_, pose_->held(), parameters[0], residuals, nullptr,
                                 jacobians ? jacobians[0] : nullptr);
      return reprojection_cost(K, px_, sqrt_info_, min_depth_mm_, pose_->at(parameters[0]), parameters[1], residuals,
                               jacobians ? jacobians[0] : nullptr, jacobians ? jacobians[1] : nullptr);
    };
    if (!focal_) return evaluate(K_);
    // Focal lengths scaled by the last block's s (principal point kept):
    // r = sqrt_info (s f xn + c - q), so dr/ds = sqrt_info f xn = (r + sqrt_info (q - c)) / s.
    const int b = held_ ? 1 : 2;
    const double scale = parameters[b][0];
    Pinhole Ks = K_;
    Ks.fx *= scale;
    Ks.fy *= scale;
    const bool ok = evaluate(Ks);
    if (ok && jacobians && jacobians[b]) {
      jacobians[b][0] = (residuals[0] + sqrt_info_ * (px_.x() - K_.cx)) / scale;
      jacobians[b][1] = (residuals[1] + sqrt_info_ * (px_.y() - K_.cy)) / scale;
    }
    return ok;
  }

 private:
  const PoseCache* pose_ = nullptr;
  Pinhole K_;
  Vec2 px_ = Vec2::Zero();
  double sqrt_info_ = 1, min_depth_mm_ = 1;
  bool held_ = false, focal_ = false;
};

class ShapeCost final : public ceres::SizedCostFunction<3, 3> {
 public:
  void set(const ClosestPointIndex* surface, double w_shape) {
    surface_ = surface;
    sqrt_w_ = std::sqrt(w_shape);
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    return surface_ && shape_cost(*surface_, sqrt_w_, parameters[0], residuals, jacobians ? jacobians[0] : nullptr);
  }

 private:
  const ClosestPointIndex* surface_ = nullptr;
  double sqrt_w_ = 0;
};

class PlaneCost final : public ceres::SizedCostFunction<2, 3> {
 public:
  void set(const ShapePlane* plane, double w_shape) {
    plane_ = plane;
    sqrt_w_ = std::sqrt(w_shape);
  }
  bool Evaluate(double const* const* parameters, double* residuals, double** jacobians) const override {
    plane_cost(*plane_, sqrt_w_, parameters[0], residuals, jacobians ? jacobians[0] : nullptr);
    return true;
  }

 private:
  const ShapePlane* plane_ = nullptr;
  double sqrt_w_ = 0;
};

// The prior on one pose block: r = W (delta + e0), e0 = log(T0 T_prior^-1)
// (the handed-over pose's offset from the prior), W = diag(1/sigma_rad x 3,
// 1/sigma_mm x 3). First order in delta: log(exp(delta) X) = delta + log(X)
// up to a term in |delta| |e0| (a window's delta of a few mrad times a
// registration error of a few degrees or mm: far below the sigmas).
class PosePriorCost final : public ceres::SizedCostFunction<6, 6> {
 public:
  void set(const SE3& T0_camera_model, const SE3& T_prior, double sigma_rad, double sigma_mm) {
    e0_ = (T0_camera_model * T_prior.inverse()).log();
    for (int k = 0; k < 3; ++k) {
      w_[k] = 1.0 / sigma_rad;
      w_[k + 3] = 1.0 / sigma_mm;
    }
  }
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    for (int k = 0; k < 6; ++k) residuals[k] = w_[k] * (parameters[0][k] + e0_[k]);
    if (jacobians && jacobians[0]) {
      for (int k = 0; k < 36; ++k) jacobians[0][k] = 0.0;
      for (int k = 0; k < 6; ++k) jacobians[0][k * 6 + k] = w_[k];
    }
    return true;
  }

 private:
  Vec6 e0_ = Vec6::Zero();
  double w_[6] = {1, 1, 1, 1, 1, 1};
};

// Stops the solve once the gradient (max norm) has fallen below a fraction
// of its value at the start. Ceres' own tests are absolute (gradient) or
// need the next step solved and evaluated (function, parameter tolerance):
// on the bench window the last of 3 steps changed the cost by 2e-7 and cost
// a linear solve and an evaluation (~20% of the solve). Thread: the solver's.
class RelativeGradientStop final : public ceres::IterationCallback {
 public:
  explicit RelativeGradientStop(double tolerance) : tolerance_(tolerance) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary& s) override {
    if (s.iteration == 0) {
      start_norm_ = s.gradient_max_norm;
      return ceres::SOLVER_CONTINUE;
    }
    if (s.step_is_successful && s.gradient_max_norm <= tolerance_ * start_norm_)
      return ceres::SOLVER_TERMINATE_SUCCESSFULLY;
    return ceres::SOLVER_CONTINUE;
  }

 private:
  double tolerance_ = 0, start_norm_ = 0;
};

// Points first (eliminated), poses second: the Schur ordering Ceres would
// find, given instead of searched for (its independent-set search builds a
// graph of the whole problem on every solve).
std::shared_ptr<ceres::ParameterBlockOrdering> schur_ordering(BaJob* job, const std::vector<std::uint8_t>& point_observed,
                                                              const std::vector<std::uint8_t>& held, double* deltas) {
  auto ordering = std::make_shared<ceres::ParameterBlockOrdering>();
  for (int i = 0; i < job->point_count; ++i)
    if (point_observed[static_cast<std::size_t>(i)]) ordering->AddElementToGroup(job->points[static_cast<std::size_t>(i)].p_model, 0);
  for (int i = 0; i < job->keyframe_count; ++i)
    if (!held[static_cast<std::size_t>(i)]) ordering->AddElementToGroup(deltas + 6 * i, 1);
  return ordering;
}

}  // namespace

// The Ceres form: what BundleAdjuster::select() chose for a solve, as a
// ceres::Problem (a friend of BundleAdjuster: it reads the selection, the
// poses' starts and the planes, and writes the deltas and points back where
// the Schur form does).
class CeresForm final : public BaReferenceSolver {
 public:
  explicit CeresForm(const BundleAdjuster& ba);
  Run run(BundleAdjuster& ba, BaJob* job, int max_iterations, double max_time_s) override;

 private:
  void build(BundleAdjuster& ba, BaJob* job, ceres::Problem* problem);

  std::unique_ptr<ceres::LossFunction> reprojection_loss_, shape_loss_;
  // Cost functions are not copyable: fixed arrays sized at construction,
  // not owned by the per-solve Problem.
  std::unique_ptr<ReprojectionCost[]> reprojection_costs_;
  std::unique_ptr<ShapeCost[]> shape_costs_;
  std::unique_ptr<PlaneCost[]> plane_costs_;
  PosePriorCost prior_cost_;                  // the job's pose prior (at most one)
  std::unique_ptr<PoseCache[]> pose_caches_;  // per job keyframe
  std::unique_ptr<RelativeGradientStop> gradient_stop_;
  ceres::Problem::Options problem_options_;
  ceres::Solver::Options solver_options_;
};

// The pools and options, for the configured adjuster's maxima.
CeresForm::CeresForm(const BundleAdjuster& ba) {
  const BundleAdjusterOptions& options = ba.options_;
  const int max_keyframes = ba.max_keyframes_, max_points = ba.max_points_, max_observations = ba.max_observations_;
  reprojection_loss_ = std::make_unique<ceres::HuberLoss>(options.reprojection_huber);
  // The residual is sqrt(w_shape) * distance: the threshold in its units.
  shape_loss_ = std::make_unique<ceres::HuberLoss>(std::sqrt(options.w_shape) * options.shape_huber_mm);
  reprojection_costs_ = std::make_unique<ReprojectionCost[]>(static_cast<std::size_t>(max_observations));
  shape_costs_ = std::make_unique<ShapeCost[]>(static_cast<std::size_t>(max_points));
  plane_costs_ = std::make_unique<PlaneCost[]>(static_cast<std::size_t>(max_points));
  pose_caches_ = std::make_unique<PoseCache[]>(static_cast<std::size_t>(max_keyframes));
  for (int i = 0; i < max_points; ++i) {
    shape_costs_[static_cast<std::size_t>(i)].set(&ba.surface_, options.w_shape);
    plane_costs_[static_cast<std::size_t>(i)].set(&ba.planes_[static_cast<std::size_t>(i)], options.w_shape);
  }
  problem_options_.cost_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options_.loss_function_ownership = ceres::DO_NOT_TAKE_OWNERSHIP;
  problem_options_.disable_all_safety_checks = true;  // check() vetted the job; saves ~1/3 of the build
  ceres::Solver::Options& so = solver_options_;
  so.linear_solver_type = ceres::DENSE_SCHUR;
  so.num_threads = 1;
  so.jacobi_scaling = false;  // same iterations and results on the bench window, ~1 ms less (column scaling passes)
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.max_num_iterations = options.max_iterations;
  so.max_solver_time_in_seconds = options.max_time_s;
  if (options.relative_gradient_tolerance > 0) {
    gradient_stop_ = std::make_unique<RelativeGradientStop>(options.relative_gradient_tolerance);
    so.callbacks.push_back(gradient_stop_.get());
  }
}

// This solve's blocks and residuals (select()) added to problem.
void CeresForm::build(BundleAdjuster& ba, BaJob* job, ceres::Problem* problem) {
  using FocalTest = BundleAdjuster::FocalTest;
  const bool free_focal = ba.focal_ == FocalTest::kFree;
  for (int i = 0; i < job->keyframe_count; ++i) {
    pose_caches_[static_cast<std::size_t>(i)].reset(ba.T0_[static_cast<std::size_t>(i)]);
    // Held poses stay out of the problem (their residuals take the point only).
    if (!ba.held_[static_cast<std::size_t>(i)]) problem->AddParameterBlock(ba.pose_delta_block(i), 6);
  }
  if (ba.use_prior_) {
    const int prior_kf = job->prior.keyframe;
    prior_cost_.set(job->pose(prior_kf), pose_from_params(job->prior.pose), job->prior.sigma_rad, job->prior.sigma_mm);
    problem->AddResidualBlock(&prior_cost_, nullptr, ba.pose_delta_block(prior_kf));
  }
  if (free_focal) {
    ba.focal_scale_[0] = 1.0;
    problem->AddParameterBlock(ba.focal_scale_, 1);
  }
  int used = 0;
  for (int i = 0; i < job->observation_count; ++i) {
    if (!ba.observation_used_[static_cast<std::size_t>(i)]) continue;
    const BaObservation& o = job->observations[static_cast<std::size_t>(i)];
    ReprojectionCost& c = reprojection_costs_[static_cast<std::size_t>(used++)];
    const bool held = ba.held_[static_cast<std::size_t>(o.keyframe)] != 0;
    c.set(ba.K_, Vec2(o.x_ideal, o.y_ideal), o.info, ba.options_.min_depth_mm,
          &pose_caches_[static_cast<std::size_t>(o.keyframe)], held, free_focal);
    // The residual's blocks: [pose,] point[, focal scale] (ReprojectionCost::set).
    double* blocks[3];
    int n_blocks = 0;
    if (!held) blocks[n_blocks++] = ba.pose_delta_block(o.keyframe);
    blocks[n_blocks++] = job->points[static_cast<std::size_t>(o.point)].p_model;
    if (free_focal) blocks[n_blocks++] = ba.focal_scale_;
    problem->AddResidualBlock(&c, reprojection_loss_.get(), blocks, n_blocks);
  }
  for (int i = 0; i < job->point_count; ++i) {
    const auto is = static_cast<std::size_t>(i);
    if (!ba.shape_used_[is]) continue;
    double* f = job->points[is].p_model;
    if (ba.options_.exact_shape)
      problem->AddResidualBlock(&shape_costs_[is], shape_loss_.get(), f);
    else
      problem->AddResidualBlock(&plane_costs_[is], shape_loss_.get(), f);
  }
}

// A Problem built, solved and torn down (allocates).
BaReferenceSolver::Run CeresForm::run(BundleAdjuster& ba, BaJob* job, int max_iterations, double max_time_s) {
  ceres::Problem problem(problem_options_);
  build(ba, job, &problem);
  ceres::Solver::Options so = solver_options_;
  so.linear_solver_ordering = schur_ordering(job, ba.point_observed_, ba.held_, ba.deltas_.data());
  if (ba.focal_ == BundleAdjuster::FocalTest::kFree) so.linear_solver_ordering->AddElementToGroup(ba.focal_scale_, 1);
  if (max_iterations > 0) so.max_num_iterations = max_iterations;
  if (max_time_s > 0) so.max_solver_time_in_seconds = max_time_s;
  ceres::Solver::Summary s;
  ceres::Solve(so, &problem, &s);
  Run run;
  run.initial_cost = s.initial_cost;
  run.final_cost = s.final_cost;
  run.total_s = s.total_time_in_seconds;
  run.iterations = static_cast<int>(s.iterations.size());
  run.usable = s.IsSolutionUsable();
  run.residuals = s.num_residuals;
  run.parameters = s.num_effective_parameters;
  return run;
}

Status configure_ceres_form(BundleAdjuster* ba, const BundleAdjusterOptions& options, const Mesh& mesh,
                            const Pinhole& K, int max_keyframes, int max_points, int max_observations) {
  if (Status s = ba->configure(options, mesh, K, max_keyframes, max_points, max_observations); !s.ok()) return s;
  ba->use_reference(std::make_unique<CeresForm>(*ba));
  return Status::Ok();
}

}  // namespace st
