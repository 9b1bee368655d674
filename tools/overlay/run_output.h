// The tracker's output folder read back for display: per frame, the pose
// (trajectory.txt) and the state (frames.csv). Host tool code: allocates.
#pragma once

#include <filesystem>
#include <optional>
#include <string_view>
#include <vector>

#include "core/base/result.h"
#include "core/geometry/se3.h"
#include "core/formats/trajectory.h"

namespace st::overlay {

struct RunFrames {
  std::vector<std::optional<SE3>> T_model_camera;  // by frame index; nullopt: no pose
  std::vector<std::optional<FrameState>> state;    // by frame index; nullopt: no row
  const SE3* pose(int frame) const;                // nullptr when none
  std::optional<FrameState> state_of(int frame) const;
};

// Poses by frame index from TUM poses (timestamp i / fps, a quarter frame of
// tolerance). Poses that match no frame are an error (a wrong fps).
Result<std::vector<std::optional<SE3>>> poses_by_frame(const std::vector<TimedPose>& poses, double fps);

// frames.csv text: header, then "frame,timestamp,state,inliers,latency_ms".
Result<std::vector<std::optional<FrameState>>> parse_frame_states(std::string_view csv);

// trajectory.txt (required) and frames.csv (optional) of a run folder.
Result<RunFrames> read_run_output(const std::filesystem::path& out_dir, double fps);

}  // namespace st::overlay
