// RegionModality: the outline of a textureless organ (a flat-coloured CT
// liver on a background of another colour) measures the camera pose.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "core/contour/region_modality.h"
#include "core/raster/rasterizer.h"
#include "hal/storage/mesh_file.h"
#include "tests/support/flat_frame.h"
#include "tests/support/raster_scene.h"
#include "tests/support/support.h"

using namespace st;

namespace {

// The organ's rim darkened as where its surface turns away from the scope's
// light: luma falls from 95 to 40 over the last 40 px inside the outline,
// and the organ's chroma (its hue) falls with it, as a surface's chroma
// scales with its luma; the background is a near-grey at the rim's darkest
// luma.
// With chroma levels of their own, the dark rim reads as background.
test::Frame render_dark_rim(const Mesh& mesh, const Pinhole& K, const SE3& T, std::uint64_t seed) {
  MeshRasterizer r;
  REQUIRE(r.configure(mesh, test::raster_config(K)));
  r.render(T, K);
  const auto m = r.mask();
  const int w = K.width, h = K.height;
  // Chamfer distance (3-4) of each organ pixel to the nearest non-organ one.
  std::vector<int> d(static_cast<std::size_t>(w * h));
  const auto at = [&](int x, int y) -> int& { return d[static_cast<std::size_t>(y * w + x)]; };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) at(x, y) = m(x, y) ? 1 << 20 : 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      if (x > 0) at(x, y) = std::min(at(x, y), at(x - 1, y) + 3);
      if (y > 0) at(x, y) = std::min(at(x, y), at(x, y - 1) + 3);
      if (x > 0 && y > 0) at(x, y) = std::min(at(x, y), at(x - 1, y - 1) + 4);
      if (x + 1 < w && y > 0) at(x, y) = std::min(at(x, y), at(x + 1, y - 1) + 4);
    }
  for (int y = h - 1; y >= 0; --y)
    for (int x = w - 1; x >= 0; --x) {
      if (x + 1 < w) at(x, y) = std::min(at(x, y), at(x + 1, y) + 3);
      if (y + 1 < h) at(x, y) = std::min(at(x, y), at(x, y + 1) + 3);
      if (x + 1 < w && y + 1 < h) at(x, y) = std::min(at(x, y), at(x + 1, y + 1) + 4);
      if (x > 0 && y + 1 < h) at(x, y) = std::min(at(x, y), at(x - 1, y + 1) + 4);
    }
  test::Frame f;
  f.w = w;
  f.h = h;
  const int cw = (w + 1) / 2, ch = (h + 1) / 2;
  f.y.assign(static_cast<std::size_t>(w * h), 0);
  f.u.assign(static_cast<std::size_t>(cw * ch), 0);
  f.v.assign(static_cast<std::size_t>(cw * ch), 0);
  std::mt19937 gen(static_cast<std::uint32_t>(seed));
  std::normal_distribution<double> nd;
  // The organ's luma at a pixel (the background's: 40).
  const auto organ_luma = [&](int x, int y) {
    if (!m(x, y)) return 40.0;
    const double rim = std::min(1.0, at(x, y) / (3.0 * 40.0));
    return 40.0 + 55.0 * rim;
  };
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      f.y[static_cast<std::size_t>(y * w + x)] =
          static_cast<std::uint8_t>(std::clamp(organ_luma(x, y) + 2.0 * nd(gen), 0.0, 255.0));
  for (int y = 0; y < ch; ++y)
    for (int x = 0; x < cw; ++x) {
      double du = 0, dv = 0, background = 0;
      for (int k = 0; k < 4; ++k) {
        const int px = std::min(2 * x + (k & 1), w - 1), py = std::min(2 * y + (k >> 1), h - 1);
        if (!m(px, py)) {
          background += 0.25;
          continue;
        }
        const double scale = (organ_luma(px, py) - 16.0) / (95.0 - 16.0);  // hue kept, chroma with luma
        du += 0.25 * 4.0 * scale;
        dv += 0.25 * 22.0 * scale;
      }
      f.u[static_cast<std::size_t>(y * cw + x)] =
          static_cast<std::uint8_t>(std::lround(128 + du + 2 * background + 1.0 * nd(gen)));
      f.v[static_cast<std::size_t>(y * cw + x)] =
          static_cast<std::uint8_t>(std::lround(128 + dv + 2 * background + 1.0 * nd(gen)));
    }
  return f;
}

struct LiverView {
  Mesh mesh;
  Pinhole K{800.0, 800.0, 479.5, 269.5, 960, 540};
  SE3 T;
};

LiverView liver_view() {
  auto m = load_mesh_file(test::shared_data("liver/liver.ply"), nullptr);
  REQUIRE_MESSAGE(m, (m ? std::string() : m.message()));
  LiverView v;
  v.mesh = std::move(m).value();
  // Far enough that the whole outline is in view (about 2/3 of the image).
  v.T = test::look_at(test::bbox_centre(v.mesh), Vec3(0.2, -0.3, 1.0).normalized(), 260.0, 0.3);
  return v;
}

}  // namespace

TEST_CASE("contour: the outline alone recovers a perturbed pose of a textureless organ") {
  const LiverView v = liver_view();
  const CameraModel camera(v.K, Distortion{});
  const test::Frame f = test::render_flat(v.mesh, v.K, v.T, 7);
  RegionModality region;
  REQUIRE(region.configure(v.mesh, v.K.width, v.K.height));
  region.learn(f.luma(), f.chroma(), GrayView{}, camera, v.T);
  REQUIRE(region.has_colour_model());
  std::mt19937 gen(11);
  std::normal_distribution<double> nd;
  for (int trial = 0; trial < 6; ++trial) {
    CAPTURE(trial);
    // 2 deg and 8 mm, in random directions.
    Vec3 w(nd(gen), nd(gen), nd(gen));
    Vec3 t(nd(gen), nd(gen), nd(gen));
    Vec6 xi;
    xi << w.normalized() * (2.0 * M_PI / 180.0), t.normalized() * 8.0;
    SE3 T = SE3::exp(xi) * v.T;
    const PoseDelta before = pose_delta(T, v.T);
    ContourFit fit;
    REQUIRE(region.estimate(f.luma(), f.chroma(), GrayView{}, camera, &T, &fit));
    const PoseDelta after = pose_delta(T, v.T);
    // The organ's centre in the camera frame: where the overlay draws it.
    const Vec3 c = test::bbox_centre(v.mesh);
    const double organ_mm = (T * c - v.T * c).norm();
    MESSAGE("from " << before.angle_deg << " deg, organ " << (SE3::exp(xi) * v.T * c - v.T * c).norm() << " mm off to "
                    << after.angle_deg << " deg, " << organ_mm << " mm, " << fit.lines << " lines, rms " << fit.rms_px
                    << " px");
    CHECK(fit.lines >= 100);
    CHECK(after.angle_deg < 0.5);
    CHECK(organ_mm < 1.0);
  }
}

TEST_CASE("contour: no evidence where the valid mask is off, no lines without a colour model") {
  const LiverView v = liver_view();
  const CameraModel camera(v.K, Distortion{});
  const test::Frame f = test::render_flat(v.mesh, v.K, v.T, 3);
  RegionModality region;
  REQUIRE(region.configure(v.mesh, v.K.width, v.K.height));
  CHECK(region.measure(f.luma(), f.chroma(), GrayView{}, camera, v.T, 1) == 0);  // no colour model yet
  region.learn(f.luma(), f.chroma(), GrayView{}, camera, v.T);
  const int all = region.measure(f.luma(), f.chroma(), GrayView{}, camera, v.T, 1);
  // The field stop (or an instrument) over the left half: only the right
  // half's outline is measured.
  std::vector<std::uint8_t> valid(static_cast<std::size_t>(v.K.width / 2 * (v.K.height / 2)), 255);
  const GrayView vm{valid.data(), v.K.width / 2, v.K.height / 2, v.K.width / 2};
  for (int y = 0; y < vm.height; ++y)
    for (int x = 0; x < vm.width / 2; ++x) valid[static_cast<std::size_t>(y * vm.width + x)] = 0;
  const int right = region.measure(f.luma(), f.chroma(), vm, camera, v.T, 1);
  MESSAGE(all << " lines, " << right << " with the left half masked");
  CHECK(all >= 100);
  CHECK(right > 0);
  CHECK(right < 0.8 * all);
  // Non-finite pose: nothing measured.
  SE3 bad = v.T;
  bad = SE3(bad.rotation(), Vec3(std::nan(""), 0, 0));
  CHECK(region.measure(f.luma(), f.chroma(), GrayView{}, camera, bad, 1) == 0);
}

TEST_CASE("contour: an organ's rim darkened by the light still counts as organ: the outline is not pulled in") {
  const LiverView v = liver_view();
  const CameraModel camera(v.K, Distortion{});
  const test::Frame f = render_dark_rim(v.mesh, v.K, v.T, 5);
  RegionModality region;
  REQUIRE(region.configure(v.mesh, v.K.width, v.K.height));
  region.learn(f.luma(), f.chroma(), GrayView{}, camera, v.T);
  // At the true pose the lines find the outline where it is.
  REQUIRE(region.measure(f.luma(), f.chroma(), GrayView{}, camera, v.T, 1) >= 100);
  ContourFit at_truth;
  region.evaluate(v.T, &at_truth);
  MESSAGE(at_truth.lines << " lines at the true pose, rms " << at_truth.rms_px << " px");
  CHECK(at_truth.rms_px < 1.5);
  // And from a perturbed pose the outline comes back to it.
  Vec6 xi;
  xi << Vec3(0.3, -0.5, 0.8).normalized() * (2.0 * M_PI / 180.0), Vec3(-0.6, 0.2, 0.5).normalized() * 8.0;
  SE3 T = SE3::exp(xi) * v.T;
  ContourFit fit;
  REQUIRE(region.estimate(f.luma(), f.chroma(), GrayView{}, camera, &T, &fit));
  const Vec3 c = test::bbox_centre(v.mesh);
  MESSAGE("recovered to " << pose_delta(T, v.T).angle_deg << " deg, organ " << (T * c - v.T * c).norm() << " mm off");
  CHECK(pose_delta(T, v.T).angle_deg < 0.5);
  CHECK((T * c - v.T * c).norm() < 1.0);
}
