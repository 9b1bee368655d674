#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "core/pose/p3p.h"
#include "support/draws.h"

#ifdef SCOPETRACK_HAVE_CALIB3D
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>
#endif

using namespace st;

namespace {

struct P3PCase {
  SE3 T_camera_model;
  std::array<Vec3, 3> p_model, bearing;
};

// Random pose, three points 20-200 mm in front of the camera within a
// ~70 deg field of view, expressed in the model frame.
P3PCase random_case(std::mt19937& rng) {
  std::uniform_real_distribution<double> u(-1.0, 1.0), depth(20.0, 200.0);
  Vec6 xi;
  xi << 3 * u(rng), 3 * u(rng), 3 * u(rng), 200 * u(rng), 200 * u(rng), 200 * u(rng);
  P3PCase c;
  c.T_camera_model = SE3::exp(xi);
  const SE3 T_model_camera = c.T_camera_model.inverse();
  for (int i = 0; i < 3; ++i) {
    const Vec2 xy = 0.7 * test::draw_vec2(u, rng);
    const Vec3 dir = Vec3(xy.x(), xy.y(), 1.0).normalized();
    c.bearing[i] = dir;
    c.p_model[i] = T_model_camera * Vec3(depth(rng) * dir);
  }
  return c;
}

bool contains(const P3PSolutions& s, const SE3& T_true, double tol) {
  for (int k = 0; k < s.count; ++k) {
    const SE3& T = s.T_camera_model[k];
    const double dR = (T.rotation() - T_true.rotation()).norm();
    const double dt = (T.translation() - T_true.translation()).norm() /
                      std::max(1.0, T_true.translation().norm());
    if (dR < tol && dt < tol) return true;
  }
  return false;
}

}  // namespace

TEST_CASE("p3p: cubic solver finds every real root") {
  double r[3];
  REQUIRE(solve_cubic_real(-6.0, 11.0, -6.0, r) == 3);  // (x-1)(x-2)(x-3)
  std::sort(r, r + 3);
  CHECK(r[0] == doctest::Approx(1.0).epsilon(1e-12));
  CHECK(r[1] == doctest::Approx(2.0).epsilon(1e-12));
  CHECK(r[2] == doctest::Approx(3.0).epsilon(1e-12));
  REQUIRE(solve_cubic_real(0.0, 1.0, 0.0, r) == 1);  // x (x^2 + 1)
  CHECK(std::abs(r[0]) < 1e-15);
  REQUIRE(solve_cubic_real(-3.0, 3.0, -1.0, r) >= 1);  // (x-1)^3
  CHECK(r[0] == doctest::Approx(1.0).epsilon(1e-4));
}

TEST_CASE("p3p: the true pose is among the solutions, every solution fits the rays") {
  std::mt19937 rng(17);
  int missed = 0, total_solutions = 0;
  double worst_ray = 0;
  const int trials = 5000;
  for (int trial = 0; trial < trials; ++trial) {
    const P3PCase c = random_case(rng);
    P3PSolutions s;
    const int n = solve_p3p(c.bearing, c.p_model, &s);
    CHECK(n == s.count);
    CHECK(n <= 4);
    total_solutions += n;
    if (!contains(s, c.T_camera_model, 1e-6)) ++missed;
    for (int k = 0; k < n; ++k)
      for (int i = 0; i < 3; ++i) {
        const Vec3 p = s.T_camera_model[k] * c.p_model[i];
        worst_ray = std::max(worst_ray, (p.normalized() - c.bearing[i]).norm());
      }
  }
  INFO("missed " << missed << " of " << trials << ", mean solutions "
                 << static_cast<double>(total_solutions) / trials);
  CHECK(missed == 0);
  CHECK(worst_ray < 1e-7);
}

TEST_CASE("p3p: degenerate input gives no solution and no NaN") {
  std::mt19937 rng(5);
  const P3PCase c = random_case(rng);
  P3PSolutions s;
  auto collinear = c.p_model;
  collinear[2] = collinear[0] + 2.5 * (collinear[1] - collinear[0]);
  CHECK(solve_p3p(c.bearing, collinear, &s) == 0);
  auto coincident = c.p_model;
  coincident[1] = coincident[0];
  CHECK(solve_p3p(c.bearing, coincident, &s) == 0);
  auto parallel = c.bearing;
  parallel[1] = 3.0 * parallel[0];
  CHECK(solve_p3p(parallel, c.p_model, &s) == 0);
  auto zero = c.bearing;
  zero[2] = Vec3::Zero();
  CHECK(solve_p3p(zero, c.p_model, &s) == 0);
  auto nan = c.bearing;
  nan[0].x() = std::numeric_limits<double>::quiet_NaN();
  CHECK(solve_p3p(nan, c.p_model, &s) == 0);
  auto inf = c.p_model;
  inf[1].z() = std::numeric_limits<double>::infinity();
  CHECK(solve_p3p(c.bearing, inf, &s) == 0);
}

TEST_CASE("p3p: points behind the camera and random garbage never yield NaN") {
  std::mt19937 rng(23);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::uniform_real_distribution<double> expo(-8.0, 8.0);
  int behind_solutions = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    P3PCase c = random_case(rng);
    // Bearings pointing away from the points: a solution must still have
    // positive depths along the given rays.
    for (auto& b : c.bearing) b = -b;
    P3PSolutions s;
    const int n = solve_p3p(c.bearing, c.p_model, &s);
    behind_solutions += n;
    for (int k = 0; k < n; ++k) {
      CHECK(s.T_camera_model[k].all_finite());
      for (int i = 0; i < 3; ++i) CHECK((s.T_camera_model[k] * c.p_model[i]).dot(c.bearing[i]) > 0);
    }
    // Garbage at any scale.
    std::array<Vec3, 3> b, p;
    for (int i = 0; i < 3; ++i) {
      b[i] = test::draw_vec3(u, rng);
      b[i] *= std::pow(10.0, expo(rng));
      p[i] = test::draw_vec3(u, rng);
      p[i] *= std::pow(10.0, expo(rng));
    }
    const int m = solve_p3p(b, p, &s);
    for (int k = 0; k < m; ++k) CHECK(s.T_camera_model[k].all_finite());
  }
  MESSAGE("solutions with flipped bearings: " << behind_solutions);
}

#ifdef SCOPETRACK_HAVE_CALIB3D
TEST_CASE("p3p: agrees with cv::solveP3P on the true pose") {
  std::mt19937 rng(99);
  const cv::Matx33d K(1000, 0, 639.5, 0, 1000, 359.5, 0, 0, 1);
  int cv_missed = 0, ours_missed = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const P3PCase c = random_case(rng);
    std::vector<cv::Point3d> object;
    std::vector<cv::Point2d> image;
    for (int i = 0; i < 3; ++i) {
      object.emplace_back(c.p_model[i].x(), c.p_model[i].y(), c.p_model[i].z());
      const Vec3 b = c.bearing[i] / c.bearing[i].z();
      image.emplace_back(1000 * b.x() + 639.5, 1000 * b.y() + 359.5);
    }
    std::vector<cv::Mat> rvecs, tvecs;
    const int n_cv = cv::solveP3P(object, image, K, cv::noArray(), rvecs, tvecs, cv::SOLVEPNP_P3P);
    P3PSolutions cv_sol;
    for (int k = 0; k < std::min(n_cv, 4); ++k) {
      cv::Mat R;
      cv::Rodrigues(rvecs[k], R);
      Mat3 Re;
      Vec3 te;
      cv::cv2eigen(R, Re);
      cv::cv2eigen(tvecs[k], te);
      cv_sol.T_camera_model[cv_sol.count++] = SE3(Re, te);
    }
    P3PSolutions ours;
    solve_p3p(c.bearing, c.p_model, &ours);
    cv_missed += !contains(cv_sol, c.T_camera_model, 1e-6);
    ours_missed += !contains(ours, c.T_camera_model, 1e-6);
  }
  MESSAGE("true pose missed at 1e-6: ours " << ours_missed << ", cv::solveP3P " << cv_missed
                                            << " of 500");
  CHECK(ours_missed <= cv_missed);
  CHECK(ours_missed == 0);
}
#endif
