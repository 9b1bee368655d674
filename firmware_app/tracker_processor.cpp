#include "firmware_app/tracker_processor.h"

namespace st::app {

Status TrackerProcessor::configure(const TrackerConfig& config, const Mesh& mesh,
                                   const CameraModel& camera, const SE3& T_camera_model_init) {
  stage_sum_ms_.fill(0.0);
  stage_runs_.fill(0);
  return tracker_.configure(config, mesh, camera, T_camera_model_init);
}

TrackResult TrackerProcessor::step(GrayView luma, int frame_index) {
  const TrackResult r = tracker_.step(luma, frame_index);
  for (std::size_t i = 0; i < stage_sum_ms_.size(); ++i) {
    if (r.times_ms[i] <= 0.0) continue;  // the stage did not run
    stage_sum_ms_[i] += r.times_ms[i];
    ++stage_runs_[i];
  }
  return r;
}

void TrackerProcessor::append_summary(std::vector<std::pair<std::string, double>>* fields) const {
  for (std::size_t i = 0; i < stage_sum_ms_.size(); ++i) {
    if (stage_runs_[i] == 0) continue;
    const std::string name = to_string(static_cast<Stage>(i));
    fields->emplace_back("stage_" + name + "_mean_ms", stage_sum_ms_[i] / static_cast<double>(stage_runs_[i]));
  }
}

}  // namespace st::app
