// The tracker as the replay's per-frame processor: st::Tracker behind
// firmware_app/replay.h's FrameProcessor, with its mapping thread (bundle
// adjustment, firmware_app/mapping_worker.h) when TrackerConfig::use_ba,
// plus the mean stage times and BA counts for summary.json.
// Threads: configure() on the owner; start/step/stop on the tracking thread
// (step allocates nothing: the tracker's own guarantee, and fixed arrays
// here); the mapping thread lives between start() and stop().
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "core/tracking/tracker.h"
#include "firmware_app/mapping_worker.h"
#include "firmware_app/replay.h"

namespace st::app {

class TrackerProcessor : public FrameProcessor {
 public:
  Status configure(const TrackerConfig& config, const Mesh& mesh, const CameraModel& camera,
                   const SE3& T_camera_model_init);
  void start() override;
  TrackResult step(const FrameRef& frame) override;
  void stop() override;
  // "stage_<name>_mean_ms" for every stage that ran, the occluder mask's
  // frames and mean share of the valid mask, the dim frames (FAST
  // thresholds scaled down) and their smallest scale, and the BA figures.
  void append_summary(std::vector<std::pair<std::string, double>>* fields) const override;
  // The tracker's calibration test (TrackerConfig::check_calibration).
  CalibrationCheck calibration_check() const { return tracker_.calibration_check(); }
  // The size the tracker works at (TrackerConfig::working_width).
  Pinhole working_pinhole() const { return tracker_.working_camera().pinhole(); }
  CameraModel working_camera() const { return tracker_.working_camera(); }

 private:
  Tracker tracker_;
  MappingWorker mapping_;
  bool use_ba_ = false;
  std::array<double, static_cast<int>(Stage::kCount)> stage_sum_ms_{};
  std::array<std::int64_t, static_cast<int>(Stage::kCount)> stage_runs_{};
  std::int64_t ba_submitted_ = 0, ba_applied_ = 0;
  std::int64_t occluder_frames_ = 0, occluder_pixels_ = 0, occluder_refused_ = 0;  // frames with an occluder mask, valid pixels removed
  std::int64_t dim_frames_ = 0;    // frames whose FAST thresholds were scaled down (fast_reference_luma or _contrast)
  std::int64_t low_contrast_frames_ = 0;  // of those, scaled for a flat texture (TrackerConfig::fast_reference_contrast)
  double noise_ratio_ = -1;  // at the last initialisation (TrackerConfig::denoise_noise_ratio); -1: not measured
  bool denoise_ = false;     // its decision: the keypoints come from the filtered frame
  int mesh_triangles_ = 0;                // the mesh as given (the tracker may render a simplified copy)
  double min_fast_scale_ = 1.0;    // the smallest scale
};

// The warning for a calibration judged suspect (CalibrationCheck): from
// which frame, the focal scale the video fits, what it means and what to
// check; empty when not suspect. calibration_file names the calibration's
// source.
std::string describe_calibration(const CalibrationCheck& c, const std::string& calibration_file);

}  // namespace st::app
