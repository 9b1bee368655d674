// Surgical smoke in the simulator (tools/sim/smoke.h): episodes that come
// and clear, a veil that lifts the dark tissue towards the airlight and
// flattens its texture, labels untouched, and no change without it.
#include <doctest/doctest.h>

#include <cmath>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "support/support.h"
#include "tools/sim/renderer.h"
#include "tools/sim/sim_run.h"
#include "tools/sim/smoke.h"

using namespace st;
using namespace st::sim;

namespace {

struct Rendered {
  cv::Mat gray, labels;
};

Rendered render_frame(double smoke, int frame) {
  SimOptions o;
  o.scenario = ScenarioKind::Orbit;
  o.frames = 300;
  o.seed = 3;
  o.width = 320;
  o.height = 180;
  o.smoke = smoke;
  auto setup = make_setup(o);
  REQUIRE(setup);
  const Trajectory trajectory(o.scenario, setup->scene, o.frames, o.seed);
  SceneRenderer renderer;
  REQUIRE(renderer.configure(setup->scene, setup->render));
  Rendered r;
  cv::Mat rgb;
  renderer.render(trajectory, frame, rgb, r.labels);
  cv::cvtColor(rgb, r.gray, cv::COLOR_RGB2GRAY);
  return r;
}

// Mean and standard deviation of the luma over organ pixels.
void organ_stats(const Rendered& r, double* mean, double* stddev) {
  cv::Mat organ = r.labels == kLabelOrgan;
  cv::Scalar m, s;
  cv::meanStdDev(r.gray, m, s, organ);
  *mean = m[0];
  *stddev = s[0];
}

}  // namespace

TEST_CASE("sim smoke: episodes build up, hold and clear, the veil's share stays within the opacity") {
  SmokeVeil veil;
  veil.configure(0.7, 5, 320, 180);
  REQUIRE(veil.enabled());
  int first = -1, thick = 0, clear_after = 0;
  for (int f = 0; f < 600; ++f) {
    const double e = veil.envelope(f);
    REQUIRE(e >= 0.0);
    REQUIRE(e <= 1.0);
    if (e > 0.0 && first < 0) first = f;
    thick += e > 0.99;
    if (first >= 0 && e == 0.0) ++clear_after;
  }
  MESSAGE("first episode at frame " << first << ", " << thick << " of 600 frames at full thickness");
  CHECK(first >= 20);
  CHECK(first <= 60);
  CHECK(thick >= 2 * 25);   // at least 2 episodes in 20 s, each holding ~1 s
  CHECK(clear_after > 100); // and clear spells between them
  for (int f = 0; f < 300; f += 7)
    for (double x : {0.0, 100.5, 319.0})
      for (double y : {0.0, 90.0, 179.0}) {
        const double a = veil.share(f, x, y);
        CHECK(a >= 0.0);
        CHECK(a <= 0.7 + 1e-12);
      }
  SmokeVeil none;
  none.configure(0.0, 5, 320, 180);
  CHECK_FALSE(none.enabled());
  CHECK(none.envelope(60) == 0.0);
}

TEST_CASE("sim smoke: a thick veil lifts and flattens the organ, leaves the labels, no smoke, no change" *
          doctest::timeout(st::test::budget_s(60))) {
  // Seed 3's first episode: find a frame at full thickness.
  SmokeVeil veil;
  veil.configure(0.8, 3, 320, 180);
  int frame = -1;
  for (int f = 0; f < 300 && frame < 0; ++f)
    if (veil.envelope(f) > 0.99) frame = f;
  REQUIRE(frame >= 0);
  const Rendered clear = render_frame(0.0, frame), smoky = render_frame(0.8, frame);
  CHECK(cv::countNonZero(clear.labels != smoky.labels) == 0);
  double m0, s0, m1, s1;
  organ_stats(clear, &m0, &s0);
  organ_stats(smoky, &m1, &s1);
  MESSAGE("frame " << frame << ": organ luma mean " << m0 << " -> " << m1 << ", std " << s0 << " -> " << s1);
  CHECK(m1 > m0 + 10.0);  // the veil is brighter than the dark liver
  CHECK(s1 < 0.7 * s0);   // and hides its texture
  // Outside an episode, and with smoke 0, the frame is the one without smoke.
  int calm = -1;
  for (int f = 0; f < 300 && calm < 0; ++f)
    if (veil.envelope(f) == 0.0) calm = f;
  REQUIRE(calm >= 0);
  const Rendered a = render_frame(0.0, calm), b = render_frame(0.8, calm);
  CHECK(cv::norm(a.gray, b.gray, cv::NORM_INF) == 0.0);
}

TEST_CASE("sim smoke: out-of-range opacity is refused") {
  SimOptions o;
  o.scenario = ScenarioKind::Orbit;
  o.width = 64;
  o.height = 48;
  for (double bad : {-0.1, 0.95, std::nan("")}) {
    o.smoke = bad;
    auto setup = make_setup(o);
    REQUIRE(setup);
    SceneRenderer renderer;
    CHECK_FALSE(renderer.configure(setup->scene, setup->render));
  }
}
