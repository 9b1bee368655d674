// The tracker's settings file (core/tracking/tracker_settings.h): every key
// round-trips, the defaults lie in their ranges and pass the tracker's own
// checks, cv::FileStorage reads the printed file, and bad bytes are refused
// with the line and the key.
#include <doctest/doctest.h>

#include <cmath>
#include <set>
#include <string>

#include <opencv2/core.hpp>

#include "core/tracking/tracker_settings.h"

using namespace st;

namespace {

// Every key's value as the printed file spells it (a line "key: value").
std::string value_of(const std::string& text, const std::string& key) {
  const std::size_t at = text.find("\n" + key + ": ");
  REQUIRE_MESSAGE(at != std::string::npos, key);
  const std::size_t begin = at + key.size() + 3;
  return text.substr(begin, text.find('\n', begin) - begin);
}

}  // namespace

TEST_CASE("settings: every key once, named as its field, its default inside its range") {
  std::set<std::string> names;
  const TrackerConfig defaults;
  const std::string text = format_tracker_settings(defaults);
  for (const SettingKey& k : tracker_setting_keys()) {
    CAPTURE(k.key);
    CHECK(names.insert(k.key).second);
    CHECK(k.lo <= k.hi);
    // The default, read back through the key, is accepted unchanged.
    TrackerConfig c;
    CHECK(apply_tracker_setting(k.key, value_of(text, k.key), &c).ok());
    CHECK(format_tracker_settings(c) == text);
  }
  CHECK(names.size() > 70);
  CHECK(validate_tracker_settings(defaults).ok());
}

TEST_CASE("settings: a changed value of each kind round-trips exactly through the file") {
  TrackerConfig c;
  REQUIRE(apply_tracker_setting("features.scale_factor", "1.3", &c).ok());
  REQUIRE(apply_tracker_setting("ba.w_shape", "37.25", &c).ok());
  REQUIRE(apply_tracker_setting("min_inliers", "+40", &c).ok());
  REQUIRE(apply_tracker_setting("use_ba", "false", &c).ok());
  REQUIRE(apply_tracker_setting("search_radius_px", " 12.5 ", &c).ok());
  CHECK(c.features.scale_factor == 1.3f);
  CHECK(c.ba.w_shape == 37.25);
  CHECK(c.min_inliers == 40);
  CHECK_FALSE(c.use_ba);
  CHECK(c.search_radius_px == 12.5f);
  TrackerConfig back;
  REQUIRE(read_tracker_settings(format_tracker_settings(c), &back).ok());
  CHECK(format_tracker_settings(back) == format_tracker_settings(c));
  CHECK(back.features.scale_factor == 1.3f);
  CHECK(back.ba.w_shape == 37.25);
  CHECK_FALSE(back.use_ba);
  // A file naming some keys changes only those.
  TrackerConfig partial;
  REQUIRE(read_tracker_settings("%YAML:1.0\n---\n# a comment\nmin_inliers: 25  # trailing\n\n", &partial).ok());
  CHECK(partial.min_inliers == 25);
  CHECK(partial.max_rms_px == TrackerConfig{}.max_rms_px);
}

TEST_CASE("settings: cv::FileStorage reads the printed file with the same values") {
  TrackerConfig c;
  c.ba.w_shape = 12.5;
  c.features.n_features = 1234;
  c.use_occluder_mask = false;
  c.min_inlier_ratio = 0.3;
  const std::string text = format_tracker_settings(c);
  cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  REQUIRE(fs.isOpened());
  CHECK(static_cast<double>(fs["ba.w_shape"]) == 12.5);
  CHECK(static_cast<int>(fs["features.n_features"]) == 1234);
  CHECK(static_cast<int>(fs["use_occluder_mask"]) == 0);
  CHECK(static_cast<double>(fs["min_inlier_ratio"]) == 0.3);
  CHECK(static_cast<double>(fs["features.scale_factor"]) == doctest::Approx(1.2));
}

TEST_CASE("settings: bad files are refused with the line and the key, the config untouched") {
  const auto refused = [](const std::string& text, const std::string& message) {
    CAPTURE(text);
    TrackerConfig c;
    c.min_inliers = 31;
    const Status s = read_tracker_settings(text, &c);
    REQUIRE_FALSE(s.ok());
    CHECK_MESSAGE(s.message().find(message) != std::string::npos, s.message());
    CHECK(c.min_inliers == 31);  // nothing applied, not even the good lines before
  };
  refused("min_inliers: 40\nmin_inlier: 0.3\n", "line 2: unknown setting 'min_inlier'");
  refused("min_inliers: 40\nmin_inliers: 41\n", "line 2: min_inliers is given twice");
  refused("min_inliers: 40\nmin_inlier_ratio: 1.5\n", "line 2: min_inlier_ratio: '1.5' is not a number in 0..1");
  refused("min_inliers: 5\n", "min_inliers: '5' is not a whole number in 6..4096");
  refused("min_inliers: 7.5\n", "is not a whole number");
  refused("min_inliers: 1e3\n", "is not a whole number");
  refused("max_rms_px: nan\n", "max_rms_px: 'nan'");
  refused("max_rms_px: inf\n", "max_rms_px: 'inf'");
  refused("search_radius_px: 1e40\n", "search_radius_px: '1e40'");
  refused("use_mask: yes\n", "use_mask: 'yes' is not 0 or 1");
  refused("use_mask:\n", "use_mask has no value");
  refused("features:\n  n_features: 100\n", "line 1: unknown setting 'features'");
  refused("  min_inliers: 40\n", "indented");
  refused("min_inliers 40\n", "expected 'key: value'");
  refused(": 40\n", "expected 'key: value'");
  refused(std::string("min_inliers: 4") + '\0' + "0\n", "control characters");
  refused("min_inliers: 40\x01\n", "control characters");
  refused("{min_inliers: 40}\n", "unknown setting '{min_inliers'");
  // Long junk is quoted short.
  TrackerConfig c;
  const Status s = apply_tracker_setting(std::string(5000, 'k'), "1", &c);
  CHECK_FALSE(s.ok());
  CHECK(s.message().size() < 200);
}
