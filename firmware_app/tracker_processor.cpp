#include "firmware_app/tracker_processor.h"

#include <algorithm>
#include <cstdio>

namespace st::app {

Status TrackerProcessor::configure(const TrackerConfig& config, const Mesh& mesh, const CameraModel& camera,
                                   const SE3& T_camera_model_init) {
  stage_sum_ms_.fill(0.0);
  stage_runs_.fill(0);
  ba_submitted_ = ba_applied_ = 0;
  occluder_frames_ = occluder_pixels_ = occluder_refused_ = 0;
  dim_frames_ = low_contrast_frames_ = 0;
  noise_ratio_ = -1;
  denoise_ = false;
  min_fast_scale_ = 1.0;
  use_ba_ = false;
  mesh_triangles_ = mesh.triangle_count();
  if (Status s = tracker_.configure(config, mesh, camera, T_camera_model_init); !s.ok()) return s;
  if (config.use_ba) {
    if (Status s = mapping_.configure(config, mesh, tracker_.working_camera().pinhole()); !s.ok()) return s;
    tracker_.set_ba_channel(&mapping_);
    use_ba_ = true;
  }
  return Status::Ok();
}

void TrackerProcessor::start() {
  if (use_ba_) mapping_.start();
  tracker_.start();
}

void TrackerProcessor::stop() {
  tracker_.stop();
  if (use_ba_) mapping_.stop();
}

TrackResult TrackerProcessor::step(const FrameRef& frame) {
  // The capture's working-size copy when it made one (the tracker takes a
  // frame of either size).
  const TrackResult r = frame.y_work.empty() ? tracker_.step(frame.y, frame.index, ChromaView{frame.u, frame.v})
                                             : tracker_.step(frame.y_work, frame.index, ChromaView{frame.u_work, frame.v_work});
  for (std::size_t i = 0; i < stage_sum_ms_.size(); ++i) {
    if (r.times_ms[i] <= 0.0) continue;  // the stage did not run
    stage_sum_ms_[i] += r.times_ms[i];
    ++stage_runs_[i];
  }
  ba_submitted_ += r.ba_submitted ? 1 : 0;
  ba_applied_ += r.ba_applied ? 1 : 0;
  if (r.occluder_pixels >= 0) {
    ++occluder_frames_;
    occluder_pixels_ += r.occluder_pixels;
  }
  occluder_refused_ += r.occluder_refused ? 1 : 0;
  if (r.fast_threshold_scale < 1.f) {
    ++dim_frames_;
    min_fast_scale_ = std::min(min_fast_scale_, static_cast<double>(r.fast_threshold_scale));
  }
  low_contrast_frames_ += r.low_contrast ? 1 : 0;
  if (r.state == TrackState::kInitialised) {  // the filter is decided there, for the run
    noise_ratio_ = r.noise_ratio;
    denoise_ = r.denoise;
  }
  return r;
}

void TrackerProcessor::append_summary(std::vector<std::pair<std::string, double>>* fields) const {
  for (std::size_t i = 0; i < stage_sum_ms_.size(); ++i) {
    if (stage_runs_[i] == 0) continue;
    const std::string name = to_string(static_cast<Stage>(i));
    fields->emplace_back("stage_" + name + "_mean_ms", stage_sum_ms_[i] / static_cast<double>(stage_runs_[i]));
  }
  const Pinhole working = working_pinhole();
  fields->emplace_back("working_width", working.width);
  fields->emplace_back("working_height", working.height);
  fields->emplace_back("mesh_triangles", static_cast<double>(mesh_triangles_));
  fields->emplace_back("raster_triangles", static_cast<double>(tracker_.raster_triangles()));
  fields->emplace_back("occluder_mask_frames", static_cast<double>(occluder_frames_));
  fields->emplace_back("occluder_refused_frames", static_cast<double>(occluder_refused_));
  if (occluder_frames_ > 0)
    fields->emplace_back("occluder_removed_px_mean", static_cast<double>(occluder_pixels_) / static_cast<double>(occluder_frames_));
  fields->emplace_back("dim_frames", static_cast<double>(dim_frames_));
  fields->emplace_back("min_fast_threshold_scale", min_fast_scale_);
  fields->emplace_back("low_contrast_frames", static_cast<double>(low_contrast_frames_));
  fields->emplace_back("noise_ratio", noise_ratio_);
  fields->emplace_back("features_denoise", denoise_ ? 1.0 : 0.0);
  const CalibrationCheck cal = tracker_.calibration_check();
  fields->emplace_back("calibration_tests", cal.tests);
  fields->emplace_back("calibration_max_f", cal.max_f);
  fields->emplace_back("calibration_focal_scale", cal.focal_scale);
  fields->emplace_back("calibration_focal_f", cal.focal_f);
  fields->emplace_back("calibration_suspect", cal.suspect ? 1.0 : 0.0);
  fields->emplace_back("calibration_suspect_frame", cal.suspect_frame);
  if (!use_ba_) return;
  fields->emplace_back("ba_jobs_submitted", static_cast<double>(ba_submitted_));
  fields->emplace_back("ba_jobs_applied", static_cast<double>(ba_applied_));
  mapping_.append_summary(fields);
}

std::string describe_calibration(const CalibrationCheck& c, const std::string& calibration_file) {
  if (!c.suspect) return {};
  char buf[640];
  std::snprintf(buf, sizeof buf,
                "calibration suspect from frame %d: the video fits focal lengths %.3f x those of %s (F = %.0f;"
                " docs/design-notes.md, \"The focal-length test\"). Either the calibration is off (another scope's, or another"
                " zoom's?) or the organ differs from its prior in shape; either way the poses may be off by"
                " degrees and mm. Tracking went on. Check camera_matrix.",
                c.suspect_frame, c.focal_scale, calibration_file.c_str(), c.focal_f);
  return buf;
}

}  // namespace st::app
