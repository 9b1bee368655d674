// D(f), the closest point on the mesh: the triangle kernel against a dense
// barycentric sampling, the hierarchy against brute force over every
// triangle of the CT liver, the residual Jacobian against central
// differences, bad input, no allocation per query; prints memory and time.
#include <doctest/doctest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "core/mesh/closest_point.h"
#include "support/alloc_guard.h"
#include "support/ba_window.h"
#include "support/draws.h"
#include "support/track_scene.h"

using namespace st;
using namespace st::test;

namespace {

Vec3 corner(const Mesh& m, int t, int k) { return m.vertex(m.tri[static_cast<std::size_t>(3 * t + k)]); }

double brute_force_distance(const Mesh& m, const Vec3& p) {
  double best = std::numeric_limits<double>::infinity();
  for (int t = 0; t < m.triangle_count(); ++t)
    best = std::min(best, closest_point_on_triangle(p, corner(m, t, 0), corner(m, t, 1), corner(m, t, 2)).distance_mm);
  return best;
}

// Query points: uniform in the mesh box grown by 20 mm, and near the surface
// (a random vertex moved up to 5 mm along a random direction).
std::vector<Vec3> query_points(const Mesh& m, int n, std::uint32_t seed) {
  Vec3 lo = m.vertex(0), hi = lo;
  for (int v = 0; v < m.vertex_count(); ++v) {
    lo = lo.cwiseMin(m.vertex(v));
    hi = hi.cwiseMax(m.vertex(v));
  }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  std::vector<Vec3> q;
  for (int i = 0; i < n; ++i) {
    if (i % 2 == 0) {
      const Vec3 r = draw_vec3(u, rng);
      q.push_back(lo - Vec3::Constant(20) + (hi - lo + Vec3::Constant(40)).cwiseProduct(r));
    } else {
      const int v = static_cast<int>(u(rng) * (m.vertex_count() - 1));
      const double reach = 5.0 * u(rng);
      q.push_back(m.vertex(v) + reach * draw_vec3(g, rng).normalized());
    }
  }
  return q;
}

}  // namespace

TEST_CASE("closest point: triangle kernel is the minimum over a dense sampling of the triangle") {
  std::mt19937 rng(3);
  std::normal_distribution<double> g(0.0, 10.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Vec3 a = draw_vec3(g, rng), b = draw_vec3(g, rng), c = draw_vec3(g, rng);
    const Vec3 p = draw_vec3(g, rng);
    const SurfacePoint s = closest_point_on_triangle(p, a, b, c);
    double sampled = std::numeric_limits<double>::infinity();
    const int n = 200;
    for (int i = 0; i <= n; ++i)
      for (int j = 0; i + j <= n; ++j)
        sampled = std::min(sampled, (p - (a + (b - a) * i / n + (c - a) * j / n)).norm());
    CHECK(s.distance_mm <= sampled + 1e-9);
    CHECK(s.distance_mm >= sampled - 0.15);  // sampling step ~0.1 mm of ~30 mm edges
    // The returned point lies in the triangle's plane and inside it.
    const Vec3 n3 = (b - a).cross(c - a);
    CHECK(std::abs(n3.normalized().dot(s.p_model - a)) < 1e-9);
    CHECK(std::abs((p - s.p_model).norm() - s.distance_mm) < 1e-12);
    // The search kernel (squared distance only) agrees.
    CHECK(triangle_distance2(p, a, b, c) == doctest::Approx(s.distance_mm * s.distance_mm).epsilon(1e-12).scale(1e-12));
  }
}

TEST_CASE("closest point: degenerate triangles fall back to their edges") {
  const Vec3 a(0, 0, 0), b(1, 0, 0), c(2, 0, 0);  // collinear
  const SurfacePoint s = closest_point_on_triangle(Vec3(0.5, 1, 0), a, b, c);
  CHECK(s.distance_mm == doctest::Approx(1.0));
  CHECK(s.feature == SurfaceFeature::kEdge);
  const SurfacePoint v = closest_point_on_triangle(Vec3(3, 0, 0), a, a, a);
  CHECK(v.distance_mm == doctest::Approx(3.0));
  CHECK(v.feature == SurfaceFeature::kVertex);
  CHECK(triangle_distance2(Vec3(0.5, 1, 0), a, b, c) == doctest::Approx(1.0));
  CHECK(triangle_distance2(Vec3(3, 0, 0), a, a, a) == doctest::Approx(9.0));
}

TEST_CASE("closest point: BVH equals brute force over every triangle of the CT liver") {
  const Mesh mesh = load_liver_for_tracking();
  ClosestPointIndex index;
  REQUIRE(index.configure(mesh).ok());
  CHECK(index.triangle_count() == mesh.triangle_count());
  const std::vector<Vec3> q = query_points(mesh, 400, 11);
  double max_err = 0;
  for (const Vec3& p : q) {
    SurfacePoint s;
    REQUIRE(index.closest(p, &s));
    const double exact = brute_force_distance(mesh, p);
    max_err = std::max(max_err, std::abs(s.distance_mm - exact));
    // The reported triangle really holds the reported point.
    const SurfacePoint t = closest_point_on_triangle(p, corner(mesh, s.triangle, 0), corner(mesh, s.triangle, 1),
                                                     corner(mesh, s.triangle, 2));
    CHECK((t.p_model - s.p_model).norm() < 1e-4);
  }
  MESSAGE("liver: " << mesh.triangle_count() << " triangles, " << index.node_count() << " nodes, depth "
                    << index.depth() << ", " << index.memory_bytes() / 1024 << " KiB; max |BVH - brute force| "
                    << max_err << " mm over " << q.size() << " queries");
  // Vertices are float in the index and double here: agreement to float precision.
  CHECK(max_err < 1e-4);
}

TEST_CASE("closest point: d(f - D(f))/df is the feature's normal-space projector (central differences)") {
  const Mesh mesh = load_liver_for_tracking();
  ClosestPointIndex index;
  REQUIRE(index.configure(mesh).ok());
  const std::vector<Vec3> q = query_points(mesh, 200, 5);
  const double h = 1e-5;
  int checked = 0, faces = 0;
  for (const Vec3& p : q) {
    SurfacePoint s;
    REQUIRE(index.closest(p, &s));
    Mat3 numeric;
    bool same_feature = true;
    for (int k = 0; k < 3; ++k) {
      SurfacePoint sp, sm;
      REQUIRE(index.closest(p + h * Vec3::Unit(k), &sp));
      REQUIRE(index.closest(p - h * Vec3::Unit(k), &sm));
      same_feature = same_feature && sp.triangle == s.triangle && sm.triangle == s.triangle &&
                     sp.feature == s.feature && sm.feature == s.feature;
      numeric.col(k) = ((p + h * Vec3::Unit(k) - sp.p_model) - (p - h * Vec3::Unit(k) - sm.p_model)) / (2 * h);
    }
    if (!same_feature) continue;  // on a Voronoi boundary: the derivative jumps
    ++checked;
    faces += s.feature == SurfaceFeature::kFace ? 1 : 0;
    CHECK((numeric - s.residual_jacobian()).norm() < 1e-4);
  }
  MESSAGE(checked << " points checked, " << faces << " on a face");
  CHECK(checked > 150);
  CHECK(faces > 20);
}

TEST_CASE("closest point: bad input is refused, queries allocate nothing") {
  ClosestPointIndex index;
  SurfacePoint s;
  CHECK_FALSE(index.closest(Vec3::Zero(), &s));  // not configured
  Mesh empty;
  CHECK_FALSE(index.configure(empty).ok());
  Mesh bad;
  bad.add_vertex(0, 0, 0);
  bad.add_vertex(1, 0, 0);
  bad.add_triangle(0, 1, 2);
  CHECK_FALSE(index.configure(bad).ok());
  bad.add_vertex(std::numeric_limits<float>::quiet_NaN(), 0, 0);
  CHECK_FALSE(index.configure(bad).ok());

  const Mesh mesh = load_liver_for_tracking();
  REQUIRE(index.configure(mesh).ok());
  CHECK_FALSE(index.closest(Vec3(std::nan(""), 0, 0), &s));
  const std::vector<Vec3> q = query_points(mesh, 20000, 9);
  double sum = 0;
  const AllocationCounter counter;
  const auto t0 = std::chrono::steady_clock::now();
  for (const Vec3& p : q) {
    if (index.closest(p, &s)) sum += s.distance_mm;
  }
  const double us = std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - t0).count();
  CHECK(counter.count() == 0);
  MESSAGE("mean query " << us / static_cast<double>(q.size()) << " us (half near the surface, half in the box "
                        << "+20 mm); mean distance " << sum / static_cast<double>(q.size()) << " mm");
}

// The float box tests of the 4-wide search: points on the surface (ties
// between the triangles sharing a vertex), points far out (large float
// rounding of the coordinates) and a one-leaf mesh all give the exhaustive
// minimum; coordinates beyond 1e15 mm are refused like non-finite ones.
TEST_CASE("closest point: on-surface, far-out and one-leaf queries equal brute force, huge coordinates refused") {
  const Mesh mesh = load_liver_for_tracking();
  ClosestPointIndex index;
  REQUIRE(index.configure(mesh).ok());
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  double max_err = 0;
  for (int i = 0; i < 200; ++i) {
    const int v = static_cast<int>(u(rng) * (mesh.vertex_count() - 1));
    const Vec3 dir = random_unit(rng);
    const Vec3 on = mesh.vertex(v), near = on + 1e-7 * dir, far = on + 5e3 * dir;
    for (const Vec3& p : {on, near, far}) {
      SurfacePoint s;
      REQUIRE(index.closest(p, &s));
      max_err = std::max(max_err, std::abs(s.distance_mm - brute_force_distance(mesh, p)));
    }
  }
  MESSAGE("max |search - brute force| " << max_err << " mm over 600 queries (on vertices, 0.1 nm off, 5 m off)");
  CHECK(max_err < 1e-9);

  Mesh one;
  one.add_vertex(0, 0, 0);
  one.add_vertex(10, 0, 0);
  one.add_vertex(0, 10, 0);
  one.add_triangle(0, 1, 2);
  REQUIRE(index.configure(one).ok());
  SurfacePoint s;
  REQUIRE(index.closest(Vec3(2, 3, 4), &s));
  CHECK(s.distance_mm == doctest::Approx(4.0));
  CHECK(s.triangle == 0);
  CHECK(index.closest(Vec3(1e14, 0, 0), &s));
  CHECK(s.distance_mm == doctest::Approx(1e14 - 10.0));
  CHECK_FALSE(index.closest(Vec3(2e15, 0, 0), &s));
}
