#include "core/tracking/pose_gates.h"

#include <algorithm>
#include <cmath>

namespace st {

void PoseGates::configure(const TrackerConfig& c) {
  normal_.min_inliers = c.min_inliers;
  normal_.min_inlier_ratio = c.min_inlier_ratio;
  normal_.max_rms_px = c.max_rms_px;
  normal_.min_mask_agreement = c.min_mask_agreement;
  normal_.min_spread_cells = 0;
  strict_inlier_factor_ = c.strict_inlier_factor;
  strict_min_spread_cells_ = c.min_spread_cells;
  confirmed_min_inlier_ratio_ = c.confirmed_min_inlier_ratio;
}

QualityGates PoseGates::normal() const { return normal_; }

QualityGates PoseGates::strict() const {
  QualityGates g = normal_;
  g.min_inliers = static_cast<int>(std::ceil(normal_.min_inliers * strict_inlier_factor_));
  g.max_rms_px = 0.8 * normal_.max_rms_px;
  g.min_mask_agreement = std::max(normal_.min_mask_agreement, 0.95);
  g.min_spread_cells = strict_min_spread_cells_;
  return g;
}

QualityGates PoseGates::confirm() const {
  QualityGates g = normal_;
  g.min_inlier_ratio = std::min(g.min_inlier_ratio, confirmed_min_inlier_ratio_);
  return g;
}

bool PoseGates::passes(const PoseEstimate& e, const QualityGates& g) {
  return e.solved && e.T_camera_model.all_finite() && e.inliers >= g.min_inliers &&
         e.inlier_ratio() >= g.min_inlier_ratio && e.whitened_rms <= g.max_rms_px &&
         e.mask_agreement >= g.min_mask_agreement && e.spread_cells >= g.min_spread_cells;
}

}  // namespace st
