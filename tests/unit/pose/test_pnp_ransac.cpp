#include <doctest/doctest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <set>

#include "core/pose/pnp_ransac.h"
#include "core/base/rng.h"
#include "support/alloc_guard.h"
#include "support/draws.h"
#include "support/pose_scene.h"

#ifdef SCOPETRACK_HAVE_CALIB3D
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#endif

using namespace st;
using st::test::camera_centre_distance_mm;
using st::test::make_liver_scene;
using st::test::PoseSceneOptions;

namespace {

PnpRansac configured_ransac(int capacity = 4096, PnpRansacOptions opt = {}) {
  PnpRansac ransac;
  REQUIRE(ransac.configure(capacity, opt).ok());
  return ransac;
}

st::test::PoseScene half_outlier_scene(std::uint32_t seed, int n = 500) {
  PoseSceneOptions o;
  o.num_points = n;
  o.outlier_ratio = 0.5;
  o.noise_px = 1.0;
  o.seed = seed;
  return make_liver_scene(o);
}

}  // namespace

TEST_CASE("pnp ransac: Pcg32 is deterministic and covers its range") {
  Pcg32 a(42), b(42), c(43), d(5);
  bool differs = false;
  std::set<std::uint32_t> seen;
  for (int i = 0; i < 1000; ++i) {
    const std::uint32_t x = a.next();
    CHECK(x == b.next());
    differs |= x != c.next();
    seen.insert(d.below(10));
  }
  CHECK(differs);
  CHECK(seen.size() == 10u);
  CHECK(*seen.rbegin() == 9u);
}

TEST_CASE("pnp ransac: 50% outliers, 1 px noise, liver geometry: < 0.5 deg, < 1 mm") {
  PnpRansac ransac = configured_ransac();
  double worst_deg = 0, worst_mm = 0;
  for (std::uint32_t seed = 1; seed <= 20; ++seed) {
    const auto scene = half_outlier_scene(seed);
    SE3 T;
    PnpRansacSummary s;
    REQUIRE(ransac.solve(scene.view(), scene.K, &T, &s));
    INFO("seed " << seed << " iterations " << s.iterations << " inliers " << s.num_inliers);
    CHECK(s.refined);
    worst_deg = std::max(worst_deg, pose_delta(T, scene.T_camera_model).angle_deg);
    worst_mm = std::max(worst_mm, camera_centre_distance_mm(T, scene.T_camera_model));
    int outliers_kept = 0, inliers_lost = 0;
    for (std::size_t i = 0; i < scene.p_model.size(); ++i) {
      outliers_kept += scene.is_outlier[i] && ransac.inliers()[i];
      inliers_lost += !scene.is_outlier[i] && ransac.inliers()[i] == 0;
    }
    CHECK(outliers_kept <= 2);  // an outlier displaced along its epipolar-free ray may fit
    CHECK(inliers_lost <= 25);  // ~5% of 250 by the 95% chi2 test
    // Adaptive stop: after the best hypothesis was found, no more samples
    // than the rule asks for at its inlier ratio w: log(0.01) / log(1 - w^4).
    const double w = s.hypothesis_inliers / static_cast<double>(s.num_valid);
    const double needed = std::ceil(std::log(0.01) / std::log(1 - w * w * w * w));
    CHECK(s.iterations <= std::max(needed, s.best_iteration + 1.0));
    CHECK(s.iterations >= std::min(needed, 1000.0));
  }
  MESSAGE("worst pose error over 20 scenes: " << worst_deg << " deg, camera centre " << worst_mm
                                              << " mm");
  CHECK(worst_deg < 0.5);
  CHECK(worst_mm < 1.0);
}

TEST_CASE("pnp ransac: deterministic, outlier-free input stops after few samples") {
  PnpRansac ransac = configured_ransac();
  const auto scene = half_outlier_scene(7);
  SE3 T1, T2;
  PnpRansacSummary s1, s2;
  REQUIRE(ransac.solve(scene.view(), scene.K, &T1, &s1));
  const std::vector<std::uint8_t> flags1(ransac.inliers().begin(), ransac.inliers().end());
  REQUIRE(ransac.solve(scene.view(), scene.K, &T2, &s2));
  CHECK(T1.matrix() == T2.matrix());
  CHECK(s1.iterations == s2.iterations);
  CHECK(std::equal(flags1.begin(), flags1.end(), ransac.inliers().begin()));

  PoseSceneOptions o;
  o.num_points = 200;
  o.noise_px = 0.5;
  const auto clean = make_liver_scene(o);
  PnpRansacSummary s;
  REQUIRE(ransac.solve(clean.view(), clean.K, &T1, &s));
  CHECK(s.iterations <= 10);
  CHECK(s.num_inliers >= 190);
}

TEST_CASE("pnp ransac: failures are reported and leave the pose alone") {
  const auto scene = half_outlier_scene(3);
  const SE3 T0 = SE3::exp((Vec6() << 0.1, 0.2, 0.3, 1, 2, 3).finished());
  SE3 T = T0;
  PnpRansacSummary s;
  PnpRansac unconfigured;
  CHECK_FALSE(unconfigured.solve(scene.view(), scene.K, &T, &s));
  CHECK(s.status == PnpRansacStatus::kNotConfigured);
  CHECK_FALSE(PnpRansac().configure(3).ok());
  PnpRansacOptions bad;
  bad.confidence = 1.0;
  CHECK_FALSE(PnpRansac().configure(100, bad).ok());

  PnpRansac small = configured_ransac(100);
  CHECK_FALSE(small.solve(scene.view(), scene.K, &T, &s));
  CHECK(s.status == PnpRansacStatus::kTooManyPoints);

  PnpRansac ransac = configured_ransac();
  Correspondences few = scene.view();
  few.count = 3;
  CHECK_FALSE(ransac.solve(few, scene.K, &T, &s));
  CHECK(s.status == PnpRansacStatus::kTooFewPoints);
  Pinhole K_bad = scene.K;
  K_bad.fy = std::numeric_limits<double>::quiet_NaN();
  CHECK_FALSE(ransac.solve(scene.view(), K_bad, &T, &s));
  CHECK(s.status == PnpRansacStatus::kInvalidCamera);

  // Observations unrelated to the points: no consensus.
  auto garbage = scene;
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> ux(0, 1279), uy(0, 719);
  for (auto& px : garbage.px_ideal) px = test::draw_vec2(ux, uy, rng);
  CHECK_FALSE(ransac.solve(garbage.view(), scene.K, &T, &s));
  CHECK(s.status == PnpRansacStatus::kNoConsensus);
  CHECK(s.iterations == ransac.options().max_iterations);
  CHECK(T.matrix() == T0.matrix());
  for (std::uint8_t f : ransac.inliers()) CHECK(f == 0);

  // NaN correspondences are skipped, the rest still solves.
  auto partly_nan = scene;
  for (int i = 0; i < 50; ++i)
    partly_nan.p_model[2 * i + 1].x() = std::numeric_limits<double>::quiet_NaN();
  REQUIRE(ransac.solve(partly_nan.view(), scene.K, &T, &s));
  CHECK(s.num_valid == 450);
  CHECK(pose_delta(T, scene.T_camera_model).angle_deg < 0.5);
  for (int i = 0; i < 50; ++i) CHECK(ransac.inliers()[2 * i + 1] == 0);
}

TEST_CASE("pnp ransac: solve allocates nothing after configure") {
  PnpRansac ransac = configured_ransac();
  const auto scene = half_outlier_scene(11, 1500);
  SE3 T;
  PnpRansacSummary s;
  REQUIRE(ransac.solve(scene.view(), scene.K, &T, &s));  // warm-up
  const test::AllocationCounter allocations;
  for (int k = 0; k < 10; ++k) CHECK(ransac.solve(scene.view(), scene.K, &T, &s));
  CHECK(allocations.count() == 0);
}

#ifdef SCOPETRACK_HAVE_CALIB3D
TEST_CASE("pnp ransac: accuracy and time next to cv::solvePnPRansac (report)") {
  PnpRansac ransac = configured_ransac();
  const cv::Matx33d K(1000, 0, 639.5, 0, 1000, 359.5, 0, 0, 1);
  double ours_deg = 0, cv_deg = 0, ours_mm = 0, cv_mm = 0, ours_ms = 0, cv_ms = 0;
  const int scenes = 10;
  for (std::uint32_t seed = 1; seed <= scenes; ++seed) {
    const auto scene = half_outlier_scene(seed);
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (std::size_t i = 0; i < scene.p_model.size(); ++i) {
      object.emplace_back(scene.p_model[i].x(), scene.p_model[i].y(), scene.p_model[i].z());
      image.emplace_back(scene.px_ideal[i].x(), scene.px_ideal[i].y());
    }
    SE3 T;
    auto t0 = std::chrono::steady_clock::now();
    REQUIRE(ransac.solve(scene.view(), scene.K, &T, nullptr));
    auto t1 = std::chrono::steady_clock::now();
    cv::Mat rvec, tvec;
    REQUIRE(cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, 1000, 2.45f,
                               0.99, cv::noArray(), cv::SOLVEPNP_P3P));
    auto t2 = std::chrono::steady_clock::now();
    cv::Mat R;
    cv::Rodrigues(rvec, R);
    Mat3 Re;
    Vec3 te;
    cv::cv2eigen(R, Re);
    cv::cv2eigen(tvec, te);
    ours_deg += pose_delta(T, scene.T_camera_model).angle_deg / scenes;
    ours_mm += camera_centre_distance_mm(T, scene.T_camera_model) / scenes;
    cv_deg += pose_delta(SE3(Re, te), scene.T_camera_model).angle_deg / scenes;
    cv_mm += camera_centre_distance_mm(SE3(Re, te), scene.T_camera_model) / scenes;
    ours_ms += std::chrono::duration<double, std::milli>(t1 - t0).count() / scenes;
    cv_ms += std::chrono::duration<double, std::milli>(t2 - t1).count() / scenes;
  }
  MESSAGE("mean over " << scenes << " scenes (500 corr., 50% outliers, 1 px): ours " << ours_deg
                       << " deg " << ours_mm << " mm (camera centre) " << ours_ms
                       << " ms; cv::solvePnPRansac(P3P) " << cv_deg << " deg " << cv_mm << " mm "
                       << cv_ms << " ms");
  CHECK(ours_deg < 0.5);
  CHECK(ours_mm < 1.0);
}
#endif
