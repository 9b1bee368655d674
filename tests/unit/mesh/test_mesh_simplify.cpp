// Mesh simplification by vertex clustering (core/mesh/mesh_simplify.h) on the
// CT liver of shared/data, subdivided to the density of a segmentation
// exported as it is, and on malformed input.
#include <doctest/doctest.h>

#include <chrono>
#include <cmath>
#include <limits>
#include <random>

#include "core/mesh/closest_point.h"
#include "core/mesh/mesh_simplify.h"
#include "core/raster/rasterizer.h"
#include "support/draws.h"
#include "support/raster_scene.h"
#include "support/support.h"
#include "support/track_scene.h"
#include "tools/sim/mesh_ops.h"

using namespace st;
using namespace st::test;

namespace {

Mesh load_liver() { return load_liver_for_tracking(); }

// One triangle in the z = 0 plane, counter-clockwise seen from +z.
Mesh one_triangle(float size) {
  Mesh m;
  m.add_vertex(0, 0, 0);
  m.add_vertex(size, 0, 0);
  m.add_vertex(0, size, 0);
  m.add_triangle(0, 1, 2);
  return m;
}

// Largest and median distance from the vertices of `coarse` to the surface
// of `fine`.
std::pair<double, double> vertex_distances(const Mesh& coarse, const Mesh& fine) {
  ClosestPointIndex index;
  REQUIRE(index.configure(fine).ok());
  std::vector<double> d;
  for (int i = 0; i < coarse.vertex_count(); ++i) {
    SurfacePoint sp;
    REQUIRE(index.closest(coarse.vertex(i), &sp));
    d.push_back(sp.distance_mm);
  }
  std::sort(d.begin(), d.end());
  MESSAGE("vertex distances p99 " << d[d.size() * 99 / 100] << " p999 " << d[d.size() * 999 / 1000] << " over 0.5 mm: "
          << (d.end() - std::upper_bound(d.begin(), d.end(), 0.5)) << " of " << d.size());
  return {d.back(), d[d.size() / 2]};
}

}  // namespace

TEST_CASE("mesh simplify: a dense liver (320k triangles) to the tracker's budget, close to the surface" *
          doctest::timeout(budget_s(60))) {
  const Mesh liver = load_liver();
  const Mesh dense = sim::subdivide(liver, 2);
  REQUIRE(dense.triangle_count() == 320000);
  SimplifyReport report;
  const auto t0 = std::chrono::steady_clock::now();
  auto simplified = simplify_to_budget(dense, 40000, &report);
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  REQUIRE_MESSAGE(simplified.ok(), simplified.message());
  MESSAGE("320000 -> " << report.output_triangles << " triangles, cell " << report.cell_mm << " mm, "
                       << report.passes << " passes, " << seconds << " s");
  CHECK(report.input_triangles == 320000);
  CHECK(report.output_triangles == simplified->triangle_count());
  CHECK(simplified->triangle_count() <= 40000);
  CHECK(simplified->triangle_count() >= 20000);  // the first cell of the series that fits, not a crude one
  // Every merged vertex stays near the organ's surface: the cells are a
  // few mm, the surface within one is nearly flat.
  const auto [max_d, median_d] = vertex_distances(simplified.value(), liver);
  MESSAGE("vertex to surface: max " << max_d << " mm, median " << median_d << " mm");
  CHECK(max_d < 0.25 * report.cell_mm);
  CHECK(median_d < 0.05);
  // Indices valid, no degenerate triangle.
  for (int t = 0; t < simplified->triangle_count(); ++t) {
    const std::int32_t a = simplified->tri[3 * t], b = simplified->tri[3 * t + 1], c = simplified->tri[3 * t + 2];
    REQUIRE((a >= 0 && b >= 0 && c >= 0));
    REQUIRE((a < simplified->vertex_count() && b < simplified->vertex_count() && c < simplified->vertex_count()));
    REQUIRE((a != b && b != c && a != c));
  }
}

TEST_CASE("mesh simplify: renders of the simplified liver match the original's (mask and depth)" *
          doctest::timeout(budget_s(60))) {
  const Mesh liver = load_liver();
  auto simplified = simplify_to_budget(sim::subdivide(liver, 1), 10000);
  REQUIRE(simplified.ok());
  const Vec3 centre = bbox_centre(liver);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  RasterConfig cfg;
  cfg.width = 640;
  cfg.height = 360;
  const Pinhole K{500.0, 500.0, 319.5, 179.5, 640, 360};
  MeshRasterizer fine, coarse;
  REQUIRE(fine.configure(liver, cfg).ok());
  REQUIRE(coarse.configure(simplified.value(), cfg).ok());
  long both = 0, either = 0;
  std::vector<double> dz;
  for (int i = 0; i < 20; ++i) {
    Vec3 dir = draw_vec3(u, rng);
    if (dir.norm() < 0.1) dir = Vec3(0, 0, 1);
    const Vec3 target = centre + 30.0 * draw_vec3(u, rng);
    const double distance = 200.0 + 60.0 * u(rng);
    const SE3 T = look_at(target, dir, distance, M_PI * u(rng));
    fine.render(T, K);
    coarse.render(T, K);
    for (int y = 0; y < 360; ++y)
      for (int x = 0; x < 640; ++x) {
        const bool a = fine.mask()(x, y) != 0, b = coarse.mask()(x, y) != 0;
        both += a && b;
        either += a || b;
        if (a && b) dz.push_back(std::abs(double{fine.depth()(x, y)} - double{coarse.depth()(x, y)}));
      }
  }
  REQUIRE(either > 100000);
  std::sort(dz.begin(), dz.end());
  const double iou = double(both) / double(either);
  MESSAGE("80000 -> " << simplified->triangle_count() << " triangles: mask IoU " << iou << ", depth |diff| median "
                      << dz[dz.size() / 2] << " mm, p99 " << dz[dz.size() * 99 / 100] << " mm");
  CHECK(iou > 0.99);
  CHECK(dz[dz.size() / 2] < 0.1);
  CHECK(dz[dz.size() * 99 / 100] < 1.0);  // silhouettes and creases
}

TEST_CASE("mesh simplify: within budget the mesh is returned as it is") {
  const Mesh liver = load_liver();
  SimplifyReport report;
  auto same = simplify_to_budget(liver, 20000, &report);
  REQUIRE(same.ok());
  CHECK(same->tri == liver.tri);
  CHECK(same->x == liver.x);
  CHECK(report.cell_mm == 0.0);
  CHECK(report.passes == 0);
}

TEST_CASE("mesh simplify: clustering keeps windings and merges duplicates") {
  // A unit square in two triangles, counter-clockwise seen from +z, and a
  // sliver whose corners fall into one cell.
  Mesh m;
  m.add_vertex(0, 0, 0);
  m.add_vertex(10, 0, 0);
  m.add_vertex(10, 10, 0);
  m.add_vertex(0, 10, 0);
  m.add_vertex(0.1f, 0.1f, 0);
  m.add_triangle(0, 1, 2);
  m.add_triangle(0, 2, 3);
  m.add_triangle(0, 1, 4);  // 0 and 4 share a cell (and a side): collapses
  auto c = cluster_vertices(m, 1.0);
  REQUIRE(c.ok());
  CHECK(c->triangle_count() == 2);
  for (int t = 0; t < 2; ++t) {
    const Vec3 a = c->vertex(c->tri[3 * t]), b = c->vertex(c->tri[3 * t + 1]), d = c->vertex(c->tri[3 * t + 2]);
    CHECK((b - a).cross(d - a).z() > 0);  // still facing +z
  }
  // Two copies of the same triangle, spelled from different corners: one.
  Mesh dup = one_triangle(5);
  dup.add_triangle(1, 2, 0);
  auto d = cluster_vertices(dup, 1.0);
  REQUIRE(d.ok());
  CHECK(d->triangle_count() == 1);
}

TEST_CASE("mesh simplify: bad input gets a clear error") {
  Mesh empty;
  CHECK(simplify_to_budget(empty, 1000).message().find("no triangles") != std::string::npos);
  const Mesh m = one_triangle(1);
  CHECK(simplify_to_budget(m, 15).message().find("below 16") != std::string::npos);
  CHECK(cluster_vertices(m, 0.0).message().find("positive") != std::string::npos);
  CHECK(cluster_vertices(m, std::numeric_limits<double>::quiet_NaN()).message().find("positive") != std::string::npos);
  CHECK(cluster_vertices(m, 1e-9).message().find("too small") != std::string::npos);
  Mesh bad_index = m;
  bad_index.add_triangle(0, 1, 7);
  CHECK(cluster_vertices(bad_index, 1.0).message().find("malformed") != std::string::npos);
  Mesh nan = m;
  nan.x[1] = std::numeric_limits<float>::quiet_NaN();
  CHECK(cluster_vertices(nan, 1.0).message().find("not finite") != std::string::npos);
}
