// The tracker as the replay's per-frame processor: st::Tracker behind
// hal/replay.h's FrameProcessor, plus the mean stage times for summary.json.
// Threads: configure() on the owner; start/step/stop on the tracking thread
// (step allocates nothing: the tracker's own guarantee, and fixed arrays here).
#pragma once

#include <array>
#include <cstdint>

#include "core/tracker.h"
#include "hal/replay.h"

namespace st::app {

class TrackerProcessor : public FrameProcessor {
 public:
  Status configure(const TrackerConfig& config, const Mesh& mesh, const CameraModel& camera,
                   const SE3& T_camera_model_init);
  void start() override { tracker_.start(); }
  TrackResult step(GrayView luma, int frame_index) override;
  void stop() override { tracker_.stop(); }
  // "stage_<name>_mean_ms" for every stage that ran.
  void append_summary(std::vector<std::pair<std::string, double>>* fields) const override;

 private:
  Tracker tracker_;
  std::array<double, static_cast<int>(Stage::kCount)> stage_sum_ms_{};
  std::array<std::int64_t, static_cast<int>(Stage::kCount)> stage_runs_{};
};

}  // namespace st::app
