// Dim frames: FAST thresholds scaled with the light
// (OrbExtractor::set_threshold_scale, TrackerConfig::fast_reference_luma).
#include <doctest/doctest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "core/features/orb_extractor.h"
#include "support/orb_fixtures.h"

using namespace st;
using namespace st::test;

namespace {

// Share of b's keypoints with a keypoint of a on the same octave within
// radius_px (level-0 pixels).
double share_found_in(const FeatureSet& b, const FeatureSet& a, float radius_px) {
  if (b.count == 0) return 0.0;
  int found = 0;
  for (int i = 0; i < b.count; ++i) {
    const Keypoint& p = b.keypoints[static_cast<std::size_t>(i)];
    for (int j = 0; j < a.count; ++j) {
      const Keypoint& q = a.keypoints[static_cast<std::size_t>(j)];
      if (q.octave == p.octave && std::hypot(q.x - p.x, q.y - p.y) <= radius_px) {
        ++found;
        break;
      }
    }
  }
  return static_cast<double>(found) / b.count;
}

}  // namespace

TEST_CASE("orb dim frames: the threshold scale keeps its floors and ignores nonsense") {
  OrbExtractor orb;
  REQUIRE(orb.configure(OrbConfig{}, 640, 360));
  CHECK(orb.strict_threshold() == 20);
  CHECK(orb.relaxed_threshold() == 7);
  orb.set_threshold_scale(0.5f);
  CHECK(orb.strict_threshold() == 10);
  CHECK(orb.relaxed_threshold() == 4);  // 3.5 rounds up
  orb.set_threshold_scale(0.f);
  CHECK(orb.strict_threshold() == OrbExtractor::kMinStrictThreshold);
  CHECK(orb.relaxed_threshold() == OrbExtractor::kMinRelaxedThreshold);
  orb.set_threshold_scale(-3.f);
  CHECK(orb.strict_threshold() == OrbExtractor::kMinStrictThreshold);
  orb.set_threshold_scale(std::numeric_limits<float>::quiet_NaN());
  CHECK(orb.threshold_scale() == 1.f);
  CHECK(orb.strict_threshold() == 20);
  orb.set_threshold_scale(4.f);  // never above the configured thresholds
  CHECK(orb.strict_threshold() == 20);
  CHECK(orb.relaxed_threshold() == 7);
  // Configured thresholds below the floors stay as configured.
  OrbConfig low;
  low.fast_threshold_strict = 4;
  low.fast_threshold_relaxed = 1;
  REQUIRE(orb.configure(low, 640, 360));
  orb.set_threshold_scale(0.25f);
  CHECK(orb.strict_threshold() == 4);
  CHECK(orb.relaxed_threshold() == 1);
}

// The real frame lit at a quarter of its light (luma above video black x
// 0.25): every intensity difference shrinks with it, and at the configured
// thresholds the dim frame keeps 841 keypoints, 45 % of them where the
// bright frame has one. With the thresholds scaled by the same 0.25: 1500
// keypoints, 79 % found again (the rest: the frame's own noise, quantised
// more coarsely in the dim copy).
TEST_CASE("orb dim frames: a dim copy of the real frame, thresholds scaled with its light, keeps its keypoints") {
  const cv::Mat bright = real_frame_luma(1280, 720);
  REQUIRE(!bright.empty());
  constexpr double kLight = 0.25, kBlack = 16.0;
  cv::Mat dim;
  bright.convertTo(dim, CV_8U, kLight, kBlack * (1.0 - kLight));
  OrbConfig cfg;
  cfg.n_features = 1500;
  OrbExtractor orb;
  REQUIRE(orb.configure(cfg, 1280, 720));
  auto a = std::make_unique<FeatureSet>(), d = std::make_unique<FeatureSet>(), s = std::make_unique<FeatureSet>();
  REQUIRE(orb.extract(view_of(bright), GrayView(), GrayView(), *a));
  REQUIRE(orb.extract(view_of(dim), GrayView(), GrayView(), *d));
  orb.set_threshold_scale(static_cast<float>(kLight));
  REQUIRE(orb.extract(view_of(dim), GrayView(), GrayView(), *s));
  const double unscaled_found = share_found_in(*a, *d, 1.5f);  // of the bright frame's keypoints
  const double scaled_found = share_found_in(*a, *s, 1.5f);
  MESSAGE("keypoints: bright " << a->count << ", dim " << d->count << ", dim with scaled thresholds " << s->count
                               << "; bright keypoints found again: " << unscaled_found << " / " << scaled_found);
  CHECK(a->count == cfg.n_features);
  CHECK(d->count < a->count * 2 / 3);
  CHECK(s->count >= a->count * 9 / 10);
  CHECK(scaled_found > unscaled_found + 0.2);
  CHECK(scaled_found > 0.7);
}
