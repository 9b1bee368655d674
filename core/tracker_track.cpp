// Frame-to-map tracking: features inside the organ rendered at the
// prediction, search by projection of the local map, robust LM pose twice
// (prediction, then refined pose), quality measures at the final pose and
// the state decision. Tracking thread; allocates nothing.
#include <algorithm>
#include <bit>
#include <cmath>

#include "core/tracker_impl.h"

namespace st {

namespace {

Vec3 camera_centre(const SE3& T_camera_model) { return -(T_camera_model.rotation().transpose() * T_camera_model.translation()); }

// Depth tolerance of "this point is the visible surface": 3% plus 2 mm
// covers raster quantisation and a prediction a few mm off.
bool visible_at_depth(double z_mm, float raster_depth_mm) {
  return raster_depth_mm > 0.f && z_mm <= 1.03 * static_cast<double>(raster_depth_mm) + 2.0;
}

}  // namespace

bool TrackerImpl::extract(GrayView luma, bool with_organ_mask, TrackResult* r) {
  const GrayView organ = with_organ_mask && config_.use_mask && raster_valid_ ? raster_.mask() : GrayView{};
  FeatureSet& f = *features_;
  if (!orb_.extract(luma, organ, valid_view_, f)) f.clear();
  for (int k = 0; k < f.count; ++k) {
    const Keypoint& kp = f.keypoints[static_cast<std::size_t>(k)];
    const Vec2 px(static_cast<double>(kp.x), static_cast<double>(kp.y));
    Vec2& ideal = kp_ideal_[static_cast<std::size_t>(k)];
    // A keypoint whose undistortion does not converge keeps its best
    // estimate; a non-finite one is dropped by the solvers' validity test.
    if (!distorted_ || !camera_.undistort_pixel(px, &ideal)) ideal = distorted_ ? ideal : px;
    kp_inlier_[static_cast<std::size_t>(k)] = 0;
  }
  grid_.build(f);
  r->features = f.count;
  return f.count > 0;
}

// Projects every alive map point at T_camera_model into the local map
// (bounded by the projection buffers): in front, inside the image, within
// the scale range and 60 degrees of the creating view, and (with the raster
// rendered near that pose) not hidden behind the mesh.
int TrackerImpl::select_local_map(const SE3& T_camera_model, bool check_occlusion) {
  const Vec3 centre = camera_centre(T_camera_model);
  const double log_scale = std::log(static_cast<double>(config_.scale_factor));
  const int capacity = static_cast<int>(projected_.size());
  const ImageView<const float> depth = raster_.depth();
  int n = 0;
  for (int id = 0; id < map_.point_high_water() && n < capacity; ++id) {
    const MapPoint& p = map_.point(id);
    if (!p.alive) continue;
    const Vec3 p_camera = T_camera_model * p.p_model;
    if (p_camera.z() < 1.0) continue;
    const Vec3 ray = p.p_model - centre;
    const double dist = ray.norm(), ref = static_cast<double>(p.ref_distance_mm);
    if (dist < 0.4 * ref || dist > 2.5 * ref || ray.dot(p.view_dir_model) < 0.5 * dist) continue;
    const Vec2 ideal = K_.project(p_camera);
    if (!K_.in_image(ideal, 2.0)) continue;
    if (check_occlusion) {
      const Vec2 rp = raster_.full_to_raster(ideal);
      const int x = static_cast<int>(std::lround(rp.x())), y = static_cast<int>(std::lround(rp.y()));
      if (!depth.contains(x, y) || !visible_at_depth(p_camera.z(), depth(x, y))) continue;
    }
    const Vec2 px = distorted_ ? camera_.distort_pixel(ideal) : ideal;
    const int octave = std::clamp(p.ref_octave + static_cast<int>(std::lround(std::log(ref / dist) / log_scale)), 0,
                                  config_.levels - 1);
    ProjectedPoint& q = projected_[static_cast<std::size_t>(n)];
    q.x = static_cast<float>(px.x());
    q.y = static_cast<float>(px.y());
    q.predicted_octave = octave;
    q.ref_angle_deg = p.ref_angle_deg;
    q.descriptor = p.descriptor;
    local_ids_[static_cast<std::size_t>(n++)] = id;
  }
  local_count_ = n;
  return n;
}

// Search by projection with radius_px (scaled by the predicted octave) into
// the correspondence arrays. Returns their count.
int TrackerImpl::match_local_map(float radius_px) {
  for (int i = 0; i < local_count_; ++i) {
    ProjectedPoint& q = projected_[static_cast<std::size_t>(i)];
    q.radius_px = radius_px * octave_scale_[static_cast<std::size_t>(q.predicted_octave)];
  }
  matcher_.search_by_projection(projected_.data(), local_count_, *features_, grid_, match_of_point_.data(),
                                dist_of_point_.data());
  int c = 0;
  for (int i = 0; i < local_count_ && c < kMaxKeypoints; ++i) {
    const int k = match_of_point_[static_cast<std::size_t>(i)];
    if (k < 0) continue;
    const auto cs = static_cast<std::size_t>(c++);
    const int id = local_ids_[static_cast<std::size_t>(i)];
    corr_p_[cs] = map_.point(id).p_model;
    corr_px_[cs] = kp_ideal_[static_cast<std::size_t>(k)];
    corr_info_[cs] = octave_info_[static_cast<std::size_t>(features_->keypoints[static_cast<std::size_t>(k)].octave)];
    corr_point_[cs] = id;
    corr_kp_[cs] = k;
  }
  corr_count_ = c;
  return c;
}

bool TrackerImpl::solve_pose(SE3* T_camera_model, PoseEstimate* e) {
  const Correspondences c{corr_p_.data(), corr_px_.data(), corr_info_.data(), corr_count_};
  PoseSolverSummary s;
  const bool ok = corr_count_ >= 6 && solver_.solve(c, K_, T_camera_model, &s);
  e->matches = corr_count_;
  e->inliers = ok ? s.num_inliers : 0;
  e->rms_px = ok ? s.rms_reprojection_px : 0.0;
  const auto flags = solver_.inliers();
  for (int i = 0; i < corr_count_; ++i)
    corr_inlier_[static_cast<std::size_t>(i)] = ok && i < static_cast<int>(flags.size()) ? flags[static_cast<std::size_t>(i)] : 0;
  return ok && e->inliers > 0;
}

// Pose from the features already extracted, starting at T_predicted (the
// raster must hold a render near it: occlusion test of the local map).
bool TrackerImpl::track_from(const SE3& T_predicted, float first_radius_px, PoseEstimate* e, TrackResult* r) {
  double t = now_ms();
  r->local_map = select_local_map(T_predicted, true);
  if (match_local_map(first_radius_px) < 2 * config_.min_inliers && config_.wide_radius_px > first_radius_px)
    match_local_map(config_.wide_radius_px);
  lap(Stage::kMatch, &t, r);
  SE3 T = T_predicted;
  const bool first = solve_pose(&T, e);
  lap(Stage::kPose, &t, r);
  if (!first) return false;
  select_local_map(T, true);
  match_local_map(config_.refine_radius_px);
  lap(Stage::kMatch, &t, r);
  const bool second = solve_pose(&T, e);
  lap(Stage::kPose, &t, r);
  if (!second) return false;
  e->solved = true;
  e->T_camera_model = T;
  measure_final(e);
  lap(Stage::kRaster, &t, r);
  return true;
}

// Mask agreement (inliers on the organ and not hidden, at the final pose),
// inlier spread over a 4x4 image grid, mean inlier depth; marks the
// keypoints' match status. Re-renders when the final pose moved the image
// by more than ~3 px from the render's pose.
void TrackerImpl::measure_final(PoseEstimate* e) {
  const SE3& T = e->T_camera_model;
  double depth_sum = 0, chi2_sum = 0;
  int depth_n = 0;
  for (int i = 0; i < corr_count_; ++i)
    if (corr_inlier_[static_cast<std::size_t>(i)]) {
      const auto is = static_cast<std::size_t>(i);
      const Vec3 p_camera = T * corr_p_[is];
      depth_sum += p_camera.z();
      chi2_sum += corr_info_[is] * (K_.project(p_camera) - corr_px_[is]).squaredNorm();
      ++depth_n;
    }
  e->mean_depth_mm = depth_n > 0 ? depth_sum / depth_n : 100.0;
  e->whitened_rms = depth_n > 0 ? std::sqrt(chi2_sum / depth_n) : 0.0;
  const PoseDelta d = pose_delta(raster_pose_, T);
  const double shift_px = K_.fx * (d.angle_deg * M_PI / 180.0 +
                                   (camera_centre(raster_pose_) - camera_centre(T)).norm() / e->mean_depth_mm);
  if (!raster_valid_ || shift_px > 3.0) render_at(T);
  const ImageView<const float> depth = raster_.depth();
  std::uint32_t cells = 0;
  int agree = 0;
  for (int i = 0; i < corr_count_; ++i) {
    const auto is = static_cast<std::size_t>(i);
    const int k = corr_kp_[is];
    kp_inlier_[static_cast<std::size_t>(k)] = corr_inlier_[is] ? 2 : 1;
    if (!corr_inlier_[is]) continue;
    const Vec2& px = corr_px_[is];
    const Vec2 rp = raster_.full_to_raster(px);
    const int x = static_cast<int>(std::lround(rp.x())), y = static_cast<int>(std::lround(rp.y()));
    if (depth.contains(x, y) && visible_at_depth((T * corr_p_[is]).z(), depth(x, y))) ++agree;
    const int cx = std::clamp(static_cast<int>(4.0 * px.x() / K_.width), 0, 3);
    const int cy = std::clamp(static_cast<int>(4.0 * px.y() / K_.height), 0, 3);
    cells |= 1u << (cy * 4 + cx);
  }
  e->mask_agreement = e->inliers > 0 ? static_cast<double>(agree) / e->inliers : 0.0;
  e->spread_cells = std::popcount(cells);
}

QualityGates TrackerImpl::gates(bool strict) const {
  QualityGates g;
  g.min_inliers = config_.min_inliers;
  g.min_inlier_ratio = config_.min_inlier_ratio;
  g.max_rms_px = config_.max_rms_px;
  g.min_mask_agreement = config_.min_mask_agreement;
  if (strict) {
    g.min_inliers = static_cast<int>(std::ceil(config_.min_inliers * config_.strict_inlier_factor));
    g.max_rms_px = 0.8 * config_.max_rms_px;
    g.min_mask_agreement = std::max(config_.min_mask_agreement, 0.95);
    g.min_spread_cells = config_.min_spread_cells;
  }
  return g;
}

bool TrackerImpl::passes(const PoseEstimate& e, const QualityGates& g) const {
  const double ratio = e.matches > 0 ? static_cast<double>(e.inliers) / e.matches : 0.0;
  return e.solved && e.T_camera_model.all_finite() && e.inliers >= g.min_inliers &&
         ratio >= g.min_inlier_ratio && e.whitened_rms <= g.max_rms_px &&
         e.mask_agreement >= g.min_mask_agreement && e.spread_cells >= g.min_spread_cells;
}

TrackResult TrackerImpl::track(GrayView luma, int frame_index) {
  TrackResult r;
  double t = now_ms();
  const SE3 T_predicted = velocity_ * T_last_;
  render_at(T_predicted);
  lap(Stage::kRaster, &t, &r);
  extract(luma, true, &r);
  lap(Stage::kDetect, &t, &r);
  PoseEstimate e;
  bool ok = track_from(T_predicted, config_.search_radius_px, &e, &r);
  if (ok) {
    r.pose_jump_deg = pose_delta(T_predicted, e.T_camera_model).angle_deg;
    r.pose_jump_mm = (camera_centre(T_predicted) - camera_centre(e.T_camera_model)).norm();
    ok = passes(e, gates(strict_frames_left_ > 0)) && r.pose_jump_deg <= config_.max_jump_deg &&
         r.pose_jump_mm <= config_.max_jump_mm;
  }
  fill_measures(e, &r);
  if (ok) {
    accept(e, frame_index, TrackState::kTracking, &r);
  } else {
    r.state = TrackState::kLost;
    lost_ = true;
    lost_frames_ = 1;
    velocity_ = SE3();
  }
  return r;
}

void TrackerImpl::fill_measures(const PoseEstimate& e, TrackResult* r) const {
  r->matches = e.matches;
  r->inliers = e.inliers;
  r->inlier_ratio = e.matches > 0 ? static_cast<double>(e.inliers) / e.matches : 0.0;
  r->rms_px = e.rms_px;
  r->whitened_rms_px = e.whitened_rms;
  r->mask_agreement = e.mask_agreement;
}

// The frame passed its gates: report the pose, update velocity, counters and
// (when useful and not under strict gates) insert a keyframe.
void TrackerImpl::accept(const PoseEstimate& e, int frame_index, TrackState state, TrackResult* r) {
  double t = now_ms();
  r->state = state;
  r->pose_valid = true;
  r->T_camera_model = e.T_camera_model;
  velocity_ = state == TrackState::kTracking ? e.T_camera_model * T_last_.inverse() : SE3();
  T_last_ = e.T_camera_model;
  lost_ = false;
  lost_frames_ = 0;
  update_counters(frame_index);
  if (strict_frames_left_ > 0) {
    --strict_frames_left_;
  } else if (need_keyframe(e)) {
    r->keyframe = add_keyframe(e.T_camera_model, frame_index, true) >= 0;
  }
  lap(Stage::kMap, &t, r);
}

}  // namespace st
