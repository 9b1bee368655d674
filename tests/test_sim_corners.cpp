// Texture calibration of the simulator against the real liver frame: FAST
// corner density on the organ (per 10,000 organ pixels, highlights
// excluded) and the share of the organ's corners that are surface-fixed
// (found again when the same frame is rendered with another sensor-noise
// seed). Prints the figures; fails when the sim drifts out of the band.
#include <doctest/doctest.h>

#include <cmath>
#include <cstdio>

#include <opencv2/imgproc.hpp>

#include "hal/y4m_reader.h"
#include "tests/support/support.h"
#include "tools/sim/corner_density.h"
#include "tools/sim/renderer.h"
#include "tools/sim/sim_run.h"

using namespace st;
using namespace st::sim;

namespace {

constexpr int kThresholds[2] = {20, 7};

// The real frame's luma at 1280x720 (the sim's apparent resolution) and
// the liver rectangle scaled with it.
cv::Mat real_luma_720p(cv::Rect* liver) {
  Y4mReader reader;
  REQUIRE(reader.open(test::shared_data("real/laparoscopy_liver_1080p.y4m")));
  FrameRef f;
  REQUIRE(reader.read_frame(&f) == ReadResult::kFrame);
  const cv::Mat y(f.y.height, f.y.width, CV_8U, const_cast<std::uint8_t*>(f.y.data),
                    static_cast<std::size_t>(f.y.stride));
  cv::Mat out;
  cv::resize(y, out, cv::Size(1280, 720), 0, 0, cv::INTER_AREA);
  const double s = 1280.0 / y.cols;
  const cv::Rect r = kRealLiverRect1080p;
  *liver = cv::Rect(cvRound(r.x * s), cvRound(r.y * s), cvRound(r.width * s), cvRound(r.height * s));
  return out;
}

struct SimFigures {
  double organ_luma = 0, organ_per_10k[2] = {0, 0}, background_per_10k[2] = {0, 0}, organ_fixed[2] = {0, 0};
};

SimFigures measure_sim(ScenarioKind kind, const std::vector<int>& frames, int total_frames,
                       double organ_detail = 1.0) {
  SimOptions o;
  o.scenario = kind;
  o.frames = total_frames;
  o.organ_detail = organ_detail;
  auto setup = make_setup(o);
  REQUIRE(setup);
  RenderSettings other_noise = setup.value().render;
  other_noise.noise_seed = 0x9E3779B97F4A7C15ull;
  SceneRenderer a, b;
  REQUIRE(a.configure(setup.value().scene, setup.value().render));
  REQUIRE(b.configure(setup.value().scene, other_noise));
  const Trajectory traj(o.scenario, setup.value().scene, total_frames, o.seed);
  SimFigures fig;
  for (int i : frames) {
    cv::Mat rgb_a, rgb_b, labels, gray_a, gray_b;
    a.render(traj, i, rgb_a, labels);
    b.render(traj, i, rgb_b, labels);
    cv::cvtColor(rgb_a, gray_a, cv::COLOR_RGB2GRAY);
    cv::cvtColor(rgb_b, gray_b, cv::COLOR_RGB2GRAY);
    cv::Mat organ = labels == kLabelOrgan, background = labels == kLabelBackground;
    // Corners on the region's outline belong to the silhouette, not the texture.
    cv::erode(organ, organ, cv::Mat(), cv::Point(-1, -1), 4);
    cv::erode(background, background, cv::Mat(), cv::Point(-1, -1), 4);
    organ = exclude_highlights(gray_a, organ);
    background = exclude_highlights(gray_a, background);
    fig.organ_luma += cv::mean(gray_a, organ)[0] / static_cast<double>(frames.size());
    for (int t = 0; t < 2; ++t) {
      const double n = static_cast<double>(frames.size());
      fig.organ_per_10k[t] += corner_density(gray_a, organ, kThresholds[t]).per_10k / n;
      fig.background_per_10k[t] += corner_density(gray_a, background, kThresholds[t]).per_10k / n;
      fig.organ_fixed[t] += surface_fixed_share(gray_a, gray_b, organ, kThresholds[t]) / n;
    }
  }
  return fig;
}

}  // namespace

TEST_CASE("sim: organ corner density matches the real liver and the corners are surface-fixed" *
          doctest::timeout(test::budget_s(120))) {
  cv::Rect liver;
  const cv::Mat real = real_luma_720p(&liver);
  cv::Mat mask(real.size(), CV_8U, cv::Scalar(0));
  mask(liver).setTo(255);
  mask = exclude_highlights(real, mask);
  const SimFigures sim = measure_sim(ScenarioKind::Orbit, {50, 150, 250}, 300);
  std::printf("mean luma: real liver %.0f, sim organ %.0f\n", cv::mean(real, mask)[0], sim.organ_luma);
  for (int t = 0; t < 2; ++t) {
    const CornerDensity r = corner_density(real, mask, kThresholds[t]);
    std::printf("FAST>%d per 10k px: real liver %.1f (%d px) | sim organ %.1f (surface-fixed %.0f%%), "
                "sim background %.1f\n",
                kThresholds[t], r.per_10k, r.pixels, sim.organ_per_10k[t], 100.0 * sim.organ_fixed[t],
                sim.background_per_10k[t]);
    // Near the real liver's density: a factor 1.5 at ORB's threshold 20 and
    // 1.6 at 7 (measured 0.99x and 0.65x; at 7 both are mostly sensor noise).
    const double band = t == 0 ? 1.5 : 1.6;
    CHECK(sim.organ_per_10k[t] > r.per_10k / band);
    CHECK(sim.organ_per_10k[t] < r.per_10k * band);
  }
  // At ORB's threshold (20) most organ corners belong to the surface, not the
  // sensor noise (measured 61%; before the texture calibration: 0%).
  CHECK(sim.organ_fixed[0] > 0.55);
}

TEST_CASE("sim: --organ-detail makes the organ smoother, and the texture's corners go with it" *
          doctest::timeout(test::budget_s(120))) {
  const SimFigures full = measure_sim(ScenarioKind::Orbit, {150}, 300, 1.0);
  const SimFigures half = measure_sim(ScenarioKind::Orbit, {150}, 300, 0.5);
  const SimFigures none = measure_sim(ScenarioKind::Orbit, {150}, 300, 0.0);
  std::printf("FAST>20 per 10k organ px: detail 1 %.1f, 0.5 %.1f, 0 %.1f; mean luma %.0f %.0f %.0f\n",
              full.organ_per_10k[0], half.organ_per_10k[0], none.organ_per_10k[0], full.organ_luma,
              half.organ_luma, none.organ_luma);
  CHECK(half.organ_per_10k[0] < 0.5 * full.organ_per_10k[0]);
  CHECK(none.organ_per_10k[0] < half.organ_per_10k[0]);
  // Smoother, not darker or brighter: the speckle modulates around the albedo.
  CHECK(std::abs(half.organ_luma - full.organ_luma) < 8.0);
  // The background's texture is untouched.
  CHECK(half.background_per_10k[0] == doctest::Approx(full.background_per_10k[0]).epsilon(0.01));
}

namespace {

// Whether a renderer accepts the settings made by options whose `field`
// is set to value (10 frames, the rest default).
bool renderer_accepts(double SimOptions::*field, double value) {
  SimOptions o;
  o.frames = 10;
  o.*field = value;
  auto setup = make_setup(o);
  REQUIRE(setup);
  SceneRenderer r;
  return r.configure(setup.value().scene, setup.value().render).ok();
}

}  // namespace

TEST_CASE("sim: organ detail outside 0..2 or not a number is refused") {
  for (double bad : {-0.1, 2.5, std::nan("")}) CHECK_FALSE(renderer_accepts(&SimOptions::organ_detail, bad));
}

TEST_CASE("sim: a shutter outside 0..1 or not a number is refused") {
  for (double bad : {-0.1, 1.5, std::nan("")}) CHECK_FALSE(renderer_accepts(&SimOptions::shutter, bad));
  CHECK(renderer_accepts(&SimOptions::shutter, 0.0));
}
