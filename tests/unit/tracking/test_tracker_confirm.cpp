// Confirmed poses (TrackerConfig::confirmed_min_inlier_ratio): on smooth,
// noisy tissue most ORB matches are wrong and a right pose fails the inlier
// ratio; direct alignment against the last normal-gate frame confirms it.
// The simulator's invivo scenario (field stop, distortion, sensor noise, a
// coarser and 1 mm off CT mesh) with half the organ detail, tracked twice
// from the same frames: with confirmation, and with it turned off.
#include <doctest/doctest.h>

#include <algorithm>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/tracking/tracker.h"
#include "support/pose_scene.h"
#include "support/support.h"
#include "tools/sim/renderer.h"
#include "tools/sim/sim_run.h"

using namespace st;
using namespace st::sim;

namespace {

struct SmoothInvivo {
  SimSetup setup;
  Trajectory trajectory;
  std::vector<cv::Mat> luma;

  explicit SmoothInvivo(int frames) : setup(make(frames)), trajectory(ScenarioKind::InVivo, setup.scene, frames, 1) {
    SceneRenderer renderer;
    REQUIRE(renderer.configure(setup.scene, setup.render));
    for (int f = 0; f < frames; ++f) {
      cv::Mat rgb, labels, gray;
      renderer.render(trajectory, f, rgb, labels);
      cv::cvtColor(rgb, gray, cv::COLOR_RGB2GRAY);
      luma.push_back(gray);
    }
  }

  static SimSetup make(int frames) {
    SimOptions o;
    o.scenario = ScenarioKind::InVivo;
    o.frames = frames;
    o.seed = 1;
    o.width = 640;
    o.height = 360;
    o.organ_detail = 0.5;
    auto s = make_setup(o);
    REQUIRE(s);
    return std::move(s.value());
  }

  SE3 truth(int frame) const { return trajectory.at(frame).T_model_camera().inverse(); }

  // Mean image distance (px) between where the true organ's vertices
  // project at T and at the truth (vertices in view).
  double error_px(const SE3& T, int frame) const {
    int n = 0;
    const double px = test::vertex_reprojection_px(setup.scene.organ, setup.render.K, T, truth(frame), 7, &n);
    return n > 0 ? px : 1e9;
  }
};

double median(std::vector<double> v) {
  if (v.empty()) return 1e9;
  std::sort(v.begin(), v.end());
  return v[v.size() / 2];
}

struct Outcome {
  int lost = 0;
  // Errors of the reported poses: those direct alignment confirmed, those
  // the normal gates passed after the first confirmed one, and the worst.
  std::vector<double> confirmed_px, normal_px;
  double worst_px = 0;
};

Outcome track(const SmoothInvivo& seq, bool confirm) {
  const Pinhole& K = seq.setup.render.K;
  TrackerConfig cfg;
  cfg.width = K.width;
  cfg.height = K.height;
  if (!confirm) cfg.confirmed_min_inlier_ratio = cfg.min_inlier_ratio;
  // The mask as it was when these figures were measured (dilated, outline
  // keypoints kept): their wrong matches are what makes the ratio refuse
  // right poses here. With the default mask (patch on the organ) the same
  // frames mostly pass the normal gates, and confirmation has little to do.
  cfg.features.organ_margin_px = 12;
  cfg.features.organ_patch_inside = false;
  // And the FAST thresholds unscaled: scaled to this dim organ's luma, more
  // frames pass the normal gates (lost 90, 10 confirmed).
  cfg.fast_reference_luma = 0.0;
  // And features alone: the outline carries some of the frames both runs
  // lose (confirmation off: lost 106 instead of 139), which is not what
  // this test measures.
  cfg.use_contour = false;
  // And keypoints from the raw frame: this noisy tissue (noise ratio 3.3)
  // would have them from the filtered one, and then more frames pass the
  // normal gates (denoise_noise_ratio; the same reason as above).
  cfg.denoise_noise_ratio = 0.0;
  Tracker t;
  REQUIRE(t.configure(cfg, seq.setup.prior, CameraModel(K, seq.setup.render.distortion), seq.truth(0)).ok());
  t.start();
  Outcome o;
  for (int f = 0; f < static_cast<int>(seq.luma.size()); ++f) {
    const cv::Mat& g = seq.luma[static_cast<std::size_t>(f)];
    const TrackResult r = t.step(GrayView(g.data, g.cols, g.rows, static_cast<std::ptrdiff_t>(g.step)), f);
    if (!r.pose_valid) {
      ++o.lost;
      CHECK_FALSE(r.confirmed_by_alignment);
      continue;
    }
    const double error = seq.error_px(r.T_camera_model, f);
    o.worst_px = std::max(o.worst_px, error);
    // Normal-gate frames before the first confirmed one are left out: they
    // are the easy start near the registered pose.
    if (r.confirmed_by_alignment) o.confirmed_px.push_back(error);
    else if (f > 0 && !o.confirmed_px.empty()) o.normal_px.push_back(error);
  }
  t.stop();
  return o;
}

}  // namespace

// Measured (640x360, 150 frames, seed 1, no BA, so the same every run; the
// error is the mean over the true organ's vertices in view, which the CT
// mesh's 1 mm offset and the organ's rim make larger than the evaluator's
// marker TRE): without confirmation 139 frames are lost, the 10 tracked ones
// within 2.5 px; with it 97, 30 of them confirmed (median 5.2 px), every
// reported pose within 6.8 px; the 12 frames the normal gates passed among
// the confirmed ones: median 4.8 px.
TEST_CASE("tracker: direct alignment confirms the right poses that smooth, noisy tissue's inlier ratio refuses" *
          doctest::timeout(test::budget_s(600)) * doctest::test_suite(test::kLongSuite)) {
  const SmoothInvivo seq(150);
  const Outcome with = track(seq, true);
  const Outcome without = track(seq, false);
  MESSAGE("confirmation on: lost " << with.lost << ", confirmed " << with.confirmed_px.size() << " (error median "
                                   << median(with.confirmed_px) << " px), normal gates after the first confirmed "
                                   << with.normal_px.size() << " (median " << median(with.normal_px)
                                   << " px), worst " << with.worst_px << " px");
  MESSAGE("confirmation off: lost " << without.lost << ", worst " << without.worst_px << " px");
  CHECK(without.confirmed_px.empty());
  CHECK(with.confirmed_px.size() >= 15);
  CHECK(with.lost + 20 <= without.lost);
  CHECK(median(with.confirmed_px) <= 1.5 * median(with.normal_px));
  CHECK(with.worst_px < 12.0);
}
