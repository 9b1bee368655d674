// Frame-to-map tracking: features inside the organ rendered at the
// prediction, search by projection of the local map, robust LM pose twice
// (prediction, then refined pose), quality measures at the final pose and
// the state decision. Tracking thread; allocates nothing.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>

#include <Eigen/Eigenvalues>

#include "core/tracking/tracker_impl.h"

namespace st {

namespace {

Vec3 camera_centre(const SE3& T_camera_model) { return -(T_camera_model.rotation().transpose() * T_camera_model.translation()); }

// How far (level-0 px) the final pose may move the view from the render's
// pose before the quality measures need a new render.
constexpr double kReuseRenderPx = 8.0;

// Dead reckoning also aligns from the constant-velocity prediction when the
// image-motion prior moved the prediction by more than this (level-0 px):
// motion_prior() leaves a prediction alone below 4 px.
constexpr double kAlternativeStartPx = 4.0;

}  // namespace

bool TrackerImpl::extract(GrayView luma, bool with_organ_mask, TrackResult* r) {
  const GrayView organ = with_organ_mask && config_.use_mask && raster_valid_ ? raster_.mask() : GrayView{};
  FeatureSet& f = *features_;
  const FastThresholdScale scale = fast_scaler_.measure(luma, organ, valid_view_, valid_mask_);
  if (scale.low_contrast) r->low_contrast = true;
  orb_.set_threshold_scale(scale.scale);
  r->fast_threshold_scale = orb_.threshold_scale();
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

// Search by projection of the local map (LocalMapSearch) with radius_px,
// into the correspondence arrays. Returns their count.
int TrackerImpl::match_local_map(float radius_px) {
  local_map_.search(radius_px, *features_, grid_, &matcher_);
  int c = 0;
  for (int i = 0; i < local_map_.size() && c < kMaxKeypoints; ++i) {
    const int k = local_map_.match(i);
    if (k < 0) continue;
    const auto cs = static_cast<std::size_t>(c++);
    const int id = local_map_.point_id(i);
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

// Dead reckoning while lost: the camera's motion since the reference frame
// (the last tracked frame, then each dead-reckoned one) from an ORB pyramid
// level of both and the mesh rendered at the reference pose (DirectAligner).
// *T: in, the prediction; out, the estimate if the alignment held (at a
// coarser level if the finest one's failed: DirectAligner::align's
// allow_coarser). The current frame then becomes the next reference, at
// the estimate; if it failed (the organ left the view, say) the chain ends
// and the caller's prediction carries on. Renders at the reference pose.
//
// T_alternative: the same prediction without the whole-image motion
// (constant velocity). Where the two differ by more than
// kAlternativeStartPx, the alignment also starts from it and the estimate
// from the finer level, then the one that explains the image better
// (smaller median residual), is kept. In a
// fast swing the image-motion prior can be the worse start (a swing along
// the organ, with parallax between it and the background): on the
// simulated stomach (fast seed 2, 640x360) it put the prediction 28 px off
// where constant velocity was 3 px off, and the alignment from there
// settled 22 px off (a wrong basin; its contrast gain of 0.04 now has
// align() refuse it as well). From both starts the guess stayed within
// 1.5-3.7 px for the next 35 frames.
bool TrackerImpl::dead_reckon(SE3* T_camera_model, const SE3& T_alternative, DirectAlignSummary* fit_out) {
  if (!config_.use_image_motion || !aligner_.has_reference()) return false;
  const GrayView image = orb_.pyramid().level(align_level_);  // this frame's: extract() ran
  render_at(aligner_.reference_pose());
  SE3 T = *T_camera_model;
  DirectAlignSummary fit;
  bool ok = aligner_.align(image, valid_view_, raster_, camera_, &T, &fit, true);
  if (image_shift_px(*T_camera_model, T_alternative) > kAlternativeStartPx) {
    SE3 T_alt = T_alternative;
    DirectAlignSummary fit_alt;
    // Residuals compare within a level; an estimate from a finer level wins.
    if (aligner_.align(image, valid_view_, raster_, camera_, &T_alt, &fit_alt, true) &&
        (!ok || fit_alt.level < fit.level ||
         (fit_alt.level == fit.level && fit_alt.residual_median < fit.residual_median))) {
      T = T_alt;
      fit = fit_alt;
      ok = true;
    }
  }
  if (!ok) {
    aligner_.forget_reference();
    return false;
  }
  if (fit_out) *fit_out = fit;
  *T_camera_model = T;
  aligner_.keep_reference(image, valid_view_, T);
  return true;
}

// A pose that only the relaxed gates pass needs a second, independent
// measurement: this frame aligned directly (DirectAligner) against the
// anchor, the last frame whose pose passed the normal gates with margin
// (anchor_min_inlier_ratio), starting from T_guess. Measured against the
// anchor, not chained frame to frame, so a slow drift of the feature poses
// cannot hide in small steps. Returns how far apart (level-0 px over the
// organ) the aligned pose and T_features put the organ, or kUnknownMotion
// if there is no anchor or the alignment fails.
double TrackerImpl::anchor_agreement_px(const SE3& T_guess, const SE3& T_features) {
  if (!config_.use_image_motion || !anchor_.has_reference()) return kUnknownMotion;
  render_at(anchor_.reference_pose());
  SE3 T = T_guess;
  if (!anchor_.align(orb_.pyramid().level(align_level_), valid_view_, raster_, camera_, &T)) return kUnknownMotion;
  return view_difference_px(T, T_features);
}

namespace {

// Calls visit(p) for the organ's model points p on a 16 x 9 grid of a
// render made at raster_pose: where the pose comparisons below measure.
template <class Visit>
void for_each_organ_grid_point(const MeshRasterizer& raster, const SE3& raster_pose, Visit&& visit) {
  const ImageView<const float> depth = raster.depth();
  const Pinhole& Kr = raster.camera();
  const SE3 model_from_raster = raster_pose.inverse();
  for (int gy = 0; gy < 9; ++gy)
    for (int gx = 0; gx < 16; ++gx) {
      const int x = (2 * gx + 1) * depth.width / 32, y = (2 * gy + 1) * depth.height / 18;
      const float d = depth(x, y);
      if (d > 0.f) visit(Vec3(model_from_raster * Kr.unproject(Vec2(x, y), d)));
    }
}

}  // namespace

// How far apart two poses put the organ in view (level-0 pixels): organ
// points on a 16 x 9 grid of the current render (raster_, at whatever pose
// it was made), projected at a and at b; the mean distance
// (kUnknownMotion if no grid point is on the organ). Unlike
// image_shift_px it does not count a turn that a sideways move undoes in
// the image, and it covers the whole organ in view, not only where a
// handful of features sit.
double TrackerImpl::view_difference_px(const SE3& a, const SE3& b) const {
  if (!raster_valid_) return kUnknownMotion;
  double sum = 0;
  int n = 0;
  for_each_organ_grid_point(raster_, raster_pose_, [&](const Vec3& p) {
    const Vec3 pa = a * p, pb = b * p;
    if (!(pa.z() > 1.0) || !(pb.z() > 1.0)) return;
    sum += (K_.project(pa) - K_.project(pb)).norm();
    ++n;
  });
  return n > 0 ? sum / n : kUnknownMotion;
}

// How far (level-0 px, RMS over the organ) the organ in view moves for a
// pose error of covariance cov (the left-perturbation tangent) at pose T:
// organ points on the 16 x 9 grid of the current render (raster_), their
// projection's Jacobian J, sqrt(mean trace(J cov J^T)). kUnknownMotion if
// no grid point is on the organ.
double TrackerImpl::view_sigma_px(const Mat6& cov, const SE3& T) const {
  if (!raster_valid_) return kUnknownMotion;
  double sum = 0;
  int n = 0;
  for_each_organ_grid_point(raster_, raster_pose_, [&](const Vec3& p) {
    const Vec3 pc = T * p;
    if (!(pc.z() > 1.0)) return;
    const double iz = 1.0 / pc.z();
    Eigen::Matrix<double, 2, 3> P;
    P << K_.fx * iz, 0, -K_.fx * pc.x() * iz * iz, 0, K_.fy * iz, -K_.fy * pc.y() * iz * iz;
    Eigen::Matrix<double, 3, 6> D;
    D.leftCols<3>() = -hat(pc);
    D.rightCols<3>() = Mat3::Identity();
    const Eigen::Matrix<double, 2, 6> J = P * D;
    sum += (J * cov * J.transpose()).trace();
    ++n;
  });
  return n > 0 ? std::sqrt(sum / n) : kUnknownMotion;
}

// Image motion (level-0 pixels) between two poses for the scene at the last
// tracked depth: rotation plus parallax of the camera centre.
double TrackerImpl::image_shift_px(const SE3& a, const SE3& b) const {
  const PoseDelta d = pose_delta(a, b);
  return K_.fx * (d.angle_deg * M_PI / 180.0 + (camera_centre(a) - camera_centre(b)).norm() / last_depth_mm_);
}

// The constant-velocity prediction T_predicted (from T_reference, the last
// pose), turned about the camera centre so that the view moves as the
// measured whole-image motion (shift of the view centre and roll) says.
// Under a sudden turn (with motion blur) the constant-velocity guess is
// tens of pixels off; the motion of small blurred images is not.
// Corrections that move no image point by 4 px or more are left alone:
// there the constant-velocity prediction is as good.
SE3 TrackerImpl::motion_prior(GrayView luma, const SE3& T_reference, const SE3& T_predicted) {
  const Vec2 centre(K_.cx, K_.cy);
  const Vec3 p_model = T_reference.inverse() * K_.unproject(centre, last_depth_mm_);
  const Vec3 p_camera = T_predicted * p_model;
  ViewMotion guess;
  guess.shift_px = p_camera.z() > 1.0 ? Vec2(K_.project(p_camera) - centre) : Vec2(Vec2::Zero());
  // The predicted roll: the turn of the image plane's axes (camera x, y)
  // from the reference to the prediction, about the optical axis.
  const Mat3 R = T_predicted.rotation() * T_reference.rotation().transpose();
  guess.roll_rad = std::atan2(R(1, 0) - R(0, 1), R(0, 0) + R(1, 1));
  ViewMotion measured;
  // The whole view, neutral surfaces included: the occluder mask serves the
  // organ's features and alignment, and taking grey background (abdominal
  // wall, a pale neighbour organ) out of this prior only changed its
  // answers (photo-textured invivo seed 2: 0.7 -> 44.7 % lost).
  if (!config_.use_image_motion || !motion_.update(luma, valid_scene_, centre, guess, &measured)) return T_predicted;
  const Vec2 residual = measured.shift_px - guess.shift_px;
  const double residual_roll = measured.roll_rad - guess.roll_rad;
  const double reach = std::hypot(std::max(K_.cx, K_.width - K_.cx), std::max(K_.cy, K_.height - K_.cy));
  if (residual.norm() + std::abs(residual_roll) * reach < 4.0) return T_predicted;
  const Vec3 omega(-residual.y() / K_.fy, residual.x() / K_.fx, residual_roll);
  return SE3(so3_exp(omega), Vec3::Zero()) * T_predicted;
}

// The first pass explains few of its matches, or far fewer points than the
// last frame: the motion changed faster than the constant-velocity
// prediction allows (a sudden turn), so the search must go wider.
bool TrackerImpl::weak_first_pass(bool solved, const PoseEstimate& e) const {
  if (!solved) return true;
  return e.inlier_ratio() < 0.75 || 2 * e.inliers < last_inliers_;
}

// Pose from the features already extracted, starting at T_predicted (the
// raster must hold a render near it: occlusion test of the local map).
// The local map is selected once; a weak first pass is repeated with the
// wide radius; the refine pass re-projects the same points at the solved
// pose with a radius that covers how far the solve moved the view.
bool TrackerImpl::track_from(const SE3& T_predicted, float first_radius_px, PoseEstimate* e, TrackResult* r) {
  double t = now_ms();
  r->local_map = local_map_.select(map_, T_predicted, &raster_);
  float radius = first_radius_px;
  if (match_local_map(radius) < 2 * config_.min_inliers && config_.wide_radius_px > radius)
    match_local_map(radius = config_.wide_radius_px);
  lap(Stage::kMatch, &t, r);
  SE3 T = T_predicted;
  bool solved = solve_pose(&T, e);
  lap(Stage::kPose, &t, r);
  if (weak_first_pass(solved, *e) && config_.wide_radius_px > radius) {
    match_local_map(config_.wide_radius_px);
    lap(Stage::kMatch, &t, r);
    SE3 T_wide = T_predicted;
    PoseEstimate wide;
    if (solve_pose(&T_wide, &wide) && (!solved || wide.inliers > e->inliers)) {
      T = T_wide;
      *e = wide;
      solved = true;
    }
    lap(Stage::kPose, &t, r);
  }
  if (!solved) return false;
  const double moved_px = image_shift_px(T_predicted, T);
  if (moved_px > static_cast<double>(config_.wide_radius_px)) {
    local_map_.select(map_, T, &raster_);  // the view moved far: the predicted selection no longer fits
  } else {
    local_map_.reproject(map_, T);
  }
  match_local_map(moved_px > static_cast<double>(config_.refine_radius_px) ? config_.search_radius_px
                                                                          : config_.refine_radius_px);
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

// Mask agreement (inliers on the organ and not hidden), inlier spread over
// a 4x4 image grid, mean inlier depth; marks the keypoints' match status.
// Each inlier's model point is looked up in the render at its own pixel
// there, so the render of the prediction serves while the final pose moved
// the image by at most kReuseRenderPx (occlusion barely changes over a few
// pixels); beyond, the organ is rendered again at the final pose.
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
  if (!raster_valid_ || image_shift_px(raster_pose_, T) > kReuseRenderPx) render_at(T);
  const ImageView<const float> depth = raster_.depth();
  std::uint32_t cells = 0;
  int agree = 0;
  for (int i = 0; i < corr_count_; ++i) {
    const auto is = static_cast<std::size_t>(i);
    const int k = corr_kp_[is];
    kp_inlier_[static_cast<std::size_t>(k)] = corr_inlier_[is] ? 2 : 1;
    if (!corr_inlier_[is]) continue;
    const Vec2& px = corr_px_[is];
    const Vec3 p_render = raster_pose_ * corr_p_[is];
    const Vec2 rp = raster_.full_to_raster(K_.project(p_render));
    const int x = static_cast<int>(std::lround(rp.x())), y = static_cast<int>(std::lround(rp.y()));
    if (p_render.z() > 1.0 && depth.contains(x, y) && visible_at_depth(p_render.z(), depth(x, y))) ++agree;
    const int cx = std::clamp(static_cast<int>(4.0 * px.x() / K_.width), 0, 3);
    const int cy = std::clamp(static_cast<int>(4.0 * px.y() / K_.height), 0, 3);
    cells |= 1u << (cy * 4 + cx);
  }
  e->mask_agreement = e->inliers > 0 ? static_cast<double>(agree) / e->inliers : 0.0;
  e->spread_cells = std::popcount(cells);
}

// Of this frame's inliers, the share that are anchored map points.
double TrackerImpl::anchored_share() const {
  int n = 0, anchored = 0;
  for (int i = 0; i < corr_count_; ++i)
    if (corr_inlier_[static_cast<std::size_t>(i)]) {
      ++n;
      anchored += map_.point(corr_point_[static_cast<std::size_t>(i)]).anchored ? 1 : 0;
    }
  return n > 0 ? static_cast<double>(anchored) / n : 0.0;
}

TrackResult TrackerImpl::track(GrayView luma, int frame_index) {
  TrackResult r;
  double t = now_ms();
  const SE3 T_predicted = motion_prior(luma, T_last_, velocity_ * T_last_);
  lap(Stage::kPyramid, &t, &r);  // image preparation: the small blurred image and its alignment
  render_at(T_predicted);
  lap(Stage::kRaster, &t, &r);
  extract(luma, true, &r);
  lap(Stage::kDetect, &t, &r);
  PoseEstimate e;
  bool ok = track_from(T_predicted, config_.search_radius_px, &e, &r);
  if (ok) {
    r.pose_jump_deg = pose_delta(T_predicted, e.T_camera_model).angle_deg;
    r.pose_jump_mm = (camera_centre(T_predicted) - camera_centre(e.T_camera_model)).norm();
    const bool plausible = r.pose_jump_deg <= config_.max_jump_deg && r.pose_jump_mm <= config_.max_jump_mm;
    ok = plausible && PoseGates::passes(e, strict_frames_left_ > 0 ? gates_.strict() : gates_.normal());
    if (!ok && plausible && strict_frames_left_ == 0 && PoseGates::passes(e, gates_.confirm())) {
      const double agreement_px = anchor_agreement_px(T_predicted, e.T_camera_model);
      ok = agreement_px <= config_.confirm_agreement_px;
      r.confirmed_by_alignment = ok;
    }
  }
  if (ok && outline_refutes(e, &r)) ok = false;
  fill_measures(e, &r);
  if (ok) {
    accept(e, frame_index, TrackState::kTracking, &r);
  } else {
    r.state = TrackState::kLost;
    lost_ = true;
    lost_frames_ = 0;
    lost_velocity_ = velocity_;
    T_dead_reckoned_ = T_predicted;  // this frame's best guess (image motion included)
    // Measured from the last tracked frame where the organ allows.
    if (dead_reckon(&T_dead_reckoned_, velocity_ * T_last_)) lost_velocity_ = T_dead_reckoned_ * T_last_.inverse();
    reloc_keyframes_.forget_ranking();  // ranked at the first relocalisation attempt
    // Without a feature pose, the outline and the shading may still agree
    // on one (smooth tissue).
    PoseEstimate by_outline;
    if (track_by_outline(T_dead_reckoned_, &by_outline, &r)) {
      accept(by_outline, frame_index, TrackState::kTracking, &r);
    } else {
      velocity_ = SE3();
    }
  }
  return r;
}

// The pose from the organ's outline and its shading, for a frame whose
// features gave none (TrackerConfig::use_contour), from T_guess (dead
// reckoning's, or the prediction). Two independent measurements from the
// same start: the outline alone (RegionModality), and the shading alone,
// this frame aligned directly against the last reported frame through the
// mesh's depth (shading_ref_). judge_agreement() decides
// (core/tracking/modality_agreement.h); the pose reported minimises both,
// the outline's lines whitened by their own measured spread (their mean
// chi2, when above 1) and the shading by its information times
// photometric_weight. True with *e filled when they agree.
bool TrackerImpl::track_by_outline(const SE3& T_guess, PoseEstimate* e, TrackResult* r) {
  if (!config_.use_contour || !region_.has_colour_model() || !shading_ref_.has_reference()) return false;
  double t = now_ms();
  r->outline_tried = true;
  OutlineShadingEvidence evidence;
  SE3 T_outline = T_guess;
  ContourFit fit;
  if (region_.estimate(luma_, chroma_, valid_view_, camera_, &T_outline, &fit, config_.contour_min_lines))
    evidence.outline_lines = fit.lines;
  r->contour_lines = evidence.outline_lines;
  r->T_outline = T_outline;
  r->contour_rms_px = fit.rms_px;
  render_at(shading_ref_.reference_pose());
  Mat6 H_outline = Mat6::Zero();
  if (evidence.outline_lines > 0) evidence.outline_sigma_px = outline_sigma_px(T_outline, fit, &H_outline);
  r->contour_sigma_px = evidence.outline_sigma_px;
  lap(Stage::kContour, &t, r);
  SE3 T_shading = T_guess;
  DirectAlignSummary shading;
  evidence.shading_measured = shading_ref_.align(orb_.pyramid().level(align_level_), valid_view_, raster_, camera_,
                                                 &T_shading, &shading, true);
  if (evidence.outline_lines > 0 && evidence.shading_measured) {
    evidence.disagreement_px = view_difference_px(T_outline, T_shading);
    evidence.joint_sigma_px =
        information_sigma_px(H_outline + config_.photometric_weight * shading.information, T_outline);
  }
  r->joint_sigma_px = evidence.joint_sigma_px;
  r->T_shading = T_shading;
  r->modality_agreement_px = evidence.outline_lines > 0 && evidence.shading_measured ? evidence.disagreement_px : -1.0;
  AgreementLimits limits;
  limits.min_lines = config_.contour_min_lines;
  limits.max_outline_sigma_px = config_.contour_max_sigma_px;
  limits.max_disagreement_px = config_.contour_agreement_px;
  limits.max_joint_sigma_px = config_.contour_max_joint_sigma_px;
  r->agreement = judge_agreement(evidence, limits);
  lap(Stage::kContour, &t, r);
  if (r->agreement != Agreement::kAgree) return false;
  const double outline_scale = 1.0 / std::max(1.0, fit.chi2_per_line);
  const Mat6 I_shading = config_.photometric_weight * shading.information;
  const SE3 shading_inverse = T_shading.inverse();
  SE3 T = T_outline;
  for (int it = 0; it < 6; ++it) {
    Mat6 H = Mat6::Zero();
    Vec6 g = Vec6::Zero();
    region_.linearize(T, &H, &g);
    H *= outline_scale;
    g *= outline_scale;
    H += I_shading;
    g += I_shading * (T * shading_inverse).log();
    const Vec6 delta = H.ldlt().solve(-g);
    if (!delta.allFinite()) return false;
    T = SE3::exp(delta) * T;
    if (delta.head<3>().norm() < 1e-7 && delta.tail<3>().norm() < 1e-5) break;
  }
  lap(Stage::kContour, &t, r);
  // The joint pose lies between the two; if it left either by more than
  // they may differ, the linearisation did not hold.
  if (!T.all_finite() || view_difference_px(T, T_outline) > config_.contour_agreement_px ||
      view_difference_px(T, T_shading) > config_.contour_agreement_px) {
    r->agreement = Agreement::kDisagree;
    return false;
  }
  *e = PoseEstimate{};
  e->solved = true;
  e->T_camera_model = T;
  e->mean_depth_mm = last_depth_mm_;
  r->by_outline = true;
  return true;
}

// How far the organ in view moves (view_sigma_px, on the current render)
// for a pose of information H (normal equations) at T: view_sigma_px of
// H's inverse. Infinite when H leaves a direction unfixed.
double TrackerImpl::information_sigma_px(const Mat6& H, const SE3& T) const {
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(H, Eigen::EigenvaluesOnly);
  if (!(eig.eigenvalues()(0) > 1e-12 * std::max(1.0, eig.eigenvalues()(5))))
    return std::numeric_limits<double>::infinity();
  return view_sigma_px(H.inverse(), T);
}

// The outline's own uncertainty at its pose T (fit: what estimate() saw):
// information_sigma_px of the lines' normal equations, scaled by their
// mean chi2 when above 1; *H_out (optional) gets those scaled equations.
double TrackerImpl::outline_sigma_px(const SE3& T, const ContourFit& fit, Mat6* H_out) const {
  Mat6 H = Mat6::Zero();
  Vec6 g = Vec6::Zero();
  region_.linearize(T, &H, &g);
  H /= std::max(1.0, fit.chi2_per_line);
  if (H_out) *H_out = H;
  return information_sigma_px(H, T);
}

// A weak feature pose, checked by the organ's outline measured from it
// (TrackerConfig::contour_check_inliers): true when the outline puts the
// organ more than contour_veto_px from the features' pose, and more than
// kVetoSigmas times the outline's own uncertainty (scaled by its chi2).
// Measured on the smooth set: a blurred frame at the start of a swing
// passed the gates with 52 inliers at 10.6 deg and 21 mm from the truth;
// its outline (208 lines, sigma 3.4 px) put the organ 29.8 px away.
namespace {
// A disagreement this many of the outline's sigmas is not its noise.
constexpr double kVetoSigmas = 5.0;
}  // namespace

bool TrackerImpl::outline_refutes(const PoseEstimate& e, TrackResult* r) {
  if (!config_.use_contour || e.inliers >= config_.contour_check_inliers || !region_.has_colour_model()) return false;
  double t = now_ms();
  SE3 T = e.T_camera_model;
  ContourFit fit;
  bool refuted = false;
  if (region_.estimate(luma_, chroma_, valid_view_, camera_, &T, &fit, config_.contour_min_lines)) {
    const double difference_px = view_difference_px(T, e.T_camera_model);
    refuted = difference_px > config_.contour_veto_px && difference_px > kVetoSigmas * outline_sigma_px(T, fit);
  }
  lap(Stage::kContour, &t, r);
  r->outline_vetoed = refuted;
  return refuted;
}

// The outline's colour models learn from a reported frame at its pose,
// every kLearnEvery reported frames (one render each; the organ's and its
// surroundings' colours change slowly), and always when forced (frame 0).
void TrackerImpl::learn_colours(const SE3& T, float rate, bool force) {
  if (!config_.use_contour) return;
  if (!force && ++frames_since_learn_ < kLearnEvery) return;
  frames_since_learn_ = 0;
  region_.learn(luma_, chroma_, valid_view_, camera_, T, rate);
  outline_search_.learn(luma_, chroma_, valid_view_, region_.raster(), rate);  // region_ rendered at T
}

void TrackerImpl::fill_measures(const PoseEstimate& e, TrackResult* r) const {
  r->matches = e.matches;
  r->inliers = e.inliers;
  r->inlier_ratio = e.inlier_ratio();
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
  // No velocity from a frame the outline carried: the outline leaves a mix
  // of rotation and translation nearly unseen, and a velocity taken from
  // its poses fed their error in that mix back into the next prediction,
  // which grew it by about half each frame (orbit, the outline alone: 0.4
  // deg to 5.8 deg in six frames, the organ's outline still fitting). Nor
  // the velocity it came with: after a swing that one is the swing's.
  // Dead reckoning measures the next frame's motion from this pose.
  velocity_ = state == TrackState::kTracking && !r->by_outline ? e.T_camera_model * T_last_.inverse() : SE3();
  // How far the view moved since the last frame (level-0 px): blur. After
  // a lost spell, as dead reckoning measured it (kUnknownMotion if not).
  const double motion_px = state == TrackState::kTracking      ? image_shift_px(T_last_, e.T_camera_model)
                           : state == TrackState::kRelocalised ? lost_motion_px_
                                                               : 0.0;
  T_last_ = e.T_camera_model;
  if (config_.use_image_motion) {  // where dead reckoning starts if the next frame is lost
    const GrayView small = orb_.pyramid().level(align_level_);
    aligner_.keep_reference(small, valid_view_, e.T_camera_model);
    // The anchor that confirms weak poses must itself be clearly good: not
    // confirmed, and with margin over the ratio gate.
    if (!r->confirmed_by_alignment && e.inlier_ratio() >= config_.anchor_min_inlier_ratio)
      anchor_.keep_reference(small, valid_view_, e.T_camera_model);
    if (config_.use_contour) shading_ref_.keep_reference(small, valid_view_, e.T_camera_model);
  }
  // The outline's colours: learnt faster from feature poses, slowly from
  // the outline's own (so that an error does not teach itself).
  lap(Stage::kMap, &t, r);
  learn_colours(e.T_camera_model, r->by_outline ? 0.05f : 0.2f);
  lap(Stage::kContour, &t, r);
  last_inliers_ = e.inliers;
  last_depth_mm_ = e.mean_depth_mm;
  lost_ = false;
  lost_frames_ = 0;
  update_counters(frame_index);
  // No keyframe from a frame that moved fast: it is blurred, its pose is
  // less accurate, and the keyframe's mesh-depth points would carry that
  // error into the map for good (fast seed 4: 1-3 deg off after a burst).
  // Under the strict gates after a relocalisation no keyframe is taken.
  // The relocalised frame itself may seed one (the scope may have come back
  // to a view the map hardly covers, and without new points the next frames
  // cannot pass) when relocalise() judged its pose fit to (reloc_seed_ok_)
  // and dead reckoning measured it as slow, so not blurred.
  // A confirmed frame (relaxed ratio) may add one only if it stands mostly
  // on anchored points, and its own points are not anchored.
  bool may_add = state == TrackState::kRelocalised ? reloc_seed_ok_ : strict_frames_left_ == 0;
  if (r->by_outline) may_add = false;  // no feature inliers: the keyframe's points would have no check
  if (r->confirmed_by_alignment && anchored_share() < config_.confirmed_keyframe_min_anchored) may_add = false;
  if (strict_frames_left_ > 0) --strict_frames_left_;
  if (may_add && motion_px <= static_cast<double>(config_.keyframe_max_motion_px) && need_keyframe(e))
    r->keyframe = add_keyframe(e.T_camera_model, frame_index, true, !r->confirmed_by_alignment) >= 0;
  lap(Stage::kMap, &t, r);
}

}  // namespace st
