// The quality gates of the tracker: a frame's pose is reported only when it
// passes every one (inliers, inlier ratio, whitened reprojection RMS, share
// of inliers on the rendered organ, spread over the image). Three sets:
// normal; strict, for the frames after a relocalisation; and confirm, the
// normal gates with the inlier ratio relaxed, for a pose that direct
// alignment against the anchor frame must then confirm (tracker.h,
// TrackerConfig::confirmed_min_inlier_ratio). Pure; no allocation.
#pragma once

#include "core/geometry/se3.h"
#include "core/tracking/tracker.h"

namespace st {

struct QualityGates {
  int min_inliers = 0;
  double min_inlier_ratio = 0;
  double max_rms_px = 0;          // whitened (octave-normalised) inlier RMS, level-0 pixels
  double min_mask_agreement = 0;
  int min_spread_cells = 0;       // of a 4x4 image grid
};

// One pose estimate from correspondences and its measures, before the
// state decision.
struct PoseEstimate {
  bool solved = false;
  SE3 T_camera_model;
  int matches = 0, inliers = 0;
  double rms_px = 0, mask_agreement = 0;
  double whitened_rms = 0;  // sqrt(mean(info * |r|^2)) over the inliers: level-0 pixels
  int spread_cells = 0;
  double mean_depth_mm = 100.0;  // of the inliers at the final pose
  double inlier_ratio() const { return matches > 0 ? static_cast<double>(inliers) / matches : 0.0; }
};

class PoseGates {
 public:
  // Takes the gates' settings (min_inliers, min_inlier_ratio, max_rms_px,
  // min_mask_agreement, strict_inlier_factor, min_spread_cells,
  // confirmed_min_inlier_ratio).
  void configure(const TrackerConfig& config);
  QualityGates normal() const;
  // After a relocalisation: more inliers (strict_inlier_factor), 0.8 x the
  // RMS, mask agreement at least 0.95, and spread (min_spread_cells).
  QualityGates strict() const;
  // The normal gates with the inlier ratio lowered to
  // confirmed_min_inlier_ratio.
  QualityGates confirm() const;
  // A solved, finite pose that meets every gate.
  static bool passes(const PoseEstimate& e, const QualityGates& g);

 private:
  QualityGates normal_;
  double strict_inlier_factor_ = 1.5;
  int strict_min_spread_cells_ = 0;
  double confirmed_min_inlier_ratio_ = 0;
};

}  // namespace st
