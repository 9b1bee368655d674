#include "core/mapping/bundle_adjustment.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <utility>

#include "core/base/capacity.h"
#include "core/geometry/reprojection.h"

namespace st {

BundleAdjuster::BundleAdjuster() = default;
BundleAdjuster::~BundleAdjuster() = default;

void BundleAdjuster::use_reference(std::unique_ptr<BaReferenceSolver> solver) { reference_ = std::move(solver); }

namespace {

bool options_in_range(const BundleAdjusterOptions& o) {
  return o.w_shape >= 0 && std::isfinite(o.w_shape) && o.shape_huber_mm > 0 && o.reprojection_huber > 0 &&
         o.max_iterations >= 1 && o.max_time_s > 0 && o.min_depth_mm > 0 && o.max_point_shift_mm > 0 &&
         o.surface_distance_samples >= 0 && o.max_observations_per_point >= 0 &&
         o.relative_gradient_tolerance >= 0 && o.relative_gradient_tolerance < 1 &&
         o.max_observations_per_point <= kMaxObservationsPerPointCap && o.max_fixed_observations_per_point >= 0 &&
         o.max_fixed_observations_per_point <= kMaxObservationsPerPointCap && o.min_observations_per_point >= 1 &&
         o.min_observations_per_point <= 255 && o.plane_reuse_mm >= 0 && o.prior_release_f >= 0 &&
         std::isfinite(o.prior_release_f);
}

}  // namespace

Status BundleAdjuster::configure(const BundleAdjusterOptions& options, const Mesh& mesh, const Pinhole& K,
                                 int max_keyframes, int max_points, int max_observations) {
  configured_ = false;
  if (!options_in_range(options))
    return make_error("bundle adjustment: options out of range (w_shape >= 0, thresholds and limits > 0)");
  if (!pinhole_is_usable(K)) return make_error("bundle adjustment: the pinhole is not usable");
  if (max_keyframes < 1 || max_keyframes > kMaxKeyframes || max_points < 1 || max_points > kMaxMapPoints ||
      max_observations < 1)
    return make_error("bundle adjustment: capacities out of range (" + std::to_string(max_keyframes) + " keyframes, " +
                      std::to_string(max_points) + " points, " + std::to_string(max_observations) +
                      " observations)");
  if (Status s = surface_.configure(mesh); !s.ok()) return make_error("bundle adjustment: " + s.message());
  options_ = options;
  K_ = K;
  const auto nk = static_cast<std::size_t>(max_keyframes), np = static_cast<std::size_t>(max_points);
  planes_.assign(np, ShapePlane{});
  plane_cache_.assign(np, CachedPlane{});
  point_observed_.assign(np, 0);
  shape_used_.assign(np, 0);
  observation_used_.assign(static_cast<std::size_t>(max_observations), 0);
  held_.assign(nk, 0);
  T0_.assign(nk, SE3());
  deltas_.assign(nk * 6, 0.0);
  saved_poses_.assign(nk * kPoseParams, 0.0);
  saved_points_.assign(np * 3, 0.0);
  newest_frames_.assign(np * static_cast<std::size_t>(std::max(1, options.max_observations_per_point)), -1);
  newest_fixed_frames_.assign(np * static_cast<std::size_t>(std::max(1, options.max_fixed_observations_per_point)), -1);
  reference_.reset();
  if (Status s = schur_.configure(max_keyframes, max_points, max_observations); !s.ok())
    return make_error("bundle adjustment: " + s.message());
  max_keyframes_ = max_keyframes;
  max_points_ = max_points;
  max_observations_ = max_observations;
  configured_ = true;
  return Status::Ok();
}


// Counts within the maxima, indices in range, values finite.
BaRefusal BundleAdjuster::check(const BaJob& job) const {
  if (!configured_) return BaRefusal::kNotConfigured;
  if (job.keyframe_count < 1 || job.point_count < 1) return BaRefusal::kEmpty;
  if (job.keyframe_count > max_keyframes_ || job.point_count > max_points_ ||
      job.observation_count > max_observations_ || job.observation_count < 0)
    return BaRefusal::kTooBig;
  for (int i = 0; i < job.keyframe_count; ++i)
    if (!job.pose(i).all_finite()) return BaRefusal::kNotFinite;
  for (int i = 0; i < job.point_count; ++i)
    if (!job.point(i).allFinite()) return BaRefusal::kNotFinite;
  for (int i = 0; i < job.observation_count; ++i) {
    const BaObservation& o = job.observations[static_cast<std::size_t>(i)];
    if (o.keyframe < 0 || o.keyframe >= job.keyframe_count || o.point < 0 || o.point >= job.point_count)
      return BaRefusal::kBadIndex;
    if (!std::isfinite(o.x_ideal) || !std::isfinite(o.y_ideal) || !(o.info > 0) || !std::isfinite(o.info))
      return BaRefusal::kNotFinite;
  }
  const BaPosePrior& prior = job.prior;
  if (prior.keyframe >= job.keyframe_count || !pose_from_params(prior.pose).all_finite() ||
      (prior.keyframe >= 0 && !pose_prior_sigmas_usable(prior.sigma_rad, prior.sigma_mm)))
    return BaRefusal::kBadPrior;
  return BaRefusal::kNone;
}

// What joins this solve, for either solver: the held keyframes (fixed,
// the prior's while it is tested, the gauge), whether the prior residual
// is on, the points (select_points), the observations and the shape
// residuals. Returns the number of reprojection residuals.
int BundleAdjuster::select(BaJob* job, bool free_prior, FocalTest focal) {
  const bool focal_test = focal != FocalTest::kNone;
  focal_ = focal;
  int fixed = 0, oldest = 0;
  for (int i = 0; i < job->keyframe_count; ++i) {
    const BaKeyframe& k = job->keyframes[static_cast<std::size_t>(i)];
    T0_[static_cast<std::size_t>(i)] = job->pose(i);
    std::fill(pose_delta_block(i), pose_delta_block(i) + 6, 0.0);
    const bool hold = k.fixed && !focal_test;
    held_[static_cast<std::size_t>(i)] = hold ? 1 : 0;
    fixed += hold ? 1 : 0;
    if (k.frame < job->keyframes[static_cast<std::size_t>(oldest)].frame) oldest = i;
  }
  // A job with a pose prior is solved twice (solve()). Held: the prior's
  // keyframe is held where it is. Freed: with the shape residual on, the
  // prior fixes the frame itself (the mesh fixes the structure's pose and
  // scale, the prior the directions the observations leave open), so no
  // keyframe is held and the prior's keyframe moves too. Without a prior
  // the oldest keyframe is held for the gauge when the job holds none.
  // The focal test's solves hold nothing and take no prior: the mesh alone
  // fixes the gauge, so that a rigid misplacement of the whole map (a
  // coarse registration) is taken up by the poses in both of them, not by
  // the focal length in one (held, a 2 deg / 4 mm registration looked like
  // focal lengths 6 % short at F 195).
  const int prior_kf = focal_test ? -1 : job->prior.keyframe;
  use_prior_ = free_prior && prior_kf >= 0 && !held_[static_cast<std::size_t>(prior_kf)];
  if (prior_kf >= 0 && !free_prior && !held_[static_cast<std::size_t>(prior_kf)]) {
    held_[static_cast<std::size_t>(prior_kf)] = 1;
    ++fixed;
  }
  if (fixed == 0 && !use_prior_ && !focal_test) {  // gauge: hold the oldest keyframe
    held_[static_cast<std::size_t>(oldest)] = 1;
    fixed = 1;
  }
  job->summary.fixed_keyframes = fixed;
  if (options_.max_observations_per_point > 0)
    newest_frames_per_point(*job, options_.max_observations_per_point, false, &newest_frames_);
  if (options_.max_fixed_observations_per_point > 0)
    newest_frames_per_point(*job, options_.max_fixed_observations_per_point, true, &newest_fixed_frames_);
  select_points(job);
  int used = 0;
  for (int i = 0; i < job->observation_count; ++i) {
    const BaObservation& o = job->observations[static_cast<std::size_t>(i)];
    const bool use = point_observed_[static_cast<std::size_t>(o.point)] && observation_used_[static_cast<std::size_t>(i)];
    observation_used_[static_cast<std::size_t>(i)] = use ? 1 : 0;
    if (!use) continue;
    ++used;
    if (job->keyframes[static_cast<std::size_t>(o.keyframe)].fixed) ++job->summary.fixed_observations;
  }
  select_shapes(job);
  return used;
}

// Hands this solve (select()) to the Schur solver; false when it refuses.
bool BundleAdjuster::load_schur(const BaJob& job) {
  SchurResidualConfig r;
  r.K = K_;
  r.min_depth_mm = options_.min_depth_mm;
  r.reprojection_huber = options_.reprojection_huber;
  r.sqrt_w_shape = std::sqrt(options_.w_shape);
  r.shape_huber = r.sqrt_w_shape * options_.shape_huber_mm;
  r.surface = &surface_;
  if (!schur_.begin(r, job.keyframe_count, job.point_count, focal_ == FocalTest::kFree)) return false;
  for (int i = 0; i < job.keyframe_count; ++i)
    schur_.set_keyframe(i, T0_[static_cast<std::size_t>(i)], held_[static_cast<std::size_t>(i)] != 0);
  using Shape = SchurSolver::ShapeKind;
  const Shape shape = options_.exact_shape ? Shape::kExact : Shape::kPlane;
  for (int i = 0; i < job.point_count; ++i) {
    const auto is = static_cast<std::size_t>(i);
    schur_.set_point(i, job.points[is].p_model, point_observed_[is] != 0, shape_used_[is] ? shape : Shape::kNone,
                     planes_[is]);
  }
  for (int i = 0; i < job.observation_count; ++i) {
    if (!observation_used_[static_cast<std::size_t>(i)]) continue;
    const BaObservation& o = job.observations[static_cast<std::size_t>(i)];
    if (!schur_.add_observation(o.keyframe, o.point, Vec2(o.x_ideal, o.y_ideal), o.info)) return false;
  }
  if (use_prior_) {
    const int k = job.prior.keyframe;
    Vec6 w;
    w << Vec3::Constant(1.0 / job.prior.sigma_rad), Vec3::Constant(1.0 / job.prior.sigma_mm);
    schur_.set_prior(k, (job.pose(k) * pose_from_params(job.prior.pose).inverse()).log(), w);
  }
  return true;
}

// point_observed_[i] = 1 for the points that join the problem: at least
// min_observations_per_point usable observations. With one view a point's 2
// reprojection rows (+1 shape row) are met exactly by its own 3 unknowns for
// any pose, so it tells the poses nothing (and a point made from one
// keyframe's ray and the mesh depth already sits at that optimum); tracker
// windows hold thousands of such points (half the blocks of a solve).
void BundleAdjuster::select_points(BaJob* job) {
  for (int i = 0; i < job->point_count; ++i) point_observed_[static_cast<std::size_t>(i)] = 0;
  for (int i = 0; i < job->observation_count; ++i) {  // saturating counts
    const BaObservation& o = job->observations[static_cast<std::size_t>(i)];
    const bool usable = usable_observation(*job, o);
    observation_used_[static_cast<std::size_t>(i)] = usable ? 1 : 0;  // select() adds the point's test
    std::uint8_t& n = point_observed_[static_cast<std::size_t>(o.point)];
    if (n < 255 && usable) ++n;
  }
  for (int i = 0; i < job->point_count; ++i) {
    std::uint8_t& n = point_observed_[static_cast<std::size_t>(i)];
    if (n > 0 && n < options_.min_observations_per_point) ++job->summary.points_skipped;
    n = n >= options_.min_observations_per_point ? 1 : 0;
  }
}

// Per point, the frames of its cap newest observing keyframes (only the
// fixed ones when fixed_only; descending, -1 padded) by insertion into a
// fixed row: allocates nothing.
void BundleAdjuster::newest_frames_per_point(const BaJob& job, int cap, bool fixed_only,
                                             std::vector<std::int32_t>* rows) const {
  const auto n = static_cast<std::size_t>(cap);
  std::fill(rows->begin(), rows->begin() + static_cast<std::ptrdiff_t>(static_cast<std::size_t>(job.point_count) * n), -1);
  for (int i = 0; i < job.observation_count; ++i) {
    const BaObservation& o = job.observations[static_cast<std::size_t>(i)];
    const BaKeyframe& k = job.keyframes[static_cast<std::size_t>(o.keyframe)];
    if (fixed_only && !k.fixed) continue;
    std::int32_t frame = k.frame;
    std::int32_t* row = &(*rows)[static_cast<std::size_t>(o.point) * n];
    for (std::size_t j = 0; j < n; ++j)
      if (frame > row[j]) std::swap(frame, row[j]);
  }
}

// Passes the caps and is in front of its keyframe (the solvers need a valid start).
bool BundleAdjuster::usable_observation(const BaJob& job, const BaObservation& o) const {
  if (!keep_observation(job, o)) return false;
  const Vec3 p_camera = T0_[static_cast<std::size_t>(o.keyframe)] * job.point(o.point);
  return p_camera.z() > options_.min_depth_mm;
}

// The observation caps (the rows hold the newest frames; keyframe frames
// are distinct, so at most cap observations of a point pass each).
bool BundleAdjuster::keep_observation(const BaJob& job, const BaObservation& o) const {
  const BaKeyframe& k = job.keyframes[static_cast<std::size_t>(o.keyframe)];
  const auto point = static_cast<std::size_t>(o.point);
  const int cap = options_.max_observations_per_point, cap_fixed = options_.max_fixed_observations_per_point;
  if (cap > 0 && k.frame < newest_frames_[point * static_cast<std::size_t>(cap) + static_cast<std::size_t>(cap - 1)])
    return false;
  if (k.fixed && cap_fixed > 0 &&
      k.frame < newest_fixed_frames_[point * static_cast<std::size_t>(cap_fixed) + static_cast<std::size_t>(cap_fixed - 1)])
    return false;
  return true;
}

// shape_used_[i] = 1 for the points of the problem that get a shape
// residual: all of them in the exact form, those with a tangent plane in
// the plane form (planes_).
void BundleAdjuster::select_shapes(BaJob* job) {
  for (int i = 0; i < job->point_count; ++i) {
    const auto is = static_cast<std::size_t>(i);
    bool use = options_.w_shape > 0 && point_observed_[is];
    if (use && !options_.exact_shape) use = plane_for(job->points[is], &planes_[is], &job->summary.plane_queries);
    shape_used_[is] = use ? 1 : 0;
  }
}

// The tangent plane at p's start value: kept from an earlier solve while p
// stayed near where it was taken (tracker windows overlap: most points come
// back unchanged or moved by BA a fraction of a mm), else one query.
bool BundleAdjuster::plane_for(const BaPoint& p, ShapePlane* plane, int* queries) {
  const Vec3 f(p.p_model[0], p.p_model[1], p.p_model[2]);
  const bool cacheable = options_.plane_reuse_mm > 0 && p.id >= 0 && p.id < static_cast<int>(plane_cache_.size());
  if (cacheable) {
    const CachedPlane& c = plane_cache_[static_cast<std::size_t>(p.id)];
    if (c.valid && c.created_frame == p.created_frame && (c.at - f).norm() <= options_.plane_reuse_mm) {
      *plane = c.plane;
      return true;
    }
  }
  ++*queries;
  if (!shape_plane(surface_, f, plane)) return false;
  if (cacheable) plane_cache_[static_cast<std::size_t>(p.id)] = CachedPlane{true, p.created_frame, f, *plane};
  return true;
}

void BundleAdjuster::forget_planes() {
  for (CachedPlane& c : plane_cache_) c.valid = false;
}

bool BundleAdjuster::solve_once(BaJob* job, bool free_prior, int max_iterations, double max_time_s,
                                SolveStats* stats, FocalTest focal) {
  job->summary = BaSummary{};
  const int used = select(job, free_prior, focal);
  job->summary.keyframes = job->keyframe_count;
  job->summary.points = job->point_count;
  job->summary.observations = used;
  if (used == 0) {
    job->summary.refusal = BaRefusal::kNothingToSolve;
    return false;
  }
  const SolverRun run =
      reference_ ? reference_->run(*this, job, max_iterations, max_time_s) : run_schur(job, max_iterations, max_time_s);
  apply_pose_deltas(job);
  finish(job, run.initial_cost, run.final_cost, run.total_s, run.iterations, run.usable);
  // The focal test's solves are undone (test_focal()): no statistic of theirs is kept.
  if (focal == FocalTest::kNone)
    job->summary.mean_surface_distance_mm = mean_surface_distance(*job, options_.surface_distance_samples);
  if (stats) *stats = SolveStats{run.residuals, run.parameters};
  return job->summary.usable;
}

// The Schur solver: the solution copied back into the job's points, the
// pose deltas and the focal scale (allocates nothing).
BundleAdjuster::SolverRun BundleAdjuster::run_schur(BaJob* job, int max_iterations, double max_time_s) {
  SolverRun run;
  if (!load_schur(*job)) return run;
  SchurSolverOptions o;
  o.max_iterations = max_iterations > 0 ? max_iterations : options_.max_iterations;
  o.max_time_s = max_time_s > 0 ? max_time_s : options_.max_time_s;
  o.relative_gradient_tolerance = options_.relative_gradient_tolerance;
  o.now_ns = options_.now_ns;
  SchurSolverSummary s;
  schur_.solve(o, &s);
  for (int i = 0; i < job->point_count; ++i) {
    if (!point_observed_[static_cast<std::size_t>(i)]) continue;
    const Vec3 p = schur_.point(i);
    for (int c = 0; c < 3; ++c) job->points[static_cast<std::size_t>(i)].p_model[c] = p[c];
  }
  for (int k = 0; k < job->keyframe_count; ++k) {
    const Vec6 d = schur_.pose_delta(k);
    for (int c = 0; c < 6; ++c) pose_delta_block(k)[c] = d[c];
  }
  focal_scale_[0] = schur_.focal_scale();
  run.initial_cost = s.initial_cost;
  run.final_cost = s.final_cost;
  run.total_s = s.solver_ms * 1e-3;
  run.iterations = s.iterations;
  run.usable = s.usable;
  run.residuals = s.residuals;
  run.parameters = s.parameters;
  return run;
}

bool BundleAdjuster::solve(BaJob* job, int max_iterations, double max_time_s) {
  job->summary = BaSummary{};
  job->summary.refusal = check(*job);
  if (job->summary.refusal != BaRefusal::kNone) return false;
  if (job->kind == BaKind::kFocalTest) {  // the test alone: the job's points and poses come back as given
    if (!(options_.w_shape > 0)) {
      job->summary.refusal = BaRefusal::kNothingToSolve;  // no shape residual: no metric structure to test against
      return false;
    }
    test_focal(job, max_iterations, max_time_s);
    job->summary.keyframes = job->keyframe_count;
    job->summary.points = job->point_count;
    job->summary.usable = job->summary.focal_tested;
    return job->summary.usable;
  }
  if (!solve_tested_prior(job, max_iterations, max_time_s)) return false;
  if (job->test_focal && options_.w_shape > 0) test_focal(job, max_iterations, max_time_s);
  return job->summary.usable;
}

// The calibration's focal test: from the solved job, two more solves with
// the same budget and every keyframe free (see select()), one with the
// focal lengths held and one with a common scale s of them free; the
// solution itself is restored after. F = (C_held - C_free) / (C_free / dof), C their final
// costs (one parameter more): how much better the data fits another focal
// length. Under a right calibration and Gaussian noise F follows F(1, dof),
// P(F > 30) ~ 4e-8 for a window's thousands of residuals (see
// BaSummary::focal_f).
void BundleAdjuster::test_focal(BaJob* job, int max_iterations, double max_time_s) {
  const BaSummary kept = job->summary;
  save_solution(*job);
  bool ok = solve_once(job, false, max_iterations, max_time_s, nullptr, FocalTest::kHeld);
  const double held_cost = job->summary.final_cost;
  int iterations = job->summary.iterations;
  double solver_ms = job->summary.solver_ms;
  restore_solution(job);
  SolveStats stats;
  ok = solve_once(job, false, max_iterations, max_time_s, &stats, FocalTest::kFree) && ok;
  const double free_cost = job->summary.final_cost;
  iterations += job->summary.iterations;
  solver_ms += job->summary.solver_ms;
  restore_solution(job);
  const int dof = stats.residuals - stats.parameters;
  job->summary = kept;
  job->summary.iterations += iterations;
  job->summary.solver_ms += solver_ms;
  job->summary.focal_tested = ok && dof > 0 && free_cost > 0;
  if (!job->summary.focal_tested) return;
  job->summary.focal_scale = focal_scale_[0];
  job->summary.focal_f = std::max(0.0, held_cost - free_cost) / (free_cost / dof);
}

bool BundleAdjuster::solve_tested_prior(BaJob* job, int max_iterations, double max_time_s) {
  const int prior_kf = job->prior.keyframe;
  const bool test_prior = prior_kf >= 0 && options_.w_shape > 0 &&
                          !job->keyframes[static_cast<std::size_t>(prior_kf)].fixed;
  if (!test_prior) return solve_once(job, false, max_iterations, max_time_s, nullptr);
  // 1. The prior's keyframe held (the registration as given).
  if (!solve_once(job, false, max_iterations, max_time_s, nullptr)) return false;
  const BaSummary held = job->summary;
  save_solution(*job);
  // 2. From there, the prior's keyframe freed. Kept only if the data asks
  // for it (see BundleAdjusterOptions::prior_release_f).
  SolveStats stats;
  const bool ok = solve_once(job, true, max_iterations, max_time_s, &stats);
  const int dof = stats.residuals - stats.parameters;
  const double f =
      ok && dof > 0 && job->summary.final_cost > 0
          ? ((held.final_cost - job->summary.final_cost) / 6.0) / (job->summary.final_cost / dof)
          : 0.0;
  const bool release = ok && (options_.prior_release_f == 0 || f > options_.prior_release_f);
  if (!release) {
    restore_solution(job);
    const int iterations = job->summary.iterations;
    const double solver_ms = job->summary.solver_ms;
    job->summary = held;
    job->summary.iterations += iterations;
    job->summary.solver_ms += solver_ms;
  } else {
    job->summary.iterations += held.iterations;
    job->summary.solver_ms += held.solver_ms;
    job->summary.plane_queries += held.plane_queries;
  }
  job->summary.prior_tested = true;
  job->summary.prior_used = release;
  job->summary.prior_f = f;
  return job->summary.usable;
}

void BundleAdjuster::save_solution(const BaJob& job) {
  for (int i = 0; i < job.keyframe_count; ++i)
    std::copy_n(job.keyframes[static_cast<std::size_t>(i)].pose, kPoseParams,
                &saved_poses_[static_cast<std::size_t>(i) * kPoseParams]);
  for (int i = 0; i < job.point_count; ++i)
    std::copy_n(job.points[static_cast<std::size_t>(i)].p_model, 3,
                &saved_points_[static_cast<std::size_t>(i) * 3]);
}

void BundleAdjuster::restore_solution(BaJob* job) const {
  for (int i = 0; i < job->keyframe_count; ++i)
    std::copy_n(&saved_poses_[static_cast<std::size_t>(i) * kPoseParams], kPoseParams,
                job->keyframes[static_cast<std::size_t>(i)].pose);
  for (int i = 0; i < job->point_count; ++i)
    std::copy_n(&saved_points_[static_cast<std::size_t>(i) * 3], 3,
                job->points[static_cast<std::size_t>(i)].p_model);
}

double* BundleAdjuster::pose_delta_block(int keyframe) {
  return &deltas_[static_cast<std::size_t>(keyframe) * 6];
}

// The solved poses exp(delta) * T0 back into the job's quaternion blocks.
void BundleAdjuster::apply_pose_deltas(BaJob* job) {
  for (int i = 0; i < job->keyframe_count; ++i) {
    const double* d = pose_delta_block(i);
    Vec6 delta;
    for (int k = 0; k < 6; ++k) delta[k] = d[k];
    if (delta.isZero(0.0)) continue;  // fixed, or not moved: keep the handed-over values bit for bit
    pose_to_params(SE3::exp(delta) * job->pose(i), job->keyframes[static_cast<std::size_t>(i)].pose);
  }
}

// Summary, finiteness, and the per-point shift gate (a point moved too far
// gets its handed-over position back: the tracker keeps it unchanged).
void BundleAdjuster::finish(BaJob* job, double initial_cost, double final_cost, double total_s, int iterations,
                            bool usable) {
  BaSummary& out = job->summary;
  out.iterations = iterations;
  out.initial_cost = initial_cost;
  out.final_cost = final_cost;
  out.solver_ms = total_s * 1e3;
  bool finite = true;
  for (int i = 0; i < job->keyframe_count; ++i) finite = finite && job->pose(i).all_finite();
  for (int i = 0; i < job->point_count; ++i) {
    BaPoint& p = job->points[static_cast<std::size_t>(i)];
    const Vec3 now = job->point(i), before(p.p_initial[0], p.p_initial[1], p.p_initial[2]);
    if (!now.allFinite()) {
      finite = false;
      continue;
    }
    if ((now - before).norm() > options_.max_point_shift_mm) {
      for (int k = 0; k < 3; ++k) p.p_model[k] = p.p_initial[k];
      ++out.points_rejected;
    }
  }
  out.usable = finite && usable && final_cost <= initial_cost;
}

double BundleAdjuster::mean_surface_distance(const BaJob& job, int max_samples) const {
  double sum = 0;
  int n = 0;
  // A statistic for the log, not an input of the solve: a bounded sample
  // keeps it off the solve time (all 1000 points of a window: ~1.6 ms).
  const int step = max_samples > 0 ? std::max(1, (job.point_count + max_samples - 1) / max_samples) : 1;
  for (int i = 0; i < job.point_count; i += step) {
    SurfacePoint s;
    if (surface_.closest(job.point(i), &s)) {
      sum += s.distance_mm;
      ++n;
    }
  }
  return n > 0 ? sum / n : -1.0;
}

}  // namespace st
