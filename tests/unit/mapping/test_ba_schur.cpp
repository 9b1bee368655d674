// The window BA's own Schur-complement solver (core/mapping/schur_solver.h)
// against the Ceres form it replaced (core/mapping_ceres/ceres_form.h), on the bench
// window and on perturbed windows: the same window and start must give the
// same solution (poses within 1e-4 deg / 1e-4 mm, points within 1e-3 mm);
// no allocation per solve; bad jobs refused with a reason; the focal
// scale's Jacobian against central differences.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "core/mapping/ba_residuals.h"
#include "core/mapping/bundle_adjustment.h"
#include "core/mapping_ceres/ceres_form.h"
#include "support/alloc_guard.h"
#include "support/ba_window.h"
#include "support/raster_scene.h"
#include "support/track_scene.h"

using namespace st;
using namespace st::test;

namespace {

struct Difference {
  double rot_deg = 0, centre_mm = 0, point_mm = 0;
};

// Largest differences between two solutions of one window.
Difference difference(const BaJob& a, const BaJob& b) {
  Difference d;
  for (int k = 0; k < a.keyframe_count; ++k) {
    d.rot_deg = std::max(d.rot_deg, pose_delta(a.pose(k), b.pose(k)).angle_deg);
    d.centre_mm = std::max(d.centre_mm, (a.pose(k).inverse().translation() - b.pose(k).inverse().translation()).norm());
  }
  for (int i = 0; i < a.point_count; ++i) d.point_mm = std::max(d.point_mm, (a.point(i) - b.point(i)).norm());
  return d;
}

// Solves one job with both forms (same options otherwise); returns the
// Schur solution in *schur and the Ceres one in *ceres.
void solve_both(BundleAdjusterOptions o, const Mesh& mesh, const Pinhole& K, const BaJob& job, BaJob* schur,
                BaJob* ceres) {
  o.max_time_s = 10.0;  // iterations alone bound both (Ceres' clock would otherwise vary)
  BundleAdjuster a, b;
  REQUIRE(a.configure(o, mesh, K, job.keyframe_capacity(), job.point_capacity(), job.observation_capacity()).ok());
  REQUIRE(configure_ceres_form(&b, o, mesh, K, job.keyframe_capacity(), job.point_capacity(),
                               job.observation_capacity()).ok());
  *schur = job;
  *ceres = job;
  const bool ok_schur = a.solve(schur), ok_ceres = b.solve(ceres);
  CHECK(ok_schur == ok_ceres);
}

void check_agreement(const BaJob& schur, const BaJob& ceres, const std::string& what) {
  const Difference d = difference(schur, ceres);
  MESSAGE(what << ": " << schur.summary.iterations << " / " << ceres.summary.iterations << " iterations, cost "
               << schur.summary.final_cost << " / " << ceres.summary.final_cost << "; largest differences "
               << d.rot_deg << " deg, " << d.centre_mm << " mm, points " << d.point_mm << " mm");
  CHECK(schur.summary.usable == ceres.summary.usable);
  CHECK(schur.summary.iterations == ceres.summary.iterations);
  CHECK(schur.summary.final_cost == doctest::Approx(ceres.summary.final_cost).epsilon(1e-9));
  CHECK(d.rot_deg < 1e-4);
  CHECK(d.centre_mm < 1e-4);
  CHECK(d.point_mm < 1e-3);
}

}  // namespace

TEST_CASE("ba schur: the bench window gives the Ceres form's solution") {
  const Mesh mesh = load_liver_for_tracking();
  const Pinhole K = bench_pinhole();
  const BaWindow w = make_ba_window(mesh, K, BaWindowSpec{});
  REQUIRE(w.job.point_count > 900);
  for (const double w_shape : {100.0, 0.0}) {
    BundleAdjusterOptions o;
    o.w_shape = w_shape;
    BaJob schur, ceres;
    solve_both(o, mesh, K, w.job, &schur, &ceres);
    check_agreement(schur, ceres, "bench window, w_shape " + std::to_string(static_cast<int>(w_shape)));
  }
}

TEST_CASE("ba schur: perturbed windows, caps, the exact shape residual and more iterations agree with Ceres") {
  const Mesh mesh = load_liver_for_tracking();
  const Pinhole K = track_test_pinhole();
  for (std::uint32_t seed = 2; seed <= 4; ++seed) {
    BaWindowSpec spec;
    spec.points = 400;
    spec.seed = seed;
    spec.pose_rot_deg = 0.5 * seed;  // 1 .. 2 deg
    spec.pose_trans_mm = 1.5 * seed;
    spec.point_mm = 0.5 * seed;
    spec.fixed_keyframes = seed == 3 ? 0 : 2;  // 0: the oldest keyframe holds the gauge
    const BaWindow w = make_ba_window(mesh, K, spec);
    BundleAdjusterOptions o;
    o.max_iterations = 20;
    o.relative_gradient_tolerance = seed == 4 ? 0.0 : 1e-4;  // 0: Ceres' own stops alone
    o.max_observations_per_point = seed == 2 ? 4 : 0;
    o.exact_shape = seed == 3;
    BaJob schur, ceres;
    solve_both(o, mesh, K, w.job, &schur, &ceres);
    check_agreement(schur, ceres, "seed " + std::to_string(seed));
  }
}

TEST_CASE("ba schur: the prior test and the focal test give the Ceres form's decisions and solutions") {
  const Mesh mesh = load_liver_for_tracking();
  const Pinhole K = track_test_pinhole();
  BaWindowSpec spec;
  spec.points = 500;
  spec.fixed_keyframes = 0;
  BaWindow w = make_ba_window(mesh, K, spec);
  // A registration 1 deg / 2 mm off for the prior: the whole map moved by G.
  const SE3 G(so3_exp(1.0 * M_PI / 180.0 * Vec3(1, 1, 1).normalized()), 2.0 * Vec3(1, -1, 1).normalized());
  for (int k = 0; k < w.job.keyframe_count; ++k)
    pose_to_params(w.job.pose(k) * G, w.job.keyframes[static_cast<std::size_t>(k)].pose);
  for (int i = 0; i < w.job.point_count; ++i) {
    const Vec3 p = G.inverse() * w.job.point(i);
    std::memcpy(w.job.points[static_cast<std::size_t>(i)].p_model, p.data(), sizeof(double) * 3);
  }
  REQUIRE(w.job.set_prior(0, w.job.pose(0), 0.5 * M_PI / 180.0, 1.0));
  w.job.test_focal = true;
  Pinhole K_long = K;  // focal lengths 5 % long: the focal test has something to find
  K_long.fx *= 1.05;
  K_long.fy *= 1.05;
  BaJob schur, ceres;
  solve_both(BundleAdjusterOptions{}, mesh, K_long, w.job, &schur, &ceres);
  check_agreement(schur, ceres, "prior and focal test");
  MESSAGE("prior F " << schur.summary.prior_f << " / " << ceres.summary.prior_f << ", focal s "
                     << schur.summary.focal_scale << " / " << ceres.summary.focal_scale << ", F "
                     << schur.summary.focal_f << " / " << ceres.summary.focal_f);
  CHECK(schur.summary.prior_tested);
  CHECK(schur.summary.prior_used == ceres.summary.prior_used);
  CHECK(schur.summary.prior_f == doctest::Approx(ceres.summary.prior_f).epsilon(1e-6));
  CHECK(schur.summary.focal_tested);
  CHECK(ceres.summary.focal_tested);
  CHECK(std::abs(schur.summary.focal_scale - ceres.summary.focal_scale) < 1e-7);
  CHECK(schur.summary.focal_f == doctest::Approx(ceres.summary.focal_f).epsilon(1e-6));
}

TEST_CASE("ba schur: no allocation per solve after configure (window, prior, focal test)") {
  const Mesh mesh = load_liver_for_tracking();
  const Pinhole K = bench_pinhole();
  BaWindow w = make_ba_window(mesh, K, BaWindowSpec{});
  BundleAdjuster ba;
  REQUIRE(ba.configure(BundleAdjusterOptions{}, mesh, K, w.job.keyframe_capacity(), w.job.point_capacity(),
                       w.job.observation_capacity())
              .ok());
  const BaJob pristine = w.job;
  BaJob with_tests = w.job;
  REQUIRE(with_tests.set_prior(2, with_tests.pose(2), 0.01, 1.0));
  with_tests.test_focal = true;
  for (const BaJob* job : {&pristine, static_cast<const BaJob*>(&with_tests), &pristine}) {
    w.job = *job;  // (the copy assigns into the configured arrays: no allocation either, but outside the count)
    ba.forget_planes();
    const AllocationCounter counter;
    CHECK(ba.solve(&w.job));
    CHECK(counter.count() == 0u);
  }
}

TEST_CASE("ba schur: bad jobs are refused with a reason, never solved") {
  const Mesh mesh = load_liver_for_tracking();
  const Pinhole K = track_test_pinhole();
  BaWindowSpec spec;
  spec.points = 100;
  const BaWindow w = make_ba_window(mesh, K, spec);
  BundleAdjuster ba;
  BaJob job = w.job;
  CHECK_FALSE(ba.solve(&job));
  CHECK(job.summary.refusal == BaRefusal::kNotConfigured);
  // Configured for one keyframe, point and observation fewer than the window has.
  REQUIRE(ba.configure(BundleAdjusterOptions{}, mesh, K, w.job.keyframe_count - 1, w.job.point_capacity(),
                       w.job.observation_capacity())
              .ok());
  const auto refused = [&](BaJob j, BaRefusal why) {
    const AllocationCounter counter;
    CHECK_FALSE(ba.solve(&j));
    CHECK(counter.count() == 0u);
    CHECK(j.summary.refusal == why);
    CHECK_FALSE(j.summary.usable);
    CHECK(std::strlen(ba_refusal_text(j.summary.refusal)) > 20);
  };
  refused(w.job, BaRefusal::kTooBig);
  REQUIRE(ba.configure(BundleAdjusterOptions{}, mesh, K, w.job.keyframe_capacity(), w.job.point_count - 1,
                       w.job.observation_capacity())
              .ok());
  refused(w.job, BaRefusal::kTooBig);
  REQUIRE(ba.configure(BundleAdjusterOptions{}, mesh, K, w.job.keyframe_capacity(), w.job.point_capacity(),
                       w.job.observation_count - 1)
              .ok());
  refused(w.job, BaRefusal::kTooBig);
  REQUIRE(ba.configure(BundleAdjusterOptions{}, mesh, K, w.job.keyframe_capacity(), w.job.point_capacity(),
                       w.job.observation_capacity())
              .ok());
  job = w.job;
  job.clear();
  refused(job, BaRefusal::kEmpty);
  job = w.job;
  job.keyframes[3].pose[4] = std::nan("");
  refused(job, BaRefusal::kNotFinite);
  job = w.job;
  job.points[7].p_model[2] = std::numeric_limits<double>::infinity();
  refused(job, BaRefusal::kNotFinite);
  job = w.job;
  job.observations[5].info = std::nan("");
  refused(job, BaRefusal::kNotFinite);
  job = w.job;
  job.observations[5].keyframe = job.keyframe_count;
  refused(job, BaRefusal::kBadIndex);
  job = w.job;
  REQUIRE(job.set_prior(0, job.pose(0), 0.01, 1.0));
  job.prior.sigma_rad = 0;
  refused(job, BaRefusal::kBadPrior);
  // Every point behind every camera: nothing passes the depth test.
  job = w.job;
  for (int i = 0; i < job.point_count; ++i) job.points[static_cast<std::size_t>(i)].p_model[2] -= 1e4;
  refused(job, BaRefusal::kNothingToSolve);
  // A good job still solves after all that.
  job = w.job;
  CHECK(ba.solve(&job));
  CHECK(job.summary.refusal == BaRefusal::kNone);
}

// The focal scale's Jacobian the solvers use: d r / d s = (r + sqrt_info (q - c)) / s
// for the whitened reprojection through fx s, fy s (principal point kept).
TEST_CASE("ba schur: the focal scale's Jacobian matches central differences") {
  const Pinhole K = track_test_pinhole();
  const SE3 T(so3_exp(Vec3(0.1, -0.2, 0.05)), Vec3(3, -2, 150));
  const double f[3] = {4.0, -6.0, 10.0}, delta[6] = {0, 0, 0, 0, 0, 0};
  const Vec2 q(333.0, 170.0);
  const double sqrt_info = 1.0 / 1.2;
  for (const double s : {1.0, 0.93, 1.08}) {
    const auto residual = [&](double scale) {
      Pinhole Ks = K;
      Ks.fx *= scale;
      Ks.fy *= scale;
      Vec2 r;
      REQUIRE(reprojection_cost(Ks, q, sqrt_info, 1.0, T, delta, f, r.data(), nullptr, nullptr));
      return r;
    };
    const Vec2 r = residual(s);
    const Vec2 analytic = (r + sqrt_info * (q - Vec2(K.cx, K.cy))) / s;
    const double h = 1e-6;
    const Vec2 numeric = (residual(s + h) - residual(s - h)) / (2 * h);
    CHECK((analytic - numeric).norm() < 1e-6 * std::max(1.0, analytic.norm()));
  }
}
