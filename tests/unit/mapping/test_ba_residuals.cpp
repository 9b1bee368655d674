// Bundle-adjustment residuals: the SE3 left Jacobian of exp and
// finite-difference Jacobian tests of the reprojection cost (in the 6-dim
// pose delta Ceres optimises, at and away from the linearization point)
// and of the shape cost functions.
#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include "core/mapping/ba_job.h"
#include "core/mapping/ba_residuals.h"
#include "core/pose/correspondences.h"
#include "support/draws.h"
#include "support/track_scene.h"

using namespace st;
using namespace st::test;

namespace {

SE3 random_pose(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  Vec6 xi;
  xi << g(rng), g(rng), g(rng), 20 * g(rng), 20 * g(rng), 20 * g(rng);
  return SE3::exp(xi);
}

}  // namespace

TEST_CASE("ba residuals: SE3 left Jacobian of exp matches central differences, identity at zero") {
  std::mt19937 rng(1);
  CHECK((se3_left_jacobian(Vec6::Zero()) - Mat6::Identity()).norm() == 0.0);
  for (int trial = 0; trial < 20; ++trial) {
    std::normal_distribution<double> g(0.0, trial < 10 ? 0.05 : 0.8);  // BA-sized deltas, then large ones
    Vec6 xi;
    for (int k = 0; k < 6; ++k) xi[k] = (k < 3 ? 1.0 : 20.0) * g(rng);
    const Mat6 J = se3_left_jacobian(xi);
    const SE3 T = SE3::exp(xi);
    // exp(xi + h e_k) exp(xi)^-1 = exp(h J e_k): its log over h is column k.
    const double h = 1e-6;
    for (int k = 0; k < 6; ++k) {
      Vec6 e = Vec6::Zero();
      e[k] = h;
      const Vec6 col = ((SE3::exp(xi + e) * T.inverse()).log() - (SE3::exp(xi - e) * T.inverse()).log()) / (2 * h);
      for (int r = 0; r < 6; ++r) CHECK(col[r] == doctest::Approx(J(r, k)).epsilon(1e-5).scale(1));
    }
  }
}

TEST_CASE("ba residuals: reprojection cost Jacobians match central differences (pose delta, point)") {
  std::mt19937 rng(2);
  std::normal_distribution<double> g(0.0, 1.0);
  const Pinhole K = track_test_pinhole();
  for (int trial = 0; trial < 30; ++trial) {
    const SE3 T0 = random_pose(rng);
    // At the linearization point (delta 0) and away from it (a BA step).
    Vec6 delta = Vec6::Zero();
    if (trial % 2 == 1)
      for (int k = 0; k < 6; ++k) delta[k] = (k < 3 ? 0.03 : 1.5) * g(rng);
    const SE3 T = SE3::exp(delta) * T0;
    const Vec3 a = draw_vec3(g, rng);
    const Vec3 p_camera(20 * a.x(), 15 * a.y(), 80 + 10 * std::abs(a.z()));
    Vec3 p_model = T.inverse() * p_camera;
    const Vec2 px = K.project(p_camera) + 3 * draw_vec2(g, rng);
    const int octave = trial % 8;
    const double sqrt_info = std::sqrt(octave_information(octave));
    const auto cost = [&](const Vec6& d, const Vec3& f, double* rr, double* jp, double* jf) {
      return reprojection_cost(K, px, sqrt_info, 1.0, T0, d.data(), f.data(), rr, jp, jf);
    };
    double r[2], Jp[12], Jf[6];
    REQUIRE(cost(delta, p_model, r, Jp, Jf));
    CHECK(r[0] == doctest::Approx(sqrt_info * (K.project(p_camera) - px).x()));
    const Eigen::Map<Mat26r> J_delta(Jp);
    const double h = 1e-6;
    for (int k = 0; k < 6; ++k) {
      double rp[2], rm[2];
      Vec6 e = Vec6::Zero();
      e[k] = h;
      REQUIRE(cost(delta + e, p_model, rp, nullptr, nullptr));
      REQUIRE(cost(delta - e, p_model, rm, nullptr, nullptr));
      for (int i = 0; i < 2; ++i)
        CHECK((rp[i] - rm[i]) / (2 * h) == doctest::Approx(J_delta(i, k)).epsilon(1e-5).scale(1));
    }
    const Eigen::Map<Eigen::Matrix<double, 2, 3, Eigen::RowMajor>> J_point(Jf);
    for (int k = 0; k < 3; ++k) {
      Vec3 fp = p_model, fm = p_model;
      fp[k] += h;
      fm[k] -= h;
      double rp[2], rm[2];
      REQUIRE(cost(delta, fp, rp, nullptr, nullptr));
      REQUIRE(cost(delta, fm, rm, nullptr, nullptr));
      for (int i = 0; i < 2; ++i)
        CHECK((rp[i] - rm[i]) / (2 * h) == doctest::Approx(J_point(i, k)).epsilon(1e-5).scale(1));
    }
    // Behind the camera: refused (Ceres rejects the step).
    p_model = T.inverse() * Vec3(0, 0, -5);
    CHECK_FALSE(cost(delta, p_model, r, nullptr, nullptr));
  }
}

TEST_CASE("ba residuals: shape cost is sqrt(w) (f - D(f)), w = 100, with a Jacobian matching central differences") {
  const Mesh mesh = load_liver_for_tracking();
  ClosestPointIndex index;
  REQUIRE(index.configure(mesh).ok());
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int checked = 0;
  for (int trial = 0; trial < 100; ++trial) {
    const int v = static_cast<int>(u(rng) * (mesh.vertex_count() - 1));
    const double reach = 3.0 * u(rng);
    const Vec3 f = mesh.vertex(v) + reach * (draw_vec3(u, rng) - Vec3::Constant(0.5)).normalized();
    double r[3], J[9];
    REQUIRE(shape_cost(index, 10.0, f.data(), r, J));
    SurfacePoint s;
    REQUIRE(index.closest(f, &s));
    CHECK(Vec3(r[0], r[1], r[2]).norm() == doctest::Approx(10.0 * s.distance_mm));
    const double h = 1e-6;
    Mat3 numeric;
    bool same = true;
    for (int k = 0; k < 3; ++k) {
      Vec3 fp = f, fm = f;
      fp[k] += h;
      fm[k] -= h;
      SurfacePoint sp, sm;
      index.closest(fp, &sp);
      index.closest(fm, &sm);
      same = same && sp.triangle == s.triangle && sm.triangle == s.triangle && sp.feature == s.feature &&
             sm.feature == s.feature;
      double rp[3], rm[3];
      REQUIRE(shape_cost(index, 10.0, fp.data(), rp, nullptr));
      REQUIRE(shape_cost(index, 10.0, fm.data(), rm, nullptr));
      for (int i = 0; i < 3; ++i) numeric(i, k) = (rp[i] - rm[i]) / (2 * h);
    }
    if (!same) continue;  // a Voronoi boundary between features: no derivative
    ++checked;
    CHECK((numeric - Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(J)).norm() < 1e-3);
  }
  CHECK(checked > 70);
  // Not configured: refused.
  const ClosestPointIndex none;
  const Vec3 f = Vec3::Zero();
  double r[3];
  CHECK_FALSE(shape_cost(none, 10.0, f.data(), r, nullptr));
  CHECK_FALSE(shape_cost(index, 10.0, Vec3(std::nan(""), 0, 0).data(), r, nullptr));
}

TEST_CASE("ba residuals: tangent-plane shape cost, its Jacobian (central differences) and its foot point") {
  const Mesh mesh = load_liver_for_tracking();
  ClosestPointIndex index;
  REQUIRE(index.configure(mesh).ok());
  std::mt19937 rng(6);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (int trial = 0; trial < 50; ++trial) {
    const int v = static_cast<int>(u(rng) * (mesh.vertex_count() - 1));
    const double reach = 2.0 * u(rng);
    const Vec3 f0 = mesh.vertex(v) + reach * (draw_vec3(u, rng) - Vec3::Constant(0.5)).normalized();
    ShapePlane plane;
    REQUIRE(shape_plane(index, f0, &plane));
    SurfacePoint s;
    REQUIRE(index.closest(f0, &s));
    CHECK(std::abs(plane.normal.norm() - 1.0) < 1e-9);
    double r[2], J[6];
    plane_cost(plane, 10.0, f0.data(), r, J);
    // At the start value the plane residual is the distance to the mesh.
    CHECK(std::abs(r[0]) == doctest::Approx(10.0 * s.distance_mm).epsilon(1e-6).scale(1e-9));
    CHECK(r[1] == 0.0);
    const double h = 1e-6;
    for (int k = 0; k < 3; ++k) {
      Vec3 fp = f0, fm = f0;
      fp[k] += h;
      fm[k] -= h;
      double rp[2], rm[2];
      plane_cost(plane, 10.0, fp.data(), rp, nullptr);
      plane_cost(plane, 10.0, fm.data(), rm, nullptr);
      CHECK((rp[0] - rm[0]) / (2 * h) == doctest::Approx(J[k]).epsilon(1e-6).scale(1));
      CHECK(J[3 + k] == 0.0);
    }
  }
  const ClosestPointIndex none;
  ShapePlane plane;
  CHECK_FALSE(shape_plane(none, Vec3::Zero(), &plane));
}
