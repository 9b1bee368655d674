#include "core/pose/pose_solver.h"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "core/base/capacity.h"
#include "core/geometry/reprojection.h"

namespace st {

const char* to_string(PoseStatus s) {
  switch (s) {
    case PoseStatus::kConverged:
      return "converged";
    case PoseStatus::kNotConverged:
      return "not converged: last round hit max_iterations";
    case PoseStatus::kNotConfigured:
      return "pose solver not configured";
    case PoseStatus::kTooManyPoints:
      return "more correspondences than the configured capacity";
    case PoseStatus::kTooFewPoints:
      return "too few finite correspondences with positive information";
    case PoseStatus::kNonFiniteInput:
      return "initial pose or camera not finite (or fx, fy <= 0)";
    case PoseStatus::kPointsBehindCamera:
      return "too few points in front of the camera at the initial pose";
    case PoseStatus::kTooFewInliers:
      return "too few chi2 inliers after outlier rejection";
    case PoseStatus::kNumericalFailure:
      return "normal equations not solvable or non-finite values";
  }
  return "unknown pose status";
}

namespace {

// Huber loss on s = sqrt(s2): rho(s2) = s2 inside, 2 delta s - delta^2
// outside; weight = rho'(s2) (the IRLS weight of the squared residual).
inline double huber(double s2, double delta, double* weight) {
  if (s2 <= delta * delta) {
    *weight = 1.0;
    return s2;
  }
  const double s = std::sqrt(s2);
  *weight = delta / s;
  return 2.0 * delta * s - delta * delta;
}

// Upper triangle of H += w * (a a^T + b b^T), g += w * (a ra + b rb).
inline void accumulate(const Mat26& J, const Vec2& r, double w, Mat6* H, Vec6* g) {
  for (int col = 0; col < 6; ++col) {
    const double wa = w * J(0, col), wb = w * J(1, col);
    for (int row = 0; row <= col; ++row) (*H)(row, col) += wa * J(0, row) + wb * J(1, row);
    (*g)[col] += wa * r[0] + wb * r[1];
  }
}

inline void mirror_upper(Mat6* H) {
  for (int col = 0; col < 6; ++col)
    for (int row = col + 1; row < 6; ++row) (*H)(row, col) = (*H)(col, row);
}

}  // namespace

Status PoseSolver::configure(int max_correspondences, const Options& opt) {
  configured_ = false;
  if (max_correspondences < 1 || max_correspondences > kMaxKeypoints)
    return make_error("PoseSolver: max_correspondences " + std::to_string(max_correspondences) +
                      " outside [1, kMaxKeypoints=" + std::to_string(kMaxKeypoints) + "]");
  if (opt.rounds < 1 || opt.rounds > 4 || opt.max_iterations < 1 || opt.min_inliers < 3)
    return make_error("PoseSolver: need rounds in [1, 4], max_iterations >= 1, min_inliers >= 3");
  if (!(opt.huber_delta > 0) || !(opt.chi2_threshold > 0) || !(opt.initial_trust_region_radius > 0))
    return make_error("PoseSolver: huber_delta, chi2_threshold, trust region radius must be > 0");
  options_ = opt;
  valid_.assign(static_cast<std::size_t>(max_correspondences), 0);
  inlier_.assign(static_cast<std::size_t>(max_correspondences), 0);
  configured_ = true;
  return Status::Ok();
}

// Marks valid_ and seeds inlier_ with the valid points in front of the
// camera at the initial pose. Returns the number in front.
int PoseSolver::count_usable(const Correspondences& c, const Pinhole& K, const SE3& T) {
  int in_front = 0;
  for (int i = 0; i < c.count; ++i) {
    valid_[i] = c.valid(i) ? 1 : 0;
    Vec2 r;
    inlier_[i] = valid_[i] && reprojection_residual(K, T, c.p_model[i], c.px_ideal[i],
                                                    options_.min_depth_mm, &r, nullptr);
    in_front += inlier_[i];
  }
  return in_front;
}

bool PoseSolver::linearize(const Correspondences& c, const Pinhole& K, const SE3& T,
                           Linearization* out) const {
  out->H.setZero();
  out->g.setZero();
  out->cost = 0;
  Vec2 r;
  Mat26 J;
  for (int i = 0; i < c.count; ++i) {
    if (!inlier_[i]) continue;
    if (!reprojection_residual(K, T, c.p_model[i], c.px_ideal[i], options_.min_depth_mm, &r, &J))
      return false;
    const double info = c.info(i);
    double weight;
    out->cost += 0.5 * huber(info * r.squaredNorm(), options_.huber_delta, &weight);
    accumulate(J, r, info * weight, &out->H, &out->g);
  }
  mirror_upper(&out->H);
  return std::isfinite(out->cost) && out->H.allFinite() && out->g.allFinite();
}

// One LM solve over the current active set (tiny_solver's loop: Marquardt
// damping of the clamped diagonal, Nielsen's update of the damping).
PoseSolver::RoundEnd PoseSolver::run_round(const Correspondences& c, const Pinhole& K, SE3* T,
                                           Summary* s) {
  if (!lin_current_ && !linearize(c, K, *T, &lin_)) return RoundEnd::kFailed;
  lin_current_ = true;  // every accepted step below keeps lin_ at *T
  if (s->initial_cost < 0) s->initial_cost = lin_.cost;
  s->final_cost = lin_.cost;
  double u = 1.0 / options_.initial_trust_region_radius, v = 2.0;
  for (int it = 0; it < options_.max_iterations; ++it) {
    if (lin_.g.cwiseAbs().maxCoeff() < options_.gradient_tolerance) return RoundEnd::kConverged;
    ++s->iterations;
    Mat6 A = lin_.H;
    for (int k = 0; k < 6; ++k) A(k, k) += u * std::clamp(lin_.H(k, k), 1e-6, 1e32);
    const Eigen::LDLT<Mat6> ldlt(A);
    const Vec6 delta = ldlt.solve(-lin_.g);
    if (ldlt.info() != Eigen::Success || !delta.allFinite()) return RoundEnd::kFailed;
    if (delta.norm() < options_.step_tolerance * (1.0 + T->translation().norm()))
      return RoundEnd::kConverged;
    // The trial is linearised right away: steps are rarely rejected, and an
    // accepted step then needs no second pass over the points. A trial
    // that puts an active point behind the camera counts as infinite cost.
    const SE3 T_trial = SE3::exp(delta) * *T;
    const bool trial_ok = linearize(c, K, T_trial, &lin_trial_);
    const double cost_trial = trial_ok ? lin_trial_.cost : std::numeric_limits<double>::infinity();
    const double model_decrease = -(delta.dot(lin_.g) + 0.5 * delta.dot(lin_.H * delta));
    const double actual_decrease = lin_.cost - cost_trial;
    const double ratio = actual_decrease / model_decrease;
    if (trial_ok && model_decrease > 0 && ratio > 0) {
      *T = T_trial;
      lin_ = lin_trial_;
      s->final_cost = lin_.cost;
      if (actual_decrease <= options_.function_tolerance * (lin_.cost + actual_decrease))
        return RoundEnd::kConverged;
      const double t = 2.0 * ratio - 1.0;
      u *= std::max(1.0 / 3.0, 1.0 - t * t * t);
      v = 2.0;
    } else {
      if (trial_ok && std::abs(actual_decrease) <= options_.function_tolerance * lin_.cost)
        return RoundEnd::kConverged;
      u *= v;
      v *= 2.0;
    }
  }
  return RoundEnd::kMaxIterations;
}

// ORB-SLAM's rejection: every valid correspondence (outliers included) is
// tested at the new pose, so a point wrongly rejected early can come back.
// lin_ (at T, from the round just run) is updated by the few points that
// change sides, so the next round needs no full linearisation.
int PoseSolver::classify(const Correspondences& c, const Pinhole& K, const SE3& T, bool* changed) {
  int n = 0;
  *changed = false;
  Vec2 r;
  for (int i = 0; i < c.count; ++i) {
    std::uint8_t in = 0;
    if (valid_[i] && reprojection_residual(K, T, c.p_model[i], c.px_ideal[i], options_.min_depth_mm,
                                           &r, nullptr))
      in = c.info(i) * r.squaredNorm() < options_.chi2_threshold ? 1 : 0;
    if (in != inlier_[i]) {
      *changed = true;
      lin_current_ = lin_current_ && update_linearization(c, K, T, i, in ? 1.0 : -1.0);
    }
    inlier_[i] = in;
    n += in;
  }
  if (*changed && lin_current_) mirror_upper(&lin_.H);
  return n;
}

// Adds (sign +1) or removes (sign -1) observation i's terms in lin_ (upper
// triangle of H; the caller mirrors). False if it cannot be evaluated.
bool PoseSolver::update_linearization(const Correspondences& c, const Pinhole& K, const SE3& T,
                                      int i, double sign) {
  Vec2 r;
  Mat26 J;
  if (!reprojection_residual(K, T, c.p_model[i], c.px_ideal[i], options_.min_depth_mm, &r, &J))
    return false;
  const double info = c.info(i);
  double weight;
  lin_.cost += sign * 0.5 * huber(info * r.squaredNorm(), options_.huber_delta, &weight);
  accumulate(J, r, sign * info * weight, &lin_.H, &lin_.g);
  return true;
}

void PoseSolver::fill_quality(const Correspondences& c, const Pinhole& K, const SE3& T,
                              Summary* s) const {
  Mat6 H = Mat6::Zero();
  Vec6 g = Vec6::Zero();
  double sum_r2 = 0;
  Vec2 r;
  Mat26 J;
  for (int i = 0; i < c.count; ++i) {
    if (!inlier_[i]) continue;
    if (!reprojection_residual(K, T, c.p_model[i], c.px_ideal[i], options_.min_depth_mm, &r, &J))
      continue;
    accumulate(J, r, c.info(i), &H, &g);
    sum_r2 += r.squaredNorm();
  }
  mirror_upper(&H);
  s->hessian = H;
  s->rms_reprojection_px = s->num_inliers > 0 ? std::sqrt(sum_r2 / s->num_inliers) : -1.0;
  // Unobservable directions (degenerate geometry) show as a near-zero
  // eigenvalue; the covariance is then not a quality measure.
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(H, Eigen::EigenvaluesOnly);
  if (eig.info() != Eigen::Success || !(eig.eigenvalues()[0] > 1e-10 * eig.eigenvalues()[5]))
    return;
  const Eigen::LLT<Mat6> llt(H);
  if (llt.info() != Eigen::Success) return;
  s->covariance = llt.solve(Mat6::Identity());
  if (!s->covariance.allFinite()) return;
  s->covariance_valid = true;
  const Eigen::SelfAdjointEigenSolver<Mat3> rot(s->covariance.topLeftCorner<3, 3>(),
                                                Eigen::EigenvaluesOnly);
  const Eigen::SelfAdjointEigenSolver<Mat3> pos(s->covariance.bottomRightCorner<3, 3>(),
                                                Eigen::EigenvaluesOnly);
  s->sigma_rotation_deg = std::sqrt(std::max(0.0, rot.eigenvalues()[2])) * 180.0 / M_PI;
  s->sigma_position_mm = std::sqrt(std::max(0.0, pos.eigenvalues()[2]));
}

bool PoseSolver::solve(const Correspondences& c, const Pinhole& K, SE3* T_camera_model,
                       Summary* summary) {
  Summary local;
  Summary& s = summary ? *summary : local;
  s = Summary{};
  s.num_correspondences = c.count;
  last_count_ = 0;
  if (!configured_) return (s.status = PoseStatus::kNotConfigured), false;
  if (c.count > capacity()) return (s.status = PoseStatus::kTooManyPoints), false;
  if (c.count < options_.min_inliers || !c.p_model || !c.px_ideal)
    return (s.status = PoseStatus::kTooFewPoints), false;
  if (!T_camera_model || !T_camera_model->all_finite() || !pinhole_is_usable(K))
    return (s.status = PoseStatus::kNonFiniteInput), false;
  last_count_ = c.count;
  lin_current_ = false;
  const int in_front = count_usable(c, K, *T_camera_model);
  for (int i = 0; i < c.count; ++i) s.num_valid += valid_[i];
  s.status = s.num_valid < options_.min_inliers ? PoseStatus::kTooFewPoints
             : in_front < options_.min_inliers  ? PoseStatus::kPointsBehindCamera
                                                : PoseStatus::kConverged;
  SE3 T = *T_camera_model;
  RoundEnd end = RoundEnd::kConverged;
  for (int round = 0; round < options_.rounds && s.pose_written(); ++round) {
    end = run_round(c, K, &T, &s);
    ++s.rounds;
    bool changed = false;
    if (end == RoundEnd::kFailed) {
      s.status = PoseStatus::kNumericalFailure;
    } else if ((s.num_inliers = classify(c, K, T, &changed)) < options_.min_inliers) {
      s.status = PoseStatus::kTooFewInliers;
    } else if (!changed && end == RoundEnd::kConverged) {
      break;  // another round would solve the same problem from the same pose
    }
  }
  if (!s.pose_written()) {
    std::memset(inlier_.data(), 0, static_cast<std::size_t>(c.count));
    return false;
  }
  if (end == RoundEnd::kMaxIterations) s.status = PoseStatus::kNotConverged;
  *T_camera_model = SE3(Quat(T.rotation()), T.translation());  // re-orthonormalised
  fill_quality(c, K, *T_camera_model, &s);
  return true;
}

}  // namespace st
