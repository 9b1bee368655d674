// Rasteriser helpers (depth_at, model_point, morph_mask, visible_triangles),
// bad input, and the no-allocation guarantee after configure().
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>

#include "core/image/image.h"
#include "core/raster/rasterizer.h"
#include "support/alloc_guard.h"
#include "support/draws.h"
#include "support/morph_reference.h"
#include "support/raster_reference.h"
#include "support/raster_scene.h"
#include "support/support.h"
#include "support/test_ply.h"

using namespace st;
using namespace st::test;

namespace {

Mesh liver_mesh() {
  auto mesh = read_binary_ply_for_tests(read_file_bytes(shared_data("liver/liver.ply")));
  if (!mesh.ok()) FAIL(mesh.message());
  return std::move(mesh).value();
}

RasterConfig config_1280() {
  RasterConfig cfg;
  cfg.width = 1280;
  cfg.height = 720;
  return cfg;
}

// Two camera-facing quads in the camera frame: a tilted one at ~100 mm on
// the left half, and a far one at 200 mm behind everything.
Mesh two_quads(const Pinhole& K) {
  Mesh m;
  auto add = [&](double u0, double v0, double u1, double v1, double z0, double gx) {
    const int b = m.vertex_count();
    for (auto [u, v] : {std::pair{u0, v0}, {u1, v0}, {u1, v1}, {u0, v1}}) {
      const double qx = (u - K.cx) / K.fx, qy = (v - K.cy) / K.fy;
      const double z = z0 / (1.0 - gx * qx);
      m.add_vertex(float(qx * z), float(qy * z), float(z));
    }
    m.add_triangle(b, b + 1, b + 2);
    m.add_triangle(b, b + 2, b + 3);
  };
  add(-10, -10, 150.3, 250, 100, 0.5);
  add(-10, -10, 330, 250, 200, 0.0);
  orient_towards_origin(&m);
  return m;
}

Pinhole quad_pinhole() { return {300.0, 300.0, 159.5, 119.5, 320, 240}; }

}  // namespace

TEST_CASE("raster: render and every helper allocate nothing after configure") {
  const Mesh liver = liver_mesh();
  MeshRasterizer r;
  RasterConfig cfg = config_1280();
  REQUIRE(r.configure(liver, cfg).ok());
  const Vec3 c = bbox_centre(liver);
  Image<std::uint8_t> morphed(1280, 720);
  std::vector<std::int32_t> visible(liver.triangle_count());
  r.render(look_at(c, Vec3(0, 0, 1), 300, 0), bench_pinhole());  // warm-up
  AllocationCounter counter;
  long checksum = 0;
  for (int i = 0; i < 5; ++i) {
    r.render(look_at(c, Vec3(0.2 * i, -0.3, 1), 260 + 20 * i, 0.3 * i), bench_pinhole());
    float d = 0;
    checksum += r.depth_at(Vec2(640.25, 360.5), &d);
    const Vec3 p = r.model_point(Vec2(640, 360), d);
    checksum += p.allFinite();
    r.morph_mask(-3, morphed.view());
    r.morph_mask(4, morphed.view());
    checksum += r.visible_triangles(visible.data(), static_cast<int>(visible.size()));
    checksum += static_cast<long>(r.full_to_raster(Vec2(10, 10)).x());
  }
  CHECK(counter.count() == 0);
  CHECK(checksum > 0);
}

TEST_CASE("raster: depth_at interpolates on one surface and never across a step") {
  const Pinhole K = quad_pinhole();
  const Mesh m = two_quads(K);
  RasterConfig cfg = raster_config(K);
  MeshRasterizer r;
  REQUIRE(r.configure(m, cfg).ok());
  r.render(SE3(), K);
  // On the tilted quad: close to the exact plane depth at sub-pixel positions.
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> ux(5, 140), uy(5, 230);
  for (int i = 0; i < 200; ++i) {
    const Vec2 px = draw_vec2(ux, uy, rng);
    float d = 0;
    REQUIRE(r.depth_at(px, &d));
    const double qx = (px.x() - K.cx) / K.fx;
    const double exact = 100.0 / (1.0 - 0.5 * qx);
    CHECK(std::abs(double{d} - exact) < 1e-3 * exact);
  }
  // Across the step at u = 150.3: the nearest pixel's depth, never a blend.
  float d = 0;
  REQUIRE(r.depth_at(Vec2(150.4, 100.2), &d));
  CHECK(d == r.depth()(150, 100));
  REQUIRE(r.depth_at(Vec2(150.6, 100.2), &d));
  CHECK(d == r.depth()(151, 100));
  CHECK(std::abs(d - 200.0f) < 1e-3f);
  // Nothing there, outside the raster, or not a number: false.
  Mesh small = two_quads(K);
  small.tri.resize(6);  // only the near quad
  REQUIRE(r.configure(small, cfg).ok());
  r.render(SE3(), K);
  CHECK_FALSE(r.depth_at(Vec2(200, 100), &d));
  CHECK_FALSE(r.depth_at(Vec2(-3, 100), &d));
  CHECK_FALSE(r.depth_at(Vec2(std::nan(""), 100), &d));
  CHECK(r.depth_at(Vec2(-0.4, 100), &d));  // nearest pixel (0, 100) is covered
}

TEST_CASE("raster: model_point lands on the rendered triangle and reprojects") {
  const Mesh liver = liver_mesh();
  for (int ds : {1, 4}) {
    RasterConfig cfg = config_1280();
    cfg.downscale = ds;
    MeshRasterizer r;
    REQUIRE(r.configure(liver, cfg).ok());
    const SE3 T = look_at(bbox_centre(liver), Vec3(-0.4, 0.2, 1), 320, 1.0);
    r.render(T, bench_pinhole());
    int checked = 0;
    for (int y = 0; y < r.depth().height; y += 7) {
      for (int x = 0; x < r.depth().width; x += 7) {
        const int t = r.triangle_id()(x, y);
        if (t < 0) continue;
        const Vec3 p = r.model_point(Vec2(x, y), r.depth()(x, y));
        const Vec3 a = liver.vertex(liver.tri[3 * t]), b = liver.vertex(liver.tri[3 * t + 1]),
                   c = liver.vertex(liver.tri[3 * t + 2]);
        const Vec3 n = (b - a).cross(c - a).normalized();
        CHECK(std::abs(n.dot(p - a)) < 1e-3);  // on the plane, mm
        CHECK((r.camera().project(T * p) - Vec2(x, y)).norm() < 1e-3);
        ++checked;
      }
    }
    CHECK(checked > 100);
  }
}

TEST_CASE("raster: morph_mask equals OpenCV erode/dilate with a square kernel") {
  const Mesh liver = liver_mesh();
  RasterConfig cfg = config_1280();
  cfg.downscale = 2;
  MeshRasterizer r;
  REQUIRE(r.configure(liver, cfg).ok());
  // Partly outside the image, so the border matters too.
  r.render(look_at(bbox_centre(liver) + Vec3(60, 0, 0), Vec3(0.1, 0.3, 1), 260, 0.2),
           bench_pinhole());
  const auto m = r.mask();
  const cv::Mat mask(m.height, m.width, CV_8U, const_cast<std::uint8_t*>(m.data), m.stride);
  REQUIRE(cv::countNonZero(mask) > 10000);
  Image<std::uint8_t> out(m.width, m.height);
  // +-16 and +-17: both paths of each (shifted rows up to 16, then counts).
  for (int k : {-24, -17, -16, -5, -2, -1, 0, 1, 3, 8, 16, 17, 24}) {
    r.morph_mask(k, out.view());
    const cv::Mat expected = test::opencv_morph_square(mask, k);
    const cv::Mat ours(m.height, m.width, CV_8U, out.data());
    CAPTURE(k);
    CHECK(cv::countNonZero(ours != expected) == 0);
  }
  // A buffer of the wrong size is left alone.
  Image<std::uint8_t> wrong(m.width + 1, m.height);
  wrong.fill(7);
  r.morph_mask(2, wrong.view());
  CHECK(wrong(0, 0) == 7);
}

TEST_CASE("raster: visible_triangles is the sorted set of ids in the buffer") {
  const Mesh liver = liver_mesh();
  MeshRasterizer r;
  REQUIRE(r.configure(liver, config_1280()).ok());
  const auto ids_in_buffer = [&r] {
    std::set<std::int32_t> ids;
    const auto buf = r.triangle_id();
    for (int y = 0; y < buf.height; ++y)
      for (int x = 0; x < buf.width; ++x)
        if (buf(x, y) >= 0) ids.insert(buf(x, y));
    return ids;
  };
  std::vector<std::int32_t> out(liver.triangle_count(), -5);
  r.render(look_at(bbox_centre(liver), Vec3(0.5, 0.5, -1), 330, 2.0), bench_pinhole());
  const std::set<std::int32_t> expected = ids_in_buffer();
  REQUIRE(expected.size() > 1000);
  const int n = r.visible_triangles(out.data(), static_cast<int>(out.size()));
  REQUIRE(n == static_cast<int>(expected.size()));
  CHECK(std::equal(expected.begin(), expected.end(), out.begin()));
  // Too small a buffer: the first entries, and the full count returned.
  std::vector<std::int32_t> few(10, -5);
  CHECK(r.visible_triangles(few.data(), 10) == n);
  CHECK(std::equal(few.begin(), few.end(), out.begin()));
  // A second render from elsewhere (part of the organ, off-centre): what
  // only the first one showed is gone, what it shows is all there.
  r.render(look_at(bbox_centre(liver) + Vec3(40, 20, 0), Vec3(-1, 0.3, 0.2), 150, 0.5),
           bench_pinhole());
  const std::set<std::int32_t> partial = ids_in_buffer();
  REQUIRE(partial.size() > 100);
  REQUIRE(partial.size() < expected.size());
  CHECK(r.visible_triangles(out.data(), static_cast<int>(out.size())) ==
        static_cast<int>(partial.size()));
  CHECK(std::equal(partial.begin(), partial.end(), out.begin()));
}

TEST_CASE("raster: bad configuration and bad input are refused or give an empty render") {
  const Pinhole K = quad_pinhole();
  const Mesh good = two_quads(K);
  RasterConfig cfg = raster_config(K);
  MeshRasterizer r;
  // Before configure: nothing to see, nothing crashes.
  r.render(SE3(), K);
  CHECK(r.mask().empty());
  float d;
  CHECK_FALSE(r.depth_at(Vec2(10, 10), &d));
  CHECK(r.visible_triangles(nullptr, 0) == 0);

  auto refused = [&](const Mesh& m, const RasterConfig& c) {
    const Status s = r.configure(m, c);
    if (!s.ok()) MESSAGE(s.message());
    return !s.ok() && !s.message().empty();
  };
  RasterConfig bad = cfg;
  bad.downscale = 3;
  CHECK(refused(good, bad));
  bad = cfg;
  bad.width = 0;
  CHECK(refused(good, bad));
  bad = cfg;
  bad.height = 100000;
  CHECK(refused(good, bad));
  bad = cfg;
  bad.near_mm = 0;
  CHECK(refused(good, bad));
  bad.near_mm = std::nan("");
  CHECK(refused(good, bad));
  Mesh m = good;
  m.tri[4] = 99;
  CHECK(refused(m, cfg));
  m = good;
  m.tri[4] = -1;
  CHECK(refused(m, cfg));
  m = good;
  m.y[2] = std::numeric_limits<float>::infinity();
  CHECK(refused(m, cfg));
  m = good;
  m.z.pop_back();
  CHECK(refused(m, cfg));
  m = good;
  m.tri.pop_back();
  CHECK(refused(m, cfg));
  CHECK(refused(Mesh{}, cfg));

  // A refused configure leaves no half-configured state behind.
  CHECK(r.mask().empty());
  REQUIRE(r.configure(good, cfg).ok());
  r.render(SE3(), K);
  CHECK(r.covered_pixels() > 0);
  SE3 nan_pose;
  nan_pose.translation().x() = std::nan("");
  r.render(nan_pose, K);
  CHECK(r.covered_pixels() == 0);
  CHECK(r.mask()(100, 100) == 0);
  Pinhole zero_f = K;
  zero_f.fx = 0;
  r.render(SE3(), zero_f);
  CHECK(r.covered_pixels() == 0);
  CHECK(r.triangle_id()(100, 100) == -1);
}

TEST_CASE("raster: downscaled raster samples the full image at the mapped pixel centres") {
  const Mesh liver = liver_mesh();
  const SE3 T = look_at(bbox_centre(liver), Vec3(0.2, -0.1, 1), 300, 0.5);
  MeshRasterizer full, half;
  RasterConfig cfg = config_1280();
  REQUIRE(full.configure(liver, cfg).ok());
  cfg.downscale = 2;
  REQUIRE(half.configure(liver, cfg).ok());
  full.render(T, bench_pinhole());
  half.render(T, bench_pinhole());
  CHECK(half.mask().width == 640);
  CHECK(half.camera().fx == doctest::Approx(500.0));
  CHECK(half.full_to_raster(Vec2(0.5, 1.5)).isApprox(Vec2(0, 0.5)));
  // Raster pixel (x, y) sits at full-resolution (2x + 0.5, 2y + 0.5): its
  // depth is the full render's depth there, up to the surface slope.
  int compared = 0;
  for (int y = 10; y < 350; y += 5) {
    for (int x = 10; x < 630; x += 5) {
      // Only inside one surface: at an occluding contour the two rasters may
      // legitimately see different surfaces.
      const auto D = full.depth();
      const float a = D(2 * x, 2 * y), b = D(2 * x + 1, 2 * y), c = D(2 * x, 2 * y + 1),
                  e = D(2 * x + 1, 2 * y + 1);
      const float lo = std::min({a, b, c, e}), hi = std::max({a, b, c, e});
      float d_full = 0;
      if (half.depth()(x, y) <= 0 || lo <= 0 || hi - lo > 0.02f * lo ||
          !full.depth_at(Vec2(2 * x + 0.5, 2 * y + 0.5), &d_full))
        continue;
      CHECK(std::abs(half.depth()(x, y) - d_full) < 0.01f * d_full);
      ++compared;
    }
  }
  CHECK(compared > 1000);
}
