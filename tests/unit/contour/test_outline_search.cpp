// OutlineSearch: the organ's silhouette from every side finds a view the
// tracker's guess cannot reach, and the outline's fit from it is exact.
#include <doctest/doctest.h>

#include <cmath>

#include "core/contour/outline_search.h"
#include "core/contour/region_modality.h"
#include "hal/storage/mesh_file.h"
#include "tests/support/alloc_guard.h"
#include "tests/support/flat_frame.h"
#include "tests/support/raster_scene.h"
#include "tests/support/support.h"

using namespace st;

namespace {

Mesh liver() {
  auto m = load_mesh_file(test::shared_data("liver/liver.ply"), nullptr);
  REQUIRE_MESSAGE(m, (m ? std::string() : m.message()));
  return std::move(m).value();
}

// The liver seen through a 960x540 camera, and the view whose colours the
// models learn.
struct LiverScene {
  Mesh mesh = liver();
  Pinhole K{800.0, 800.0, 479.5, 269.5, 960, 540};
  CameraModel camera{K, Distortion{}};
  Vec3 centre = test::bbox_centre(mesh);
  SE3 T_learn = test::look_at(centre, Vec3(0.2, -0.3, 1.0).normalized(), 300.0, 0.3);
};

}  // namespace

TEST_CASE("outline search: a view from another side, closer and rolled, is found and fitted") {
  const LiverScene scene;
  const Mesh& mesh = scene.mesh;
  const Pinhole& K = scene.K;
  const CameraModel& camera = scene.camera;
  const Vec3& centre = scene.centre;
  // The colours learnt at one view...
  const SE3& T_learn = scene.T_learn;
  RegionModality region;
  REQUIRE(region.configure(mesh, K.width, K.height));
  const test::Frame learn = test::render_flat(mesh, K, T_learn, 7);
  region.learn(learn.luma(), learn.chroma(), GrayView{}, camera, T_learn);
  REQUIRE(region.has_colour_model());
  OutlineSearch search;
  REQUIRE(search.configure(mesh, K));
  search.learn(learn.luma(), learn.chroma(), GrayView{}, region.raster(), 1.f);  // region rendered at T_learn
  REQUIRE(search.has_colour_model());
  // ... and views far from it: other sides, other distances, rolls, off centre.
  struct View {
    Vec3 dir;
    double distance, roll;
    Vec2 shift;  // the organ's centre off the optical axis, mm
  };
  const View views[] = {{Vec3(-0.8, 0.1, 0.6), 240.0, 1.9, Vec2(20, 10)},
                        {Vec3(0.9, 0.4, 0.2), 260.0, -2.5, Vec2(-15, 5)},
                        {Vec3(0.1, 0.9, -0.4), 280.0, 0.8, Vec2(0, -12)}};
  for (const View& v : views) {
    CAPTURE(v.dir.transpose());
    SE3 T_true = test::look_at(centre, v.dir.normalized(), v.distance, v.roll);
    T_true.translation() += Vec3(v.shift.x(), v.shift.y(), 0);
    const test::Frame f = test::render_flat(mesh, K, T_true, 11);
    std::array<OutlineCandidate, 3> c;
    const test::AllocationCounter counter;
    const int n = search.search(f.luma(), f.chroma(), GrayView{}, c.data(), 3);
    CHECK(counter.count() == 0);
    REQUIRE(n == 3);
    CHECK(search.stats().searched);
    // The best fit of the candidates, as the tracker takes it.
    double best_chi2 = 1e300, best_deg = 0, best_mm = 0, nearest_deg = 1e9;
    for (int i = 0; i < n; ++i) {
      nearest_deg = std::min(nearest_deg, pose_delta(c[static_cast<std::size_t>(i)].T_camera_model, T_true).angle_deg);
      SE3 T = c[static_cast<std::size_t>(i)].T_camera_model;
      ContourFit fit;
      if (!region.estimate(f.luma(), f.chroma(), GrayView{}, camera, &T, &fit)) continue;
      if (fit.chi2_per_line >= best_chi2) continue;
      best_chi2 = fit.chi2_per_line;
      best_deg = pose_delta(T, T_true).angle_deg;
      best_mm = (T * centre - T_true * centre).norm();
    }
    MESSAGE("nearest candidate " << nearest_deg << " deg; best fit " << best_deg << " deg, organ " << best_mm
                                 << " mm off (chi2 " << best_chi2 << "), " << search.stats().candidates_scored
                                 << " candidates scored");
    CHECK(nearest_deg < 30.0);
    CHECK(best_deg < 1.0);
    CHECK(best_mm < 2.0);
  }
}

TEST_CASE("outline search: no search without colours, with the organ filling or missing the frame, or bad input") {
  const LiverScene scene;
  OutlineSearch search;
  CHECK_FALSE(search.configure(Mesh{}, scene.K).ok());
  CHECK_FALSE(search.configure(scene.mesh, Pinhole{0.0, 800.0, 479.5, 269.5, 960, 540}).ok());
  CHECK_FALSE(search.configure(scene.mesh, Pinhole{800.0, 800.0, -5.0, 269.5, 960, 540}).ok());
  REQUIRE(search.configure(scene.mesh, scene.K).ok());
  RegionModality region;
  REQUIRE(region.configure(scene.mesh, scene.K.width, scene.K.height));
  const test::Frame f = test::render_flat(scene.mesh, scene.K, scene.T_learn, 3);
  std::array<OutlineCandidate, 3> c;
  CHECK(search.search(f.luma(), f.chroma(), GrayView{}, c.data(), 3) == 0);  // no colour model yet
  region.learn(f.luma(), f.chroma(), GrayView{}, scene.camera, scene.T_learn);
  search.learn(f.luma(), f.chroma(), GrayView{}, region.raster(), 1.f);
  CHECK(search.search(f.luma(), f.chroma(), GrayView{}, c.data(), 3) == 3);
  // Far too close: the organ fills the frame.
  const SE3 T_close = test::look_at(scene.centre, Vec3(0.2, -0.3, 1.0).normalized(), 60.0, 0.3);
  const test::Frame close = test::render_flat(scene.mesh, scene.K, T_close, 4);
  CHECK(search.search(close.luma(), close.chroma(), GrayView{}, c.data(), 3) == 0);
  CHECK_FALSE(search.stats().searched);
  // Looking away: no organ.
  const SE3 T_away = test::look_at(scene.centre + Vec3(0, 0, 2000), Vec3(0.2, -0.3, 1.0).normalized(), 300.0, 0.3);
  const test::Frame away = test::render_flat(scene.mesh, scene.K, T_away, 5);
  CHECK(search.search(away.luma(), away.chroma(), GrayView{}, c.data(), 3) == 0);
  // A frame of another size is not searched.
  const GrayView half{f.y.data(), scene.K.width / 2, scene.K.height / 2, scene.K.width};
  CHECK(search.search(half, ChromaView{}, GrayView{}, c.data(), 3) == 0);
}
