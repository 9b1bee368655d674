#include "core/mapping/schur_solver.h"

#include <Eigen/Cholesky>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace st {

namespace {

using Mat33r = Eigen::Matrix<double, 3, 3, Eigen::RowMajor>;

// Huber's rho(s) of the squared norm s (Ceres' HuberLoss: s inside the
// threshold, 2 delta sqrt(s) - delta^2 beyond) and sqrt(rho'(s)), the
// factor Ceres' corrector puts on the residual and the Jacobian (rho'' <= 0
// everywhere: no curvature term).
double huber(double s, double delta, double* sqrt_rho1) {
  if (s > delta * delta) {
    const double r = std::sqrt(s);
    *sqrt_rho1 = std::sqrt(std::max(std::numeric_limits<double>::min(), delta / r));
    return 2.0 * delta * r - delta * delta;
  }
  *sqrt_rho1 = 1.0;
  return s;
}

template <typename V>
V clamp_diagonal(const V& d, double lo, double hi) {
  return d.cwiseMax(lo).cwiseMin(hi);
}

// The lower triangle of M += A B^T (A, B n x 2). The blocks of the normal
// equations and of the reduced system are symmetric, and every reader
// takes their lower triangle (the Cholesky, the point blocks' inverse), so
// the upper one is never formed: 21 of the 36 entries of a pose block.
template <int N>
inline void add_lower_abt(const Eigen::Matrix<double, N, 2>& A, const Eigen::Matrix<double, N, 2>& B,
                          Eigen::Matrix<double, N, N>* M) {
  for (int c = 0; c < N; ++c)
    for (int r = c; r < N; ++r) (*M)(r, c) += A(r, 0) * B(c, 0) + A(r, 1) * B(c, 1);
}

}  // namespace

Status SchurSolver::configure(int max_keyframes, int max_points, int max_observations) {
  configured_ = set_up_ = false;
  if (max_keyframes < 1 || max_points < 1 || max_observations < 1)
    return make_error("schur solver: capacities must be >= 1 (" + std::to_string(max_keyframes) + " keyframes, " +
                      std::to_string(max_points) + " points, " + std::to_string(max_observations) +
                      " observations)");
  if (max_keyframes > kMaxKeyframes)  // an observation's keyframe and column are 16-bit
    return make_error("schur solver: at most " + std::to_string(kMaxKeyframes) + " keyframes (" +
                      std::to_string(max_keyframes) + " asked)");
  const auto nk = static_cast<std::size_t>(max_keyframes), np = static_cast<std::size_t>(max_points);
  const auto no = static_cast<std::size_t>(max_observations);
  T0_.assign(nk, SE3());
  column_.assign(nk, -1);
  x_pose_.assign(nk, Vec6::Zero());
  cand_pose_ = step_pose_ = g_pose_ = diag_pose_ = U_focal_ = x_pose_;
  lin_pose_.assign(nk, PoseLinearization{});
  U_.assign(nk, Mat6::Zero());
  U_obs_diag_.assign(nk, Vec6::Zero());
  active_.assign(np, 0);
  active_points_.assign(np, 0);
  shape_.assign(np, ShapeKind::kNone);
  plane_.assign(np, ShapePlane{});
  x_point_.assign(np, Vec3::Zero());
  cand_point_ = step_point_ = g_point_ = diag_point_ = W_focal_ = shape_r_ = x_point_;
  V_.assign(np, Mat3::Zero());
  V_inv_ = shape_J_ = V_;
  first_obs_.assign(np + 1, 0);
  obs_.assign(no, Observation{});
  order_.assign(no, 0);
  lin_obs_.assign(no, Linearization{});
  S_blocks_.assign(nk * nk, Mat6::Zero());
  const int max_columns = 6 * max_keyframes + 1;
  S_.setZero(max_columns, max_columns);
  rhs_.setZero(max_columns);
  max_keyframes_ = max_keyframes;
  max_points_ = max_points;
  max_observations_ = max_observations;
  configured_ = true;
  return Status::Ok();
}

bool SchurSolver::begin(const SchurResidualConfig& residuals, int keyframe_count, int point_count, bool free_focal) {
  set_up_ = false;
  if (!configured_ || keyframe_count < 1 || keyframe_count > max_keyframes_ || point_count < 0 ||
      point_count > max_points_)
    return false;
  res_ = residuals;
  keyframe_count_ = keyframe_count;
  point_count_ = point_count;
  observation_count_ = 0;
  free_focal_ = free_focal;
  prior_keyframe_ = -1;
  x_focal_ = cand_focal_ = 1.0;
  for (int k = 0; k < keyframe_count; ++k) set_keyframe(k, SE3(), true);
  for (int i = 0; i < point_count; ++i) active_[static_cast<std::size_t>(i)] = 0;
  set_up_ = true;
  return true;
}

void SchurSolver::set_keyframe(int keyframe, const SE3& T0_camera_model, bool held) {
  const auto k = static_cast<std::size_t>(keyframe);
  T0_[k] = T0_camera_model;
  column_[k] = held ? -1 : 0;  // free columns are numbered in prepare()
  x_pose_[k].setZero();
}

void SchurSolver::set_point(int point, const double* p_model, bool active, ShapeKind shape, const ShapePlane& plane) {
  const auto i = static_cast<std::size_t>(point);
  x_point_[i] = Vec3(p_model[0], p_model[1], p_model[2]);
  active_[i] = active ? 1 : 0;
  shape_[i] = shape;
  plane_[i] = plane;
}

bool SchurSolver::add_observation(int keyframe, int point, const Vec2& px_ideal, double info) {
  if (!set_up_ || observation_count_ >= max_observations_ || keyframe < 0 || keyframe >= keyframe_count_ ||
      point < 0 || point >= point_count_ || !(info > 0))
    return false;
  Observation& o = obs_[static_cast<std::size_t>(observation_count_++)];
  o.keyframe = static_cast<std::int16_t>(keyframe);
  o.point = point;
  o.px = px_ideal;
  o.sqrt_info = std::sqrt(info);
  return true;
}

void SchurSolver::set_prior(int keyframe, const Vec6& e0, const Vec6& weight) {
  prior_keyframe_ = keyframe;
  prior_e0_ = e0;
  prior_w_ = weight;
}

Vec6 SchurSolver::pose_delta(int keyframe) const { return x_pose_[static_cast<std::size_t>(keyframe)]; }

// Columns of the free keyframes (6 each, then the focal scale), held
// keyframes' fixed linearization, the observations sorted by point.
bool SchurSolver::prepare() {
  columns_ = 0;
  for (int k = 0; k < keyframe_count_; ++k) {
    const auto ks = static_cast<std::size_t>(k);
    if (column_[ks] < 0) {
      pose_linearization(T0_[ks], x_pose_[ks].data(), &lin_pose_[ks]);  // delta 0: T0
      continue;
    }
    column_[ks] = columns_;
    columns_ += 6;
  }
  if (free_focal_) ++columns_;
  if (prior_keyframe_ >= keyframe_count_ || (prior_keyframe_ >= 0 && column_[static_cast<std::size_t>(prior_keyframe_)] < 0))
    return false;
  return sort_observations();
}

// Counting sort by point (the Schur elimination visits a point's
// observations together), stable, in place: each observation's place from
// the counts, then the permutation applied cycle by cycle. False when an
// observation names an inactive point.
bool SchurSolver::sort_observations() {
  const auto np = static_cast<std::size_t>(point_count_);
  std::fill(first_obs_.begin(), first_obs_.begin() + static_cast<std::ptrdiff_t>(np + 1), 0);
  for (int i = 0; i < observation_count_; ++i) {
    const Observation& o = obs_[static_cast<std::size_t>(i)];
    if (!active_[static_cast<std::size_t>(o.point)]) return false;
    ++first_obs_[static_cast<std::size_t>(o.point) + 1];
  }
  int n_active = 0;
  for (std::size_t p = 0; p < np; ++p) {
    first_obs_[p + 1] += first_obs_[p];
    if (active_[p]) active_points_[static_cast<std::size_t>(n_active++)] = static_cast<std::int32_t>(p);
  }
  active_count_ = n_active;
  // Places: first_obs_[p] is advanced while numbering, then shifted back.
  for (int i = 0; i < observation_count_; ++i) {
    Observation& o = obs_[static_cast<std::size_t>(i)];
    o.column = static_cast<std::int16_t>(column_[static_cast<std::size_t>(o.keyframe)]);
    order_[static_cast<std::size_t>(i)] = first_obs_[static_cast<std::size_t>(o.point)]++;
  }
  for (int i = 0; i < observation_count_; ++i) {
    const auto is = static_cast<std::size_t>(i);
    while (order_[is] != i) {  // the one here goes to its place; what was there comes here
      const auto d = static_cast<std::size_t>(order_[is]);
      std::swap(obs_[is], obs_[d]);
      std::swap(order_[is], order_[d]);
    }
  }
  for (std::size_t p = np; p > 0; --p) first_obs_[p] = first_obs_[p - 1];
  first_obs_[0] = 0;
  return true;
}

void SchurSolver::clear_normal_equations() {
  for (int k = 0; k < keyframe_count_; ++k) {
    const auto ks = static_cast<std::size_t>(k);
    U_[ks].setZero();
    U_obs_diag_[ks].setZero();
    g_pose_[ks].setZero();
    U_focal_[ks].setZero();
  }
  for (int a = 0; a < active_count_; ++a) {
    const auto p = static_cast<std::size_t>(active_points_[static_cast<std::size_t>(a)]);
    V_[p].setZero();
    g_point_[p].setZero();
    W_focal_[p].setZero();
  }
  g_focal_ = U_ff_ = 0.0;
}

// Cost (Ceres' 0.5 sum rho) at x or at the candidate; with linearize, also
// the corrected residuals and Jacobians and the normal equations' blocks at
// x. False when a residual cannot be evaluated (a point behind a camera,
// a closest-point query failing), as Ceres' evaluation fails.
bool SchurSolver::evaluate(bool candidate, bool linearize, double* cost) {
  if (linearize) clear_normal_equations();
  for (int k = 0; k < keyframe_count_; ++k) {
    const auto ks = static_cast<std::size_t>(k);
    if (column_[ks] >= 0)
      pose_linearization(T0_[ks], (candidate ? cand_pose_ : x_pose_)[ks].data(), &lin_pose_[ks]);
  }
  *cost = 0.0;
  if (!evaluate_observations(candidate, linearize, cost) || !evaluate_shapes(candidate, linearize, cost)) return false;
  *cost += evaluate_prior(candidate, linearize);
  return std::isfinite(*cost);
}

bool SchurSolver::evaluate_observations(bool candidate, bool linearize, double* cost) {
  const double s = candidate ? cand_focal_ : x_focal_;
  Pinhole K = res_.K;
  if (free_focal_) K.fx *= s, K.fy *= s;
  const Vec2 c(res_.K.cx, res_.K.cy);
  const std::vector<Vec3>& points = candidate ? cand_point_ : x_point_;
  double sum = 0.0;
  for (int i = 0; i < observation_count_; ++i) {
    const Observation& o = obs_[static_cast<std::size_t>(i)];
    const bool free_pose = o.column >= 0;
    const auto p = static_cast<std::size_t>(o.point), k = static_cast<std::size_t>(o.keyframe);
    Linearization& L = lin_obs_[static_cast<std::size_t>(i)];
    Vec2 r;
    // Row-major 2 x 6 and 2 x 3 Jacobians land as their transposes G, H.
    if (!reprojection_cost(K, o.px, o.sqrt_info, res_.min_depth_mm, lin_pose_[k], points[p].data(), r.data(),
                           linearize && free_pose ? L.G.data() : nullptr, linearize ? L.H.data() : nullptr))
      return false;
    double w = 1.0;
    sum += 0.5 * huber(r.squaredNorm(), res_.reprojection_huber, &w);
    if (!linearize) continue;
    L.r = w * r;
    if (w != 1.0) L.H *= w;
    add_lower_abt<3>(L.H, L.H, &V_[p]);
    g_point_[p].noalias() += L.H * L.r;
    if (free_pose) {
      if (w != 1.0) L.G *= w;
      U_obs_diag_[k] += L.G.rowwise().squaredNorm();  // the block itself: in eliminate_point()
      g_pose_[k].noalias() += L.G * L.r;
    }
    if (!free_focal_) continue;
    // d r / d s = sqrt_info f xn = (r + sqrt_info (q - c)) / s (the Ceres form's).
    L.J_focal = w * (r + o.sqrt_info * (o.px - c)) / s;
    U_ff_ += L.J_focal.squaredNorm();
    g_focal_ += L.J_focal.dot(L.r);
    W_focal_[p].noalias() += L.H * L.J_focal;
    if (free_pose) U_focal_[k].noalias() += L.G * L.J_focal;
  }
  *cost += sum;
  return true;
}

bool SchurSolver::evaluate_shapes(bool candidate, bool linearize, double* cost) {
  const std::vector<Vec3>& points = candidate ? cand_point_ : x_point_;
  double sum = 0.0;
  for (int a = 0; a < active_count_; ++a) {
    const auto p = static_cast<std::size_t>(active_points_[static_cast<std::size_t>(a)]);
    if (shape_[p] == ShapeKind::kNone) continue;
    if (shape_[p] == ShapeKind::kPlane) {
      // One row, r = sqrt_w n . (f - foot), J = sqrt_w n^T: a rank-one block.
      double r2[2];
      plane_cost(plane_[p], res_.sqrt_w_shape, points[p].data(), r2, nullptr);
      double w = 1.0;
      sum += 0.5 * huber(r2[0] * r2[0], res_.shape_huber, &w);
      if (!linearize) continue;
      const Vec3 j = (w * res_.sqrt_w_shape) * plane_[p].normal;
      shape_r_[p] = Vec3(w * r2[0], 0.0, 0.0);
      shape_J_[p].setZero();
      shape_J_[p].row(0) = j.transpose();
      for (int c = 0; c < 3; ++c)
        for (int q = c; q < 3; ++q) V_[p](q, c) += j[q] * j[c];
      g_point_[p].noalias() += j * shape_r_[p][0];
      continue;
    }
    Vec3 r = Vec3::Zero();
    Mat33r J = Mat33r::Zero();
    if (!res_.surface ||
        !shape_cost(*res_.surface, res_.sqrt_w_shape, points[p].data(), r.data(), linearize ? J.data() : nullptr))
      return false;
    double w = 1.0;
    sum += 0.5 * huber(r.squaredNorm(), res_.shape_huber, &w);
    if (!linearize) continue;
    shape_r_[p] = w * r;
    shape_J_[p] = w * J;
    V_[p].noalias() += shape_J_[p].transpose() * shape_J_[p];
    g_point_[p].noalias() += shape_J_[p].transpose() * shape_r_[p];
  }
  *cost += sum;
  return true;
}

double SchurSolver::evaluate_prior(bool candidate, bool linearize) {
  if (prior_keyframe_ < 0) return 0.0;
  const auto k = static_cast<std::size_t>(prior_keyframe_);
  const Vec6 r = prior_w_.cwiseProduct((candidate ? cand_pose_ : x_pose_)[k] + prior_e0_);
  if (linearize) {
    U_[k].diagonal() += prior_w_.cwiseAbs2();
    g_pose_[k] += prior_w_.cwiseProduct(r);
  }
  return 0.5 * r.squaredNorm();
}

double SchurSolver::gradient_max_norm() const {
  double m = free_focal_ ? std::abs(g_focal_) : 0.0;
  for (int k = 0; k < keyframe_count_; ++k)
    if (column_[static_cast<std::size_t>(k)] >= 0) m = std::max(m, g_pose_[static_cast<std::size_t>(k)].cwiseAbs().maxCoeff());
  for (int a = 0; a < active_count_; ++a)
    m = std::max(m, g_point_[static_cast<std::size_t>(active_points_[static_cast<std::size_t>(a)])].cwiseAbs().maxCoeff());
  return m;
}

// The norm of one set of values over the free parameters: the focal scale
// when free, the free poses, the active points.
double SchurSolver::free_norm(double focal, const std::vector<Vec6>& pose, const std::vector<Vec3>& point) const {
  double sq = free_focal_ ? focal * focal : 0.0;
  for (int k = 0; k < keyframe_count_; ++k)
    if (column_[static_cast<std::size_t>(k)] >= 0) sq += pose[static_cast<std::size_t>(k)].squaredNorm();
  for (int a = 0; a < active_count_; ++a)
    sq += point[static_cast<std::size_t>(active_points_[static_cast<std::size_t>(a)])].squaredNorm();
  return std::sqrt(sq);
}

double SchurSolver::parameter_norm() const { return free_norm(x_focal_, x_pose_, x_point_); }

double SchurSolver::step_norm() const { return free_norm(step_focal_, step_pose_, step_point_); }

// The LM step at the current linearization: (J^T J + mu D) step = -g with
// D the clamped diagonal of J^T J (taken anew after an accepted step, kept
// after a rejected one), points eliminated, the reduced camera system by
// an in-place Cholesky of its lower triangle. False when the system is not
// positive definite or the step not finite (Ceres: an invalid step).
bool SchurSolver::compute_step(double radius, bool new_diagonal, const SchurSolverOptions& o) {
  if (new_diagonal) {
    for (int k = 0; k < keyframe_count_; ++k)
      diag_pose_[static_cast<std::size_t>(k)] =
          clamp_diagonal(Vec6(U_[static_cast<std::size_t>(k)].diagonal() + U_obs_diag_[static_cast<std::size_t>(k)]),
                         o.min_lm_diagonal, o.max_lm_diagonal);
    for (int a = 0; a < active_count_; ++a) {
      const auto p = static_cast<std::size_t>(active_points_[static_cast<std::size_t>(a)]);
      diag_point_[p] = clamp_diagonal(Vec3(V_[p].diagonal()), o.min_lm_diagonal, o.max_lm_diagonal);
    }
    diag_focal_ = std::min(std::max(U_ff_, o.min_lm_diagonal), o.max_lm_diagonal);
  }
  mu_ = 1.0 / radius;
  const int n = columns_;
  const int nb = free_keyframes_ = (free_focal_ ? n - 1 : n) / 6;
  S_.topLeftCorner(n, n).setZero();
  for (int a = 0; a < nb; ++a)
    for (int b = 0; b < a; ++b) S_blocks_[static_cast<std::size_t>(a * nb + b)].setZero();
  for (int k = 0; k < keyframe_count_; ++k) {
    const auto ks = static_cast<std::size_t>(k);
    const int c = column_[ks];
    if (c < 0) continue;
    Mat6& D = S_blocks_[static_cast<std::size_t>((c / 6) * (nb + 1))];
    D = U_[ks];
    D.diagonal() += mu_ * diag_pose_[ks];
    rhs_.segment<6>(c) = -g_pose_[ks];
    if (free_focal_) S_.block<1, 6>(n - 1, c) = U_focal_[ks].transpose();
  }
  if (free_focal_) {
    S_(n - 1, n - 1) = U_ff_ + mu_ * diag_focal_;
    rhs_(n - 1) = -g_focal_;
  }
  for (int a = 0; a < active_count_; ++a) eliminate_point(active_points_[static_cast<std::size_t>(a)]);
  for (int a = 0; a < nb; ++a)
    for (int b = 0; b <= a; ++b) S_.block<6, 6>(6 * a, 6 * b) = S_blocks_[static_cast<std::size_t>(a * nb + b)];
  if (n > 0) {
    Eigen::Ref<Eigen::MatrixXd> A(S_.topLeftCorner(n, n));
    const Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>, Eigen::Lower> llt(A);
    if (llt.info() != Eigen::Success) return false;
    llt.solveInPlace(rhs_.head(n));
    if (!rhs_.head(n).allFinite()) return false;
  }
  for (int k = 0; k < keyframe_count_; ++k) {
    const auto ks = static_cast<std::size_t>(k);
    if (column_[ks] >= 0) step_pose_[ks] = rhs_.segment<6>(column_[ks]);
  }
  step_focal_ = free_focal_ ? rhs_(n - 1) : 0.0;
  return back_substitute();
}

// Point p's part of the reduced system: S -= W V^-1 W^T, rhs += W V^-1 g_p,
// W = J_pose^T J_point per observation, never formed: the 6x6 block of
// observations i, j is G_i A G_j^T with A = Q_i^T H_j (2x2), G = J_pose^T,
// H = J_point^T, Q = V^-1 H. Only the lower triangle of S is kept (the
// Cholesky reads no other). Each observation's own G_i G_i^T (the pose
// block of the normal equations) is added here too.
void SchurSolver::eliminate_point(int point) {
  const auto p = static_cast<std::size_t>(point);
  Mat3 Vd = V_[p].selfadjointView<Eigen::Lower>();
  Vd.diagonal() += mu_ * diag_point_[p];
  const Mat3 V_inv = Vd.inverse();
  V_inv_[p] = V_inv;
  const Vec3 vg = V_inv * g_point_[p];
  const int f = columns_ - 1;  // the focal column, when free
  const Vec3 vf = V_inv * W_focal_[p];
  const int first = first_obs_[p], last = first_obs_[p + 1];
  const int nb = free_keyframes_;
  for (int i = first; i < last; ++i) {
    const int ci = obs_[static_cast<std::size_t>(i)].column;
    if (ci < 0) continue;
    const Linearization& Li = lin_obs_[static_cast<std::size_t>(i)];
    const Eigen::Matrix<double, 3, 2> Qi = V_inv * Li.H;
    rhs_.segment<6>(ci).noalias() += Li.G * (Li.H.transpose() * vg);
    if (free_focal_) S_.block<1, 6>(f, ci).noalias() -= (Li.G * (Li.H.transpose() * vf)).transpose();
    for (int j = first; j <= i; ++j) {
      const int cj = obs_[static_cast<std::size_t>(j)].column;
      if (cj < 0) continue;
      const Linearization& Lj = lin_obs_[static_cast<std::size_t>(j)];
      const Eigen::Matrix2d A = Qi.transpose() * Lj.H;  // block (i, j) = G_i A G_j^T
      if (i == j) {  // the observation's own J^T J less G_i A G_i^T: G_i (I - A) G_i^T, its lower triangle
        const Eigen::Matrix<double, 6, 2> B = Li.G * (Eigen::Matrix2d::Identity() - A.transpose());
        add_lower_abt<6>(Li.G, B, &S_blocks_[static_cast<std::size_t>((ci / 6) * (nb + 1))]);
      } else if (ci > cj) {
        const Eigen::Matrix<double, 6, 2> B = Lj.G * A.transpose();
        S_blocks_[static_cast<std::size_t>((ci / 6) * nb + cj / 6)].noalias() -= Li.G * B.transpose();
      } else if (ci < cj) {
        const Eigen::Matrix<double, 6, 2> B = Li.G * A;  // the transpose: G_j A^T G_i^T
        S_blocks_[static_cast<std::size_t>((cj / 6) * nb + ci / 6)].noalias() -= Lj.G * B.transpose();
      } else {  // two observations from one keyframe: both orders land on the diagonal block
        const Eigen::Matrix<double, 6, 2> B = Lj.G * A.transpose();
        const Mat6 M = Li.G * B.transpose();
        S_blocks_[static_cast<std::size_t>((ci / 6) * (nb + 1))] -= M + M.transpose();
      }
    }
  }
  if (free_focal_) {
    S_(f, f) -= W_focal_[p].dot(vf);
    rhs_(f) += W_focal_[p].dot(vg);
  }
}

// step_p = V^-1 (-g_p - sum_i J_point_i^T J_pose_i step_pose - W_focal step_focal),
// and with it the part of the model's decrease (see model_cost_change())
// of the point's residuals (its observations and its shape residual): a
// point's observations are in cache once, so the linearization is streamed
// through once per step, not twice.
bool SchurSolver::back_substitute() {
  bool finite = std::isfinite(step_focal_);
  double change = 0.0;
  for (int a = 0; a < active_count_; ++a) {
    const auto p = static_cast<std::size_t>(active_points_[static_cast<std::size_t>(a)]);
    const int first = first_obs_[p], last = first_obs_[p + 1];
    Vec3 b = -g_point_[p] - W_focal_[p] * step_focal_;
    for (int i = first; i < last; ++i) {
      const Observation& o = obs_[static_cast<std::size_t>(i)];
      if (o.column < 0) continue;
      const Linearization& L = lin_obs_[static_cast<std::size_t>(i)];
      b.noalias() -= L.H * (L.G.transpose() * step_pose_[static_cast<std::size_t>(o.keyframe)]);
    }
    const Vec3 d = V_inv_[p] * b;
    step_point_[p] = d;
    finite = finite && d.allFinite();
    for (int i = first; i < last; ++i) {
      const Observation& o = obs_[static_cast<std::size_t>(i)];
      const Linearization& L = lin_obs_[static_cast<std::size_t>(i)];
      Vec2 Jd = L.H.transpose() * d;
      if (o.column >= 0) Jd.noalias() += L.G.transpose() * step_pose_[static_cast<std::size_t>(o.keyframe)];
      if (free_focal_) Jd += L.J_focal * step_focal_;
      change -= Jd.dot(L.r + 0.5 * Jd);
    }
    if (shape_[p] != ShapeKind::kNone) {
      const Vec3 Js = shape_J_[p] * d;
      change -= Js.dot(shape_r_[p] + 0.5 * Js);
    }
  }
  point_model_change_ = change;
  return finite;
}

// Decrease of the linear model: -(J step) . (r + J step / 2), summed over
// the residuals (Ceres' model_cost_change); the points' residuals' part
// comes from back_substitute(), the pose prior's is added here.
double SchurSolver::model_cost_change() const {
  double change = point_model_change_;
  if (prior_keyframe_ >= 0) {
    const auto k = static_cast<std::size_t>(prior_keyframe_);
    const Vec6 Jd = prior_w_.cwiseProduct(step_pose_[k]);
    const Vec6 r = prior_w_.cwiseProduct(x_pose_[k] + prior_e0_);
    change -= Jd.dot(r + 0.5 * Jd);
  }
  return change;
}

void SchurSolver::make_candidate() {
  for (int k = 0; k < keyframe_count_; ++k) {
    const auto ks = static_cast<std::size_t>(k);
    if (column_[ks] >= 0) cand_pose_[ks] = x_pose_[ks] + step_pose_[ks];
  }
  for (int a = 0; a < active_count_; ++a) {
    const auto p = static_cast<std::size_t>(active_points_[static_cast<std::size_t>(a)]);
    cand_point_[p] = x_point_[p] + step_point_[p];
  }
  cand_focal_ = x_focal_ + step_focal_;
}

void SchurSolver::accept_candidate() {
  for (int k = 0; k < keyframe_count_; ++k) {
    const auto ks = static_cast<std::size_t>(k);
    if (column_[ks] >= 0) x_pose_[ks] = cand_pose_[ks];
  }
  for (int a = 0; a < active_count_; ++a) {
    const auto p = static_cast<std::size_t>(active_points_[static_cast<std::size_t>(a)]);
    x_point_[p] = cand_point_[p];
  }
  x_focal_ = cand_focal_;
}

// One LM iteration from the linearization at x (Ceres' trust-region loop
// with its LM strategy): step, candidate, acceptance, radius update.
SchurSolver::Iteration SchurSolver::iterate(const SchurSolverOptions& o, LmState* s) {
  Iteration it;
  it.cost = s->cost;
  double change = 0.0;
  const bool valid = compute_step(s->radius, s->new_diagonal, o) && (change = model_cost_change()) > 0.0;
  s->new_diagonal = false;
  if (!valid) {
    if (++s->invalid_steps >= o.max_invalid_steps) it.end = IterationEnd::kFailure;
    s->radius /= s->decrease;
    s->decrease *= 2.0;
    return it;
  }
  s->invalid_steps = 0;
  make_candidate();
  // The candidate is evaluated with its Jacobians, in place: an accepted
  // step then needs no second evaluation (its cost and linearization are
  // the ones at the new x, bit for bit); a rejected one evaluates x again
  // (the same numbers as before the step). One set of the per-observation
  // linearization instead of two: 7 MB of the mapping thread's memory at
  // 40,000 observations. Convergence ends the solve without the
  // linearization at x: nothing reads it after.
  double candidate_cost = 0.0;
  const bool candidate_ok = evaluate(true, true, &candidate_cost);
  if (!candidate_ok) candidate_cost = std::numeric_limits<double>::max();
  if (s->any_success && step_norm() <= o.parameter_tolerance * (parameter_norm() + o.parameter_tolerance)) {
    it.end = IterationEnd::kConverged;
    return it;
  }
  if (std::abs(s->cost - candidate_cost) <= o.function_tolerance * s->cost) {
    it.end = IterationEnd::kConverged;
    return it;
  }
  const double rho = (s->cost - candidate_cost) / change;
  if (!(rho > o.min_relative_decrease)) {
    it.cost = candidate_cost;  // Ceres reports a rejected step's cost (its final_cost is the minimum)
    double cost_at_x = 0.0;
    if (!evaluate(false, true, &cost_at_x)) it.end = IterationEnd::kFailure;  // evaluated before: not expected
    s->radius /= s->decrease;
    s->decrease *= 2.0;
    return it;
  }
  accept_candidate();
  s->cost = candidate_cost;
  it.cost = s->cost;
  it.success = true;
  s->any_success = s->new_diagonal = true;
  s->gradient_max_norm = gradient_max_norm();
  s->radius = std::min(o.max_radius, s->radius / std::max(1.0 / 3.0, 1.0 - std::pow(2.0 * rho - 1.0, 3)));
  s->decrease = 2.0;
  return it;
}

// Ceres' checks after an iteration (its callbacks first: the relative
// gradient stop), in its order.
bool SchurSolver::keep_going(const SchurSolverOptions& o, const LmState& s, int iteration, bool success,
                             std::int64_t t0_ns) const {
  if (iteration > 0 && success && o.relative_gradient_tolerance > 0 &&
      s.gradient_max_norm <= o.relative_gradient_tolerance * s.start_gradient_max_norm)
    return false;
  if (o.now_ns && elapsed_s(t0_ns, o) >= o.max_time_s) return false;
  if (iteration >= o.max_iterations) return false;
  if (success && s.gradient_max_norm <= o.gradient_tolerance) return false;
  return s.radius > o.min_radius;
}

bool SchurSolver::solve(const SchurSolverOptions& o, SchurSolverSummary* out) {
  *out = SchurSolverSummary{};
  const std::int64_t t0_ns = o.now_ns ? o.now_ns() : 0;
  if (!set_up_ || !prepare()) return false;
  out->parameters = columns_ + 3 * active_count_;
  out->residuals = 2 * observation_count_ + (prior_keyframe_ >= 0 ? 6 : 0);
  for (int a = 0; a < active_count_; ++a) {
    const ShapeKind kind = shape_[static_cast<std::size_t>(active_points_[static_cast<std::size_t>(a)])];
    out->residuals += kind == ShapeKind::kPlane ? 2 : kind == ShapeKind::kExact ? 3 : 0;
  }
  LmState s;
  s.radius = o.initial_radius;
  if (!evaluate(false, true, &s.cost)) {
    out->solver_ms = elapsed_s(t0_ns, o) * 1e3;
    return false;
  }
  out->initial_cost = out->final_cost = s.cost;
  out->usable = true;
  s.gradient_max_norm = s.start_gradient_max_norm = gradient_max_norm();
  int iteration = 0;
  for (bool go = keep_going(o, s, 0, true, t0_ns); go;) {
    const Iteration it = iterate(o, &s);
    if (it.end == IterationEnd::kFailure) out->usable = false;
    if (it.end != IterationEnd::kContinue) break;
    ++iteration;
    out->final_cost = std::min(out->final_cost, it.cost);
    go = keep_going(o, s, iteration, it.success, t0_ns);
  }
  out->iterations = iteration + 1;
  out->solver_ms = elapsed_s(t0_ns, o) * 1e3;
  return out->usable;
}

double SchurSolver::elapsed_s(std::int64_t t0_ns, const SchurSolverOptions& o) const {
  return o.now_ns ? static_cast<double>(o.now_ns() - t0_ns) * 1e-9 : 0.0;
}

}  // namespace st
