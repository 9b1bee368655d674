// The rasteriser against a brute-force per-pixel ray cast (nearest hit) on
// the real CT liver and on adversarial meshes.
#include <doctest/doctest.h>

#include <random>

#include "core/raster/rasterizer.h"
#include "support/draws.h"
#include "support/raster_reference.h"
#include "support/raster_scene.h"
#include "support/support.h"
#include "support/test_ply.h"

using namespace st;
using namespace st::test;

namespace {

Mesh load_liver() {
  const std::string bytes = read_file_bytes(shared_data("liver/liver.ply"));
  auto mesh = read_binary_ply_for_tests(bytes);
  if (!mesh.ok()) FAIL(mesh.message());
  return std::move(mesh).value();
}

// Renders, compares with the reference and checks the criteria.
// ambiguous_ties: the mesh puts many pixel centres exactly on shared edges,
// where the reference hits both triangles at the same depth and keeps the
// first; there only the fill rule decides, so ties count as agreement.
RasterComparison check_against_reference(const Mesh& mesh, const SE3& T, const Pinhole& K_full,
                                         const RasterConfig& cfg, bool ambiguous_ties = false) {
  MeshRasterizer r;
  REQUIRE(r.configure(mesh, cfg).ok());
  r.render(T, K_full);
  const ReferenceRender ref =
      reference_render(mesh, T, r.camera(), cfg.near_mm, cfg.cull_backfaces);
  const RasterComparison c = compare_with_reference(r, mesh, ref);
  INFO(c.summary());
  const double agree =
      ambiguous_ties ? double(c.agree + c.depth_ties) / double(c.pixels) : c.agreement();
  CHECK(agree >= 0.999);
  CHECK(c.unexplained == 0);
  CHECK(c.cracks == 0);
  CHECK(c.max_rel_depth_error <= 1e-4);
  long mask_pixels = 0;
  for (int y = 0; y < r.mask().height; ++y)
    for (int x = 0; x < r.mask().width; ++x) mask_pixels += r.mask()(x, y) != 0;
  CHECK(r.covered_pixels() == mask_pixels);
  return c;
}

Pinhole small_pinhole() { return {300.0, 310.0, 159.5, 119.5, 320, 240}; }

}  // namespace

TEST_CASE("raster: liver matches the brute-force reference at 20 random poses") {
  const Mesh liver = load_liver();
  REQUIRE(liver.triangle_count() == 20000);
  const Vec3 centre = bbox_centre(liver);
  std::mt19937 rng(2024);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  long boundary = 0, pixels = 0, covered = 0;
  for (int i = 0; i < 20; ++i) {
    Vec3 dir = draw_vec3(u, rng);
    if (dir.norm() < 0.1) dir = Vec3(0, 0, 1);
    const double distance = 220.0 + 120.0 * (u(rng) + 1.0);
    const Vec3 target = centre + 40.0 * draw_vec3(u, rng);
    const SE3 T = look_at(target, dir, distance, M_PI * u(rng));
    RasterConfig cfg;
    cfg.width = 1280;
    cfg.height = 720;
    cfg.downscale = i % 4 == 3 ? 2 : 1;
    cfg.near_mm = i % 5 == 4 ? distance - 30.0 : 1.0;  // some poses slice the organ
    CAPTURE(i);
    const RasterComparison c = check_against_reference(liver, T, bench_pinhole(), cfg);
    MESSAGE("pose " << i << ": " << c.summary());
    boundary += c.on_boundary;
    pixels += c.pixels;
    covered += c.covered_reference;
  }
  CHECK(covered > pixels / 10);  // the organ was actually in view
  CHECK(boundary < pixels / 100000);
}

TEST_CASE("raster: adversarial meshes match the reference") {
  const Pinhole K = small_pinhole();
  struct Case {
    const char* name;
    Mesh mesh;
    double near_mm;
    bool ambiguous_ties = false;
  };
  Case cases[] = {{"fan, pixel-aligned", fan_mesh(K, true), 1.0, true},
                  {"fan, sub-pixel", fan_mesh(K, false), 1.0},
                  {"slivers", sliver_mesh(K), 1.0},
                  {"near plane", near_plane_mesh(), 1.0},
                  {"near plane at 25 mm", near_plane_mesh(), 25.0},
                  {"far outside", far_outside_mesh(), 1.0},
                  {"sphere cut by near", sphere_mesh(Vec3(5, -3, 150), 50, 24, 48), 115.0},
                  {"closed sphere", sphere_mesh(Vec3(5, -3, 160), 50, 24, 48), 1.0}};
  for (auto& c : cases) {
    for (int ds : {1, 2}) {
      RasterConfig cfg = raster_config(K);
      cfg.downscale = ds;
      cfg.near_mm = c.near_mm;
      CAPTURE(std::string(c.name));
      CAPTURE(ds);
      const RasterComparison cmp = check_against_reference(c.mesh, SE3(), K, cfg, c.ambiguous_ties);
      MESSAGE(std::string(c.name) << " ds " << ds << ": " << cmp.summary());
      CHECK(cmp.covered_reference > 0);
    }
  }
}

TEST_CASE("raster: fans sharing edges cover every pixel exactly once") {
  const Pinhole K = small_pinhole();
  for (bool aligned : {true, false}) {
    const Mesh fan = fan_mesh(K, aligned);
    RasterConfig cfg = raster_config(K);
    MeshRasterizer r;
    REQUIRE(r.configure(fan, cfg).ok());
    r.render(SE3(), K);
    CAPTURE(aligned);
    // The fans do not overlap: every fragment lands on a fresh pixel.
    CHECK(r.stats().fragments == r.covered_pixels());
    CHECK(r.covered_pixels() > 10000);
    CHECK(r.stats().triangles_drawn == fan.triangle_count());
  }
  // The near-plane floor: clipped pieces and their neighbours tile exactly.
  RasterConfig cfg = raster_config(K);
  Mesh floor = near_plane_mesh();
  floor.tri.resize(floor.tri.size() - 6);  // drop the two walls (they overlap the floor)
  MeshRasterizer r;
  REQUIRE(r.configure(floor, cfg).ok());
  r.render(SE3(), K);
  CHECK(r.stats().triangles_clipped > 0);
  CHECK(r.stats().fragments == r.covered_pixels());
}

TEST_CASE("raster: SIMD and portable kernels give identical buffers") {
  const Mesh liver = load_liver();
  const SE3 T = look_at(bbox_centre(liver), Vec3(0.3, -0.5, 1.0), 380.0, 0.4);
  RasterConfig cfg;
  cfg.width = 1280;
  cfg.height = 720;
  // Portable, universal SIMD (SSE2 / NEON), and the default: AVX-512 where
  // the CPU has it, else universal SIMD again.
  MeshRasterizer portable, simd, best;
  cfg.use_simd = false;
  REQUIRE(portable.configure(liver, cfg).ok());
  cfg.use_simd = true;
  cfg.allow_avx512 = false;
  REQUIRE(simd.configure(liver, cfg).ok());
  cfg.allow_avx512 = true;
  REQUIRE(best.configure(liver, cfg).ok());
  if (MeshRasterizer::avx512_available()) MESSAGE("AVX-512 kernels tested too");
  portable.render(T, bench_pinhole());
  for (MeshRasterizer* r : {&simd, &best}) {
    r->render(T, bench_pinhole());
    REQUIRE(r->covered_pixels() > 100000);
    CHECK(r->covered_pixels() == portable.covered_pixels());
    CHECK(r->stats().fragments == portable.stats().fragments);
    long diff = 0;
    for (int y = 0; y < 720; ++y)
      for (int x = 0; x < 1280; ++x)
        diff += r->depth()(x, y) != portable.depth()(x, y) ||
                r->triangle_id()(x, y) != portable.triangle_id()(x, y) ||
                r->mask()(x, y) != portable.mask()(x, y);
    CHECK(diff == 0);
  }
}
