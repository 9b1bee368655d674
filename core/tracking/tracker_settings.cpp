#include "core/tracking/tracker_settings.h"

#include <array>
#include <charconv>
#include <type_traits>

#include "core/base/capacity.h"
#include "core/contour/region_modality.h"
#include "core/formats/text_scan.h"

namespace st {

namespace {

template <class T>
constexpr SettingKind kind_of() {
  if constexpr (std::is_same_v<T, bool>) return SettingKind::kBool;
  else if constexpr (std::is_same_v<T, int>) return SettingKind::kInt;
  else if constexpr (std::is_same_v<T, float>) return SettingKind::kFloat;
  else {
    static_assert(std::is_same_v<T, double>, "a setting is bool, int, float or double");
    return SettingKind::kDouble;
  }
}

// One key: its name is the field's path in TrackerConfig.
#define ST_SETTING(path, lo, hi, help)                                                   \
  SettingKey {                                                                           \
    #path, kind_of<decltype(TrackerConfig{}.path)>(), static_cast<double>(lo),           \
        static_cast<double>(hi), help, [](TrackerConfig& c) -> void* { return &c.path; } \
  }

constexpr double kMaxMeshTrianglesD = static_cast<double>(kMaxMeshTriangles);

// The ranges are those Tracker::configure() and the stages' configure()
// accept (a narrower one where a wider value makes no sense: a FAST cell
// larger than a frame, a time limit of hours).
const std::array kKeys = {
    ST_SETTING(working_width, 0, kMaxImageWidth,
               "the tracker's frame width: a wider frame is brought down to it, the height in proportion (0: the frame's)"),
    // The ORB frontend (core/features/orb_extractor.h).
    ST_SETTING(features.n_features, 50, kMaxKeypoints, "keypoints a frame, over all pyramid levels"),
    ST_SETTING(features.levels, 1, kMaxPyramidLevels, "pyramid levels"),
    ST_SETTING(features.scale_factor, 1.05, 2.0, "scale between neighbouring pyramid levels"),
    ST_SETTING(features.fast_threshold_strict, 1, 254, "FAST threshold, 8-bit luma difference"),
    ST_SETTING(features.fast_threshold_relaxed, 1, 254,
               "FAST threshold in threshold cells where the strict one found nothing (<= strict)"),
    ST_SETTING(features.threshold_cell_px, 8, 512, "threshold cell size, level pixels"),
    ST_SETTING(features.edge_border_px, 16, 64, "no keypoint closer to a level's edge, level pixels"),
    ST_SETTING(features.organ_margin_px, -256, 256,
               "organ mask margin, level-0 pixels: > 0 dilates, < 0 erodes"),
    ST_SETTING(features.denoise, 0, 1, "keypoints from the frame through a 3x3 binomial filter (0: as denoise_noise_ratio decides)"),
    ST_SETTING(denoise_noise_ratio, 0, 1000,
               "the filter when the organ's pixel-level contrast is this many times its block contrast (0: never)"),
    ST_SETTING(features.organ_patch_inside, 0, 1,
               "keep a keypoint only if its descriptor patch lies on the organ"),
    ST_SETTING(features.min_spread_cell_px, 2, 512, "smallest spreading cell, level pixels"),
    ST_SETTING(features.spread_cell_keypoints, 1, 1024,
               "keypoints a spreading cell is sized for (1: evenness, larger: strong corners win)"),
    ST_SETTING(fast_reference_luma, 0, 255,
               "frames whose organ median luma is below this scale FAST thresholds down (0: off)"),
    ST_SETTING(fast_reference_contrast, 0, 255,
               "frames whose organ texture contrast is below this scale FAST thresholds down (0: off)"),
    // Pseudo-segmentation: the mesh rendered at the predicted pose.
    ST_SETTING(use_mask, 0, 1, "features only inside the rendered organ (0: whole valid image, ablation)"),
    ST_SETTING(raster_downscale, 1, 4, "render at 1/N of the frame size: 1, 2 or 4"),
    ST_SETTING(max_raster_triangles, 0, kMaxMeshTrianglesD,
               "render a simplified copy of a denser prior, at most this many triangles (0: never; else >= 1000)"),
    ST_SETTING(use_occluder_mask, 0, 1, "instruments (near-neutral chroma) leave the valid mask"),
    // Matching.
    ST_SETTING(matching.max_distance, 1, 256, "largest Hamming distance of a match, of 256 bits"),
    ST_SETTING(matching.ratio, 0.01, 1.0, "best < ratio x second best (1: no ratio test)"),
    ST_SETTING(matching.check_orientation, 0, 1, "keep matches of the dominant rotation only"),
    ST_SETTING(matching.rotation_bins, 3, 360, "bins of the orientation check"),
    ST_SETTING(matching.octave_window, 0, kMaxPyramidLevels, "search by projection: predicted octave +- this"),
    ST_SETTING(matching.use_popcnt, 0, 1, "count bits with POPCNT where the CPU has it"),
    ST_SETTING(search_radius_px, 0.5, 500, "search radius around the prediction, level-0 pixels"),
    ST_SETTING(wide_radius_px, 0.5, 1000, "second, wider search when the first finds too few (>= search)"),
    ST_SETTING(refine_radius_px, 0.5, 500, "search again at the first solved pose, level-0 pixels"),
    // The map.
    ST_SETTING(refresh_descriptors, 0, 1, "map points take their latest keyframe observation's descriptor"),
    ST_SETTING(max_keyframes, 2, kMaxKeyframes, "keyframe pool"),
    ST_SETTING(max_map_points, 50, kMaxMapPoints, "map point pool (>= features.n_features)"),
    // Honest state: below any of these the frame is lost.
    ST_SETTING(min_inliers, 6, kMaxKeypoints, "pose inliers"),
    ST_SETTING(min_inlier_ratio, 0, 1, "inliers / matched correspondences"),
    ST_SETTING(max_rms_px, 0.01, 100, "inlier reprojection RMS, octave-whitened level-0 pixels"),
    ST_SETTING(min_mask_agreement, 0, 1, "share of inliers inside the organ rendered at the pose"),
    ST_SETTING(confirmed_min_inlier_ratio, 0, 1,
               "a pose down to this ratio is reported if direct alignment confirms it"),
    ST_SETTING(confirm_agreement_px, 0, 1000, "confirmation: organ motion agreement, level-0 pixels"),
    ST_SETTING(anchor_min_inlier_ratio, 0, 1, "confirmation: the anchor frame's least inlier ratio"),
    ST_SETTING(confirmed_keyframe_min_anchored, 0, 1,
               "a confirmed frame adds a keyframe only with this share of anchored inliers"),
    ST_SETTING(use_contour, 0, 1, "no feature pose: the outline and the shading, if they agree"),
    ST_SETTING(contour_min_lines, 6, RegionModality::kMaxLines, "outline lines needed to measure a pose"),
    ST_SETTING(contour_max_sigma_px, 0, 1000, "the outline alone must fix the organ to this, 1 sigma, level-0 px"),
    ST_SETTING(contour_max_joint_sigma_px, 0, 1000,
               "the outline and the shading together must fix the organ to this, 1 sigma, level-0 px (0: no test)"),
    ST_SETTING(contour_agreement_px, 0, 1000, "outline vs shading: organ agreement, level-0 pixels"),
    ST_SETTING(contour_check_inliers, 0, kMaxKeypoints, "feature poses with fewer inliers are checked by the outline (0: never)"),
    ST_SETTING(contour_veto_px, 0.001, 1000, "such a pose is lost if the outline puts the organ this far away, level-0 px"),
    ST_SETTING(outline_guess, 0, 1, "lost: an outline far from the shading is a guess of its own for the features"),
    ST_SETTING(outline_search, 0, 1, "lost, no outline near the guess: the silhouette searched from every side"),
    ST_SETTING(outline_agreement_inlier_factor, 0.2, 1.0, "min_inliers factor for features within the refine radius of an outline search fit"),
    ST_SETTING(photometric_weight, 0, 1000, "the shading's information in the joint pose, times this"),
    ST_SETTING(max_jump_deg, 0.01, 180, "a pose turned farther from the prediction is lost, degrees"),
    ST_SETTING(max_jump_mm, 0.01, 1000, "a pose moved farther from the prediction is lost, mm"),
    // Keyframes.
    ST_SETTING(keyframe_tracked_ratio, 0, 1, "new keyframe below this share of the reference's tracked points"),
    ST_SETTING(keyframe_angle_deg, 0, 180, "new keyframe after the view turned this far, degrees"),
    ST_SETTING(keyframe_distance_ratio, 0, 10, "new keyframe after travel / median depth exceeds this"),
    ST_SETTING(keyframe_max_motion_px, 0.01, 10000,
               "no keyframe from a frame whose view moved more (blurred), level-0 pixels"),
    // Lost: dead reckoning and relocalisation.
    ST_SETTING(reloc_keyframes_per_frame, 1, kMaxKeyframes, "keyframes matched by brute force a lost frame"),
    ST_SETTING(reloc_min_matches, 4, kMaxKeypoints, "brute-force matches (and RANSAC inliers) to try a keyframe"),
    ST_SETTING(strict_frames, 0, 1000, "frames under the stricter gates after a relocalisation"),
    ST_SETTING(dead_reckoning_frames, 0, 1000, "lost: frames predicted with the last velocity"),
    ST_SETTING(dead_reckoning_decay, 0.01, 1, "lost: the carried velocity shrinks by this a frame"),
    ST_SETTING(use_image_motion, 0, 1, "rotation prior from the whole-image shift; dead reckoning; confirmation"),
    ST_SETTING(strict_inlier_factor, 1, 10, "min_inliers multiplier under the stricter gates"),
    ST_SETTING(min_spread_cells, 0, 16, "stricter gates: inliers occupy this many cells of a 4x4 grid"),
    // Bundle adjustment (the mapping thread; core/mapping/ba_options.h).
    ST_SETTING(use_ba, 0, 1, "window bundle adjustment on the mapping thread (0: none, ablation)"),
    ST_SETTING(ba.w_shape, 0, 1e6, "weight of the point-to-mesh shape residual (paper: 100; 0: none)"),
    ST_SETTING(ba.shape_huber_mm, 0.001, 100, "Huber threshold of the point-to-mesh distance, mm"),
    ST_SETTING(ba.exact_shape, 0, 1, "re-query the closest point at every evaluation (0: tangent plane)"),
    ST_SETTING(ba.reprojection_huber, 0.01, 100, "Huber threshold of the reprojection, whitened pixels"),
    ST_SETTING(ba.max_iterations, 1, 1000, "window solve: iterations"),
    ST_SETTING(ba.relative_gradient_tolerance, 0, 0.999, "stop once the gradient fell to this share"),
    ST_SETTING(ba.max_time_s, 0.001, 10, "window solve: solver time, s"),
    ST_SETTING(ba.min_depth_mm, 0.001, 1000, "observations nearer than this are left out, mm"),
    ST_SETTING(ba.max_point_shift_mm, 0.01, 1000, "a point moved farther is rejected, mm"),
    ST_SETTING(ba.max_observations_per_point, 0, kMaxObservationsPerPointCap,
               "newest observations a point keeps (0: all)"),
    ST_SETTING(ba.min_observations_per_point, 1, 255, "points with fewer usable observations are left out"),
    ST_SETTING(ba.max_fixed_observations_per_point, 0, kMaxObservationsPerPointCap,
               "newest observations from held keyframes a point keeps (0: all)"),
    ST_SETTING(ba.plane_reuse_mm, 0, 10, "a point's tangent plane is reused while it stays this close, mm"),
    ST_SETTING(ba.prior_release_f, 0, 1e6, "F test that frees frame 0 under the registration prior (0: always)"),
    ST_SETTING(ba.surface_distance_samples, 0, kMaxMapPoints,
               "points sampled for the solve's mean surface distance (0: all)"),
    ST_SETTING(ba_window_keyframes, 2, kMaxKeyframes, "newest keyframes a window solve optimises"),
    ST_SETTING(ba_global_after_reloc, 0, 1, "a global solve over every keyframe after a relocalisation"),
    ST_SETTING(ba_global_max_iterations, 1, 1000, "global solve: iterations"),
    ST_SETTING(ba_global_max_time_s, 0.001, 60, "global solve: solver time, s"),
    ST_SETTING(ba_max_observations, 1, 2000000, "observations a job holds (the job buffer)"),
    ST_SETTING(ba_lag_frames, 0, 1000,
               "0: a solve lands when done; N: exactly N frames after its hand-off (deterministic)"),
    // The first frame's registration (0 and 0: taken as exact).
    ST_SETTING(registration_sigma_deg, 0, 90, "prior on frame 0's pose: rotation sigma, degrees (with _mm)"),
    ST_SETTING(registration_sigma_mm, 0, 1000, "prior on frame 0's pose: translation sigma, mm (with _deg)"),
    ST_SETTING(ba_registration_keyframes, 0, 1000, "a global solve every N keyframes while refining (0: none)"),
    // The calibration's focal-length test.
    ST_SETTING(check_calibration, 0, 1, "test the focal length against the mesh after the first window solves"),
    ST_SETTING(calibration_test_jobs, 0, 1000, "window solves followed by a focal test"),
    ST_SETTING(calibration_min_f, 0.001, 1e9, "a vote needs F above this"),
    ST_SETTING(calibration_scale_error, 0.001, 0.999, "... and a focal scale this far from 1"),
    ST_SETTING(calibration_votes, 1, 100, "votes in a row that judge the calibration suspect"),
};

#undef ST_SETTING

const SettingKey* find_key(std::string_view key) {
  for (const SettingKey& k : kKeys)
    if (key == k.key) return &k;
  return nullptr;
}

// Shortest text that reads back to the same value.
template <class T>
std::string number_text(T v) {
  std::array<char, 64> buf{};
  const auto [end, ec] = std::to_chars(buf.data(), buf.data() + buf.size(), v);
  return ec == std::errc() ? std::string(buf.data(), end) : std::string("nan");
}

std::string range_text(const SettingKey& k) {
  if (k.kind == SettingKind::kBool) return "0 or 1";
  if (k.kind == SettingKind::kInt)
    return number_text(static_cast<long long>(k.lo)) + ".." + number_text(static_cast<long long>(k.hi));
  return number_text(k.lo) + ".." + number_text(k.hi);
}

std::string value_text(const SettingKey& k, TrackerConfig& c) {
  void* f = k.field(c);
  switch (k.kind) {
    case SettingKind::kBool: return *static_cast<bool*>(f) ? "1" : "0";
    case SettingKind::kInt: return number_text(*static_cast<int*>(f));
    case SettingKind::kFloat: return number_text(*static_cast<float*>(f));
    case SettingKind::kDouble: return number_text(*static_cast<double*>(f));
  }
  return "";
}

std::string_view trim(std::string_view s) {
  const std::size_t a = s.find_first_not_of(" \t\r");
  if (a == std::string_view::npos) return {};
  const std::size_t b = s.find_last_not_of(" \t\r");
  return s.substr(a, b - a + 1);
}

// The value's text parsed and range-checked into the key's field.
Status set_value(const SettingKey& k, std::string_view text, TrackerConfig* c) {
  const auto refuse = [&] {
    return Status(make_error(std::string(k.key) + ": " + quote_bytes(text) + " is not " +
                             (k.kind == SettingKind::kInt ? "a whole number " : "a number ") + "in " +
                             range_text(k)));
  };
  void* f = k.field(*c);
  switch (k.kind) {
    case SettingKind::kBool: {
      if (text == "1" || text == "true") *static_cast<bool*>(f) = true;
      else if (text == "0" || text == "false") *static_cast<bool*>(f) = false;
      else return make_error(std::string(k.key) + ": " + quote_bytes(text) + " is not 0 or 1");
      return Status::Ok();
    }
    case SettingKind::kInt: {
      long long v = 0;
      if (!parse_int64_in(text, static_cast<long long>(k.lo), static_cast<long long>(k.hi), &v)) return refuse();
      *static_cast<int*>(f) = static_cast<int>(v);
      return Status::Ok();
    }
    case SettingKind::kFloat: {
      std::string_view t = text;
      if (!t.empty() && t.front() == '+') t.remove_prefix(1);
      float v = 0.f;
      const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
      if (t.empty() || ec != std::errc() || end != t.data() + t.size() ||
          !(static_cast<double>(v) >= k.lo && static_cast<double>(v) <= k.hi))
        return refuse();
      *static_cast<float*>(f) = v;
      return Status::Ok();
    }
    case SettingKind::kDouble: {
      double v = 0;
      if (!parse_double_in(text, k.lo, k.hi, &v)) return refuse();
      *static_cast<double*>(f) = v;
      return Status::Ok();
    }
  }
  return refuse();
}

// Words of a printed comment wrapped at about 76 columns.
void append_comment(std::string_view text, std::string* out) {
  std::string line = "#";
  std::size_t pos = 0;
  while (pos < text.size()) {
    std::size_t end = text.find(' ', pos);
    if (end == std::string_view::npos) end = text.size();
    const std::string_view word = text.substr(pos, end - pos);
    if (line.size() > 1 && line.size() + 1 + word.size() > 76) {
      out->append(line).push_back('\n');
      line.resize(1);
    }
    line += ' ';
    line += word;
    pos = end + 1;
  }
  out->append(line).push_back('\n');
}

}  // namespace

std::span<const SettingKey> tracker_setting_keys() { return kKeys; }

Status apply_tracker_setting(std::string_view key, std::string_view value, TrackerConfig* config) {
  const SettingKey* k = find_key(key);
  if (!k) return make_error("unknown setting " + quote_bytes(key) + " (scopetrack --print-config lists them)");
  return set_value(*k, trim(value), config);
}

bool split_setting_assignment(std::string_view text, std::string_view* key, std::string_view* value) {
  const std::size_t eq = text.find('=');
  if (eq == std::string_view::npos || eq == 0) return false;
  *key = text.substr(0, eq);
  *value = text.substr(eq + 1);
  return true;
}

Status read_tracker_settings(std::string_view text, TrackerConfig* config) {
  std::array<bool, kKeys.size()> seen{};
  TrackerConfig read = *config;
  Status status = for_each_data_line(text, [&](std::string_view raw, int number) -> Status {
    const auto at_line = [number](const std::string& m) {
      return Status(make_error("line " + std::to_string(number) + ": " + m));
    };
    for (const char ch : raw)
      if ((static_cast<unsigned char>(ch) < 0x20 && ch != '\t' && ch != '\r') || ch == 0x7f)
        return at_line("control characters (not a text file?)");
    std::string_view line = raw.substr(0, raw.find('#'));
    line = trim(line);
    if (line.empty() || line == "---" || line == "..." || line.substr(0, 5) == "%YAML") return Status::Ok();
    if (raw.front() == ' ' || raw.front() == '\t')
      return at_line("indented: the settings file is a flat map, one 'key: value' a line");
    const std::size_t colon = line.find(':');
    if (colon == std::string_view::npos || colon == 0)
      return at_line("expected 'key: value', found " + quote_bytes(line));
    const std::string_view key = trim(line.substr(0, colon));
    const std::string_view value = trim(line.substr(colon + 1));
    const SettingKey* k = find_key(key);
    if (!k) return at_line("unknown setting " + quote_bytes(key) + " (scopetrack --print-config lists them)");
    const auto index = static_cast<std::size_t>(k - kKeys.data());
    if (seen[index]) return at_line(std::string(k->key) + " is given twice");
    seen[index] = true;
    if (value.empty()) return at_line(std::string(k->key) + " has no value (allowed: " + range_text(*k) + ")");
    if (Status s = set_value(*k, value, &read); !s) return at_line(s.message());
    return Status::Ok();
  });
  if (!status) return status;
  *config = read;
  return Status::Ok();
}

std::string format_tracker_settings(const TrackerConfig& config) {
  TrackerConfig c = config;
  std::string out =
      "%YAML:1.0\n"
      "---\n"
      "# ScopeTrack tracker settings (scopetrack --config FILE). One 'key: value'\n"
      "# a line; a key left out keeps its default. Each key: what it does and\n"
      "# its allowed range. Booleans are 0 or 1. docs/architecture.md explains\n"
      "# the stages; docs/design-notes.md why the defaults are what they are.\n";
  for (const SettingKey& k : kKeys) {
    out += '\n';
    std::string comment = k.help;
    comment.append(" [").append(range_text(k)).push_back(']');
    append_comment(comment, &out);
    out.append(k.key).append(": ").append(value_text(k, c)).push_back('\n');
  }
  return out;
}

}  // namespace st
