// Trajectory evaluation against ground truth: the figures scopetrack-eval
// reports and the tracker's acceptance criteria are computed here,
// as pure functions over poses, markers and the camera model.
//
// Definitions (applied to every frame index 0..frames-1):
// - a frame is *reported* when the tracker output has a pose for it;
// - lost_pct = 100 * (frames - reported) / frames;
// - init_ok: a pose is reported within the first kInitWindow frames;
// - TRE: for a reported frame with ground truth, each marker whose true
//   projection (with distortion) lies inside the image and in front of the
//   camera contributes |project(T_est, m) - project(T_gt, m)| in pixels;
//   median/mean/p95 are over all such marker contributions;
// - wrong: a reported frame whose median marker TRE exceeds kWrongTrePx
//   (confident but wrong); wrong_pct is over all frames;
// - rotation/translation errors: median over reported frames with ground
//   truth of the angle (deg) and distance (mm) between T_est and T_gt.
#pragma once

#include <optional>
#include <vector>

#include "core/geometry/camera.h"
#include "core/geometry/se3.h"

namespace st {

inline constexpr int kInitWindow = 5;
inline constexpr double kWrongTrePx = 50.0;
// TRE of a marker the estimate puts behind the camera (and the cap of any
// marker error), so that means stay finite and JSON-printable.
inline constexpr double kBehindCameraTrePx = 1e6;

struct EvalInput {
  int frames = 0;
  CameraModel camera;
  // Indexed by frame; std::nullopt where there is no pose. Both hold
  // T_model_camera (the TUM convention).
  std::vector<std::optional<SE3>> estimated;
  std::vector<std::optional<SE3>> groundtruth;
  std::vector<Vec3> markers_model;
};

struct EvalResult {
  int frames = 0;
  int reported_frames = 0;
  bool init_ok = false;
  double lost_pct = 0;
  int tre_samples = 0;       // marker contributions
  int tre_frames = 0;        // reported frames with at least one marker in view
  double tre_median_px = 0, tre_mean_px = 0, tre_p95_px = 0, tre_max_px = 0;
  int wrong_frames = 0;
  double wrong_pct = 0;
  int pose_frames = 0;       // reported frames with ground truth
  double rot_err_median_deg = 0, trans_err_median_mm = 0;
  double rot_err_max_deg = 0;  // the largest rotation error of a reported pose
};

EvalResult evaluate(const EvalInput& in);

// Projection of a model-frame marker through T_model_camera with distortion;
// false when it is behind the camera or outside the image.
bool project_marker(const CameraModel& cam, const SE3& T_model_camera, const Vec3& p_model,
                    Vec2* px);

// Index of the frame whose timestamp i / fps is nearest to t_s, or -1 when no
// frame lies within a quarter of a frame period (or outside [0, frames)).
int frame_for_timestamp(double t_s, double fps, int frames);

}  // namespace st
