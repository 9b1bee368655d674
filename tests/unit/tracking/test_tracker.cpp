// The tracker on frames rendered from the CT liver (tests/support/track_scene):
// initialisation from the mesh depth, tracking accuracy on a smooth orbit,
// honest `lost` on frames without the organ and recovery, configuration
// errors. Allocation counting is in test_tracker_alloc.cpp.
#include <doctest/doctest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <vector>

#include "core/base/capacity.h"
#include "core/raster/rasterizer.h"
#include "core/tracking/tracker.h"
#include "support/pose_scene.h"
#include "support/support.h"
#include "support/track_scene.h"

using namespace st;
using namespace st::test;

namespace {

// Rendered once per test binary run (a few seconds), shared by the tests.
const RenderedOrbit& orbit_sequence() {
  static const RenderedOrbit seq = render_liver_orbit(90);
  return seq;
}

TrackerConfig test_config(const Pinhole& K) {
  TrackerConfig c;
  c.width = K.width;
  c.height = K.height;
  c.features.n_features = 1000;
  c.max_map_points = 6000;
  c.max_keyframes = 24;
  return c;
}

std::int64_t steady_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

TEST_CASE("tracker: configure rejects bad configs with clear errors") {
  const RenderedOrbit& seq = orbit_sequence();
  const CameraModel cam(seq.K, Distortion{});
  Tracker t;
  TrackerConfig good = test_config(seq.K);
  CHECK(t.configure(good, seq.mesh, cam, seq.T_camera_model[0]).ok());
  auto rejects = [&](TrackerConfig c, const char* what) {
    const Status s = t.configure(c, seq.mesh, cam, seq.T_camera_model[0]);
    CAPTURE(what);
    CHECK_FALSE(s.ok());
    CHECK(s.message().find(what) != std::string::npos);
  };
  TrackerConfig c = good;
  c.max_keyframes = kMaxKeyframes + 1;
  rejects(c, "max_keyframes");
  c = good;
  c.max_map_points = kMaxMapPoints + 1;
  rejects(c, "max_map_points");
  c = good;
  c.features.n_features = kMaxKeypoints + 1;
  rejects(c, "n_features");
  c = good;
  c.width = 0;
  rejects(c, "frame size");
  c = good;
  c.raster_downscale = 3;
  rejects(c, "raster_downscale");
  c = good;
  c.working_width = -1;
  rejects(c, "working_width");
  c = good;
  c.working_width = seq.K.width / 10;  // more than 8x down
  rejects(c, "working_width");
  c = good;
  c.min_inliers = 2;
  rejects(c, "min_inliers");
  // One field set to a bad value, the rest good: refused, naming the field.
  auto rejects_value = [&](auto TrackerConfig::*field, auto value, const char* what) {
    TrackerConfig bad_one = good;
    bad_one.*field = value;
    rejects(bad_one, what);
  };
  for (float motion : {0.f, -1.f, std::nanf("")})
    rejects_value(&TrackerConfig::keyframe_max_motion_px, motion, "keyframe_max_motion_px");
  for (double luma : {-1.0, 256.0, std::nan("")})
    rejects_value(&TrackerConfig::fast_reference_luma, luma, "fast_reference_luma");
  for (double contrast : {-1.0, 256.0, std::nan("")})
    rejects_value(&TrackerConfig::fast_reference_contrast, contrast, "fast_reference_contrast");
  for (double decay : {0.0, 1.5, std::nan("")})
    rejects_value(&TrackerConfig::dead_reckoning_decay, decay, "relocalisation settings");
  for (double v : {-0.1, 1.5, std::nan("")}) {
    rejects_value(&TrackerConfig::confirmed_min_inlier_ratio, v, "confirmed_min_inlier_ratio");
    rejects_value(&TrackerConfig::confirmed_keyframe_min_anchored, v, "confirmed_keyframe_min_anchored");
    rejects_value(&TrackerConfig::anchor_min_inlier_ratio, v, "anchor_min_inlier_ratio");
  }
  for (double v : {-1.0, 1e6, std::nan("")})
    rejects_value(&TrackerConfig::confirm_agreement_px, v, "confirm_agreement_px");
  for (int v : {-1, 1001}) rejects_value(&TrackerConfig::ba_lag_frames, v, "ba_lag_frames");
  for (double v : {-1.0, std::nan(""), std::numeric_limits<double>::infinity()}) {
    rejects_value(&TrackerConfig::registration_sigma_deg, v, "registration prior");
    rejects_value(&TrackerConfig::registration_sigma_mm, v, "registration prior");
    c = good;
    c.ba.prior_release_f = v;
    rejects(c, "registration prior");
  }
  rejects_value(&TrackerConfig::registration_sigma_deg, 1.0,
                "registration prior");  // one sigma set, the other 0
  rejects_value(&TrackerConfig::ba_registration_keyframes, -1, "registration prior");
  c = good;
  c.registration_sigma_deg = 1.0;  // both set: the registration refined
  c.registration_sigma_mm = 2.0;
  CHECK(t.configure(c, seq.mesh, cam, seq.T_camera_model[0]).ok());
  {
    // A 1080p calibration at the default working width: the camera the
    // tracker works with is the same lens at 1280x720 (pixel centres at
    // integers: x' = (x + 0.5) 2/3 - 0.5).
    TrackerConfig hd = good;
    hd.width = 1920;
    hd.height = 1080;
    const Pinhole K{1500.0, 1470.0, 959.5, 539.5, 1920, 1080};
    Tracker t_hd;
    REQUIRE(t_hd.configure(hd, seq.mesh, CameraModel(K, Distortion{}), seq.T_camera_model[0]).ok());
    const Pinhole w = t_hd.working_camera().pinhole();
    CHECK(w.width == 1280);
    CHECK(w.height == 720);
    CHECK(w.fx == doctest::Approx(1000.0));
    CHECK(w.fy == doctest::Approx(980.0));
    CHECK(w.cx == doctest::Approx(639.5));
    CHECK(w.cy == doctest::Approx(359.5));
    hd.working_width = 0;
    REQUIRE(t_hd.configure(hd, seq.mesh, CameraModel(K, Distortion{}), seq.T_camera_model[0]).ok());
    CHECK(t_hd.working_camera().pinhole().width == 1920);
    CHECK(t_hd.working_camera().pinhole().cx == doctest::Approx(959.5));
    // Frames of the calibration's size only; the working size's are refused.
    Image<std::uint8_t> small(1280, 720);
    t_hd.start();
    CHECK_FALSE(t_hd.step(small.cview(), 0).pose_valid);
  }
  Pinhole bad = seq.K;
  bad.fx = -1;
  CHECK_FALSE(t.configure(good, seq.mesh, CameraModel(bad, Distortion{}), seq.T_camera_model[0]).ok());
  Pinhole other = seq.K;
  other.width = 800;  // principal point still inside, size differs from the frames
  CHECK(t.configure(good, seq.mesh, CameraModel(other, Distortion{}), seq.T_camera_model[0]).message().find("calibration size") != std::string::npos);
  CHECK_FALSE(t.configure(good, Mesh{}, cam, seq.T_camera_model[0]).ok());
  // A tracker whose configure failed reports lost frames, never a pose.
  const TrackResult r = t.step(seq.frames[0].view(), 0);
  CHECK(r.state == TrackState::kLost);
  CHECK_FALSE(r.pose_valid);
}

TEST_CASE("tracker: initialisation from one frame puts map points on the mesh") {
  const RenderedOrbit& seq = orbit_sequence();
  Tracker t;
  REQUIRE(t.configure(test_config(seq.K), seq.mesh, CameraModel(seq.K, Distortion{}), seq.T_camera_model[0]).ok());
  t.start();
  const TrackResult r = t.step(seq.frames[0].view(), 0);
  CHECK(r.state == TrackState::kInitialised);
  CHECK(r.pose_valid);
  CHECK(r.keyframe);
  CHECK(r.map_points > 300);
  std::vector<Vec3> pts(static_cast<std::size_t>(r.map_points));
  REQUIRE(t.map_points(pts.data(), r.map_points) == r.map_points);
  // Distance to the surface along the viewing ray: the point's depth against
  // a full-resolution render at the same pose (the map used a 1/2 raster).
  MeshRasterizer raster;
  RasterConfig rc;
  rc.width = seq.K.width;
  rc.height = seq.K.height;
  REQUIRE(raster.configure(seq.mesh, rc).ok());
  raster.render(seq.T_camera_model[0], seq.K);
  std::vector<double> err;
  for (const Vec3& p : pts) {
    const Vec3 pc = seq.T_camera_model[0] * p;
    float d = 0.f;
    if (raster.depth_at(seq.K.project(pc), &d)) err.push_back(std::abs(pc.z() - static_cast<double>(d)));
  }
  REQUIRE(err.size() > pts.size() * 9 / 10);
  std::sort(err.begin(), err.end());
  MESSAGE("init: " << pts.size() << " points, surface distance median " << err[err.size() / 2] << " mm, 95% "
                   << err[err.size() * 95 / 100] << " mm");
  CHECK(err[err.size() / 2] < 0.2);
  CHECK(err[err.size() * 95 / 100] < 1.0);
}

TEST_CASE("tracker: tracks a rendered orbit around the liver without losing it") {
  const RenderedOrbit& seq = orbit_sequence();
  TrackerConfig cfg = test_config(seq.K);
  cfg.now_ns = &steady_ns;
  Tracker t;
  REQUIRE(t.configure(cfg, seq.mesh, CameraModel(seq.K, Distortion{}), seq.T_camera_model[0]).ok());
  t.start();
  int lost = 0, keyframes = 0;
  double worst_deg = 0, worst_mm = 0;
  std::vector<double> total_ms;
  std::vector<std::vector<double>> stage_ms(static_cast<std::size_t>(Stage::kCount));
  for (std::size_t i = 0; i < seq.frames.size(); ++i) {
    const TrackResult r = t.step(seq.frames[i].view(), static_cast<int>(i));
    keyframes += r.keyframe ? 1 : 0;
    total_ms.push_back(r.times_ms[static_cast<int>(Stage::kTotal)]);
    for (int st = 0; st < static_cast<int>(Stage::kCount); ++st)
      stage_ms[static_cast<std::size_t>(st)].push_back(r.times_ms[static_cast<std::size_t>(st)]);
    if (!r.pose_valid) {
      ++lost;
      MESSAGE("frame " << i << " lost: matches " << r.matches << " inliers " << r.inliers << " rms " << r.rms_px
                       << " mask " << r.mask_agreement << " local " << r.local_map);
      continue;
    }
    worst_deg = std::max(worst_deg, pose_delta(r.T_camera_model, seq.T_camera_model[i]).angle_deg);
    worst_mm = std::max(worst_mm, camera_centre_distance_mm(r.T_camera_model, seq.T_camera_model[i]));
  }
  std::sort(total_ms.begin(), total_ms.end());
  MESSAGE("orbit: lost " << lost << "/" << seq.frames.size() << ", worst rotation " << worst_deg << " deg, worst centre "
                         << worst_mm << " mm, keyframes inserted " << keyframes << ", median step "
                         << total_ms[total_ms.size() / 2] << " ms");
  for (int st = 0; st < static_cast<int>(Stage::kCount); ++st) {
    auto& v = stage_ms[static_cast<std::size_t>(st)];
    std::sort(v.begin(), v.end());
    MESSAGE("stage " << std::string(to_string(static_cast<Stage>(st))) << " median " << v[v.size() / 2] << " ms");
  }
  CHECK(lost == 0);
  CHECK(worst_deg < 1.0);
  CHECK(worst_mm < 3.0);
  CHECK(keyframes >= 2);
}

TEST_CASE("tracker: black and noise frames are lost, then it relocalises on the organ") {
  const RenderedOrbit& seq = orbit_sequence();
  Tracker t;
  REQUIRE(t.configure(test_config(seq.K), seq.mesh, CameraModel(seq.K, Distortion{}), seq.T_camera_model[0]).ok());
  t.start();
  int f = 0;
  for (int i = 0; i < 30; ++i, ++f) REQUIRE(t.step(seq.frames[static_cast<std::size_t>(i)].view(), f).pose_valid);
  Image<std::uint8_t> black(seq.K.width, seq.K.height), noise(seq.K.width, seq.K.height);
  std::uint32_t h = 12345;
  for (int y = 0; y < noise.height(); ++y)
    for (int x = 0; x < noise.width(); ++x) {
      h = h * 1664525u + 1013904223u;
      noise(x, y) = static_cast<std::uint8_t>(h >> 24);
    }
  for (int i = 0; i < 5; ++i, ++f) {
    const TrackResult r = t.step((i % 2 ? noise : black).view(), f);
    CAPTURE(i);
    CHECK(r.state == TrackState::kLost);
    CHECK_FALSE(r.pose_valid);
  }
  // Back on the organ, 10 frames further along the orbit than when lost.
  int first_pose = -1;
  for (int i = 40; i < 60; ++i, ++f) {
    const TrackResult r = t.step(seq.frames[static_cast<std::size_t>(i)].view(), f);
    if (!r.pose_valid) continue;
    if (first_pose < 0) {
      first_pose = i;
      CHECK(r.state == TrackState::kRelocalised);
    }
    CHECK(pose_delta(r.T_camera_model, seq.T_camera_model[static_cast<std::size_t>(i)]).angle_deg < 1.0);
    CHECK(camera_centre_distance_mm(r.T_camera_model, seq.T_camera_model[static_cast<std::size_t>(i)]) < 3.0);
  }
  MESSAGE("relocalised at orbit frame " << first_pose);
  CHECK(first_pose >= 40);
  CHECK(first_pose <= 45);
}
