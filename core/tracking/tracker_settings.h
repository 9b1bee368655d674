// The tracker's settings file: every tunable of TrackerConfig under one key,
// its name the C++ path of the field (`features.n_features`,
// `min_inlier_ratio`, `ba.w_shape`), with its allowed range and meaning.
//
// The file is OpenCV FileStorage YAML in the flat form ORB-SLAM's settings
// files use: "%YAML:1.0", then one `key: value` a line, comments after '#'.
// It is read here from bytes by a strict reader of that form (OpenCV's YAML
// reader can loop forever on malformed input; docs/design-notes.md), so
// cv::FileStorage reads every file this accepts, not the reverse.
//
// Booleans are 0 or 1 (FileStorage has no boolean; true/false are taken
// too). A key may appear once; an unknown key, a value that does not parse
// or lies outside its range is refused with the key, the line and the
// allowed range. Checks across keys (both registration sigmas or neither,
// relaxed <= strict FAST thresholds, ...) stay with Tracker::configure().
#pragma once

#include <span>
#include <string>
#include <string_view>

#include "core/base/result.h"
#include "core/tracking/tracker.h"

namespace st {

enum class SettingKind : unsigned char { kBool, kInt, kFloat, kDouble };

struct SettingKey {
  const char* key;      // "features.n_features"
  SettingKind kind;
  double lo, hi;        // allowed range, inclusive (booleans: 0..1)
  const char* help;     // one line: what it does, its unit
  void* (*field)(TrackerConfig& config);  // the field the key sets
};

// Every key, in the order the printed file lists them.
std::span<const SettingKey> tracker_setting_keys();

// Sets one key from its text value (a settings file's line, or the command
// line's --set KEY=VALUE). Errors name the key and the allowed range.
Status apply_tracker_setting(std::string_view key, std::string_view value, TrackerConfig* config);

// "KEY=VALUE" (a command line's --set) split at its first '='. False when
// there is no '=' or the key is empty.
bool split_setting_assignment(std::string_view text, std::string_view* key, std::string_view* value);

// Reads a settings file's text into config: only the keys it names change.
// Errors name the line, the key and the allowed range.
Status read_tracker_settings(std::string_view text, TrackerConfig* config);

// The settings file for config: every key with its value, range and a
// comment. read_tracker_settings() of it gives config back exactly.
std::string format_tracker_settings(const TrackerConfig& config);

}  // namespace st
