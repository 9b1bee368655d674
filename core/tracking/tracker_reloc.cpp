// Relocalisation when lost: features over the whole valid image; first a
// cheap attempt by projection from the dead-reckoned pose (measured by
// direct alignment while the organ is in view, else carried forward, then
// the last good pose) with the wide radius, then brute-force matching
// against a bounded number of keyframes per frame (the keyframes nearest
// the last good pose first, then cycling through all), P3P RANSAC, LM, and
// the same projection tracking at the found pose. Every candidate must pass
// the strict gates (more inliers, spread, mask agreement), except a pose
// the measured dead reckoning predicted within the tracking search radius:
// it passes the normal gates, as a tracked frame would; and a pose that
// fails only the inlier ratio, down to confirmed_min_inlier_ratio, if
// direct alignment against the anchor confirms it (TrackerConfig,
// confirmed poses). Last, an outline that places the organ by itself far
// from the shading's guess is tried as a guess of its own
// (TrackerConfig::outline_guess), or, where there is none, the organ's
// silhouette searched from every side (TrackerConfig::outline_search).
// Tracking thread; allocates nothing.
#include <algorithm>
#include <array>
#include <cmath>

#include "core/tracking/tracker_impl.h"

namespace st {

TrackResult TrackerImpl::relocalise(GrayView luma, int frame_index) {
  TrackResult r;
  double t = now_ms();
  ++lost_frames_;
  // Dead reckoning: for the first frames the camera most likely keeps the
  // motion it had when tracking failed (a fast turn); later the last pose is
  // the better guess.
  // The image motion keeps turning the guess (and stays continuous for the
  // frames after relocalisation).
  const SE3 T_turned = motion_prior(luma, T_dead_reckoned_, lost_velocity_ * T_dead_reckoned_);
  lap(Stage::kPyramid, &t, &r);  // image preparation: the small blurred image and its alignment
  extract(luma, false, &r);  // whole valid image: the organ may be anywhere
  lap(Stage::kDetect, &t, &r);
  // Where the organ is in view, the motion is measured (dead_reckon: this
  // frame against the last one, with the mesh's depth) and that
  // measurement is the guess, however long tracking has been lost; the
  // velocity follows it.
  SE3 T_measured = T_turned;
  const bool measured = dead_reckon(&T_measured, lost_velocity_ * T_dead_reckoned_);
  // This frame's own motion (its blur), when measured.
  lost_motion_px_ = measured ? image_shift_px(T_dead_reckoned_, T_measured) : kUnknownMotion;
  if (measured) {
    lost_velocity_ = T_measured * T_dead_reckoned_.inverse();
    T_dead_reckoned_ = T_measured;
  } else {
    // The turn that broke tracking slows down (a scope swung fast is
    // stopped again): carried at full speed, the guess overshot by 40 deg
    // within 10 frames of a simulated burst. The image motion still
    // corrects rotation.
    lost_velocity_ = SE3::exp(config_.dead_reckoning_decay * lost_velocity_.log());
    if (lost_frames_ <= config_.dead_reckoning_frames) T_dead_reckoned_ = T_turned;
  }
  const SE3 T_guess = measured || lost_frames_ <= config_.dead_reckoning_frames ? T_dead_reckoned_ : T_last_;
  lap(Stage::kPyramid, &t, &r);  // image preparation, dead reckoning
  render_at(T_guess);
  lap(Stage::kRaster, &t, &r);
  const QualityGates strict = gates_.strict();
  PoseEstimate e;
  const bool solved = track_from(T_guess, config_.wide_radius_px, &e, &r);
  // Features that land where dead reckoning predicted, within the radius
  // normal tracking searches around its constant-velocity prediction,
  // confirm the measured motion: two independent measurements agree, and
  // the frame is judged like a tracked one (normal gates, no strict frames
  // after it). Otherwise the strict gates of relocalisation apply.
  const double agreement_px = solved && measured ? view_difference_px(T_guess, e.T_camera_model) : kUnknownMotion;
  const bool confirmed = agreement_px <= static_cast<double>(config_.search_radius_px);
  bool found = solved && PoseGates::passes(e, confirmed ? gates_.normal() : strict);
  // A pose only the relaxed gates pass, if direct alignment against the
  // anchor confirms it (see anchor_agreement_px): measured from a trusted
  // frame, so no strict frames after it either.
  if (!found && solved && PoseGates::passes(e, gates_.confirm()))
    found = r.confirmed_by_alignment =
        anchor_agreement_px(T_guess, e.T_camera_model) <= config_.confirm_agreement_px;
  const bool found_confirmed = found && (confirmed || r.confirmed_by_alignment);
  // A keyframe's points stay in the map. Such a frame may seed them only
  // if it passes the strict gates, or if the two measurements agree within
  // the refine radius (a weak feature pose that is still several pixels
  // off left its error in the map for the rest of a run).
  reloc_seed_ok_ = found && (PoseGates::passes(e, strict) || agreement_px <= static_cast<double>(config_.refine_radius_px));
  PoseEstimate best = e;  // reported measures when nothing passes: the attempt with most inliers
  t = now_ms();
  if (!reloc_keyframes_.ranked()) reloc_keyframes_.rank(map_, T_last_, last_depth_mm_);
  for (int j = 0; !found && j < config_.reloc_keyframes_per_frame && r.features > 0; ++j) {
    const int kf = reloc_keyframes_.next(map_);
    if (kf < 0) break;
    e = PoseEstimate{};
    found = reloc_with_keyframe(kf, &e, &r) && PoseGates::passes(e, strict);
    reloc_seed_ok_ = found;
    if (found || e.inliers > best.inliers) best = e;
  }
  lap(Stage::kReloc, &t, &r);
  fill_measures(best, &r);
  if (found) {
    report_relocalised(best, frame_index, found_confirmed ? 0 : config_.strict_frames, &r);
    return r;
  }
  // No feature pose: the outline and the shading may agree on one.
  PoseEstimate by_outline;
  if (track_by_outline(T_guess, &by_outline, &r)) {
    fill_measures(by_outline, &r);
    accept(by_outline, frame_index, TrackState::kRelocalised, &r);
    velocity_ = lost_velocity_;  // measured frame to frame by dead reckoning
    return r;
  }
  r.state = TrackState::kLost;
  if (!outline_is_a_guess(r)) {
    relocalise_by_search(frame_index, &r);
    return r;
  }
  // The outline placed the organ on its own, far from the shading's pose
  // (after a swing the shading's alignment against the last tracked frame
  // fails or slides off; the outline is measured in this frame alone). The
  // features tracked from it must pass the stricter gates, as a brute-force
  // pose must: the outline brings the guess within reach, it does not
  // vouch for the pose.
  t = now_ms();
  PoseEstimate from_outline;
  if (track_from_guess(r.T_outline, &from_outline, &r) && PoseGates::passes(from_outline, strict)) {
    lap(Stage::kReloc, &t, &r);
    reloc_seed_ok_ = true;
    report_relocalised(from_outline, frame_index, config_.strict_frames, &r);
    return r;
  }
  lap(Stage::kReloc, &t, &r);
  // Nothing measured the motion: the outline's pose is the next frame's
  // guess, with no velocity (one taken from outline poses diverges).
  if (!measured) {
    T_dead_reckoned_ = r.T_outline;
    lost_velocity_ = SE3::Identity();
  }
  return r;
}

// Lost, and neither the features nor the outline near the guess found the
// pose: the silhouette searched from every side (search_outline). Each
// fitted candidate, best fit first, is tracked by the features: reported
// when they pass the stricter gates, or the normal gates with their pose
// within the search radius of the fit, or within the refine radius with
// outline_agreement_inlier_factor of the normal inliers. Failing that,
// where no outline fits near the guess (the guess has lost the organ), the
// next frame starts from the best fit: dead reckoning, and the keyframes
// nearest it first. Where one does, the guess stays: the search's best fit
// may be the mirror view of a near-symmetric organ, and a guess that the
// outline confirms is the better start.
void TrackerImpl::relocalise_by_search(int frame_index, TrackResult* r) {
  if (!config_.use_contour || !config_.outline_search || !outline_search_.configured() || r->features == 0) return;
  const bool outline_near_guess = outline_placed(*r);
  std::array<SE3, kSearchTried> fits;
  const int n = search_outline(r, fits.data());
  if (n == 0) return;
  double t = now_ms();
  for (int i = 0; i < n; ++i) {
    const SE3& fit = fits[static_cast<std::size_t>(i)];
    PoseEstimate e;
    if (!track_from_guess(fit, &e, r)) continue;
    // Two measurements agree: the features' pose within the search radius
    // of the outline's (each measured on its own), judged by the normal
    // gates, as the measured dead reckoning's agreement is above; within
    // the refine radius, the normal gates with outline_agreement_inlier_factor
    // x their inliers.
    const bool strict = PoseGates::passes(e, gates_.strict());
    const double agreement_px = view_difference_px(fit, e.T_camera_model);
    QualityGates close = gates_.normal();
    close.min_inliers = static_cast<int>(std::lround(config_.outline_agreement_inlier_factor * close.min_inliers));
    const bool agreed =
        (PoseGates::passes(e, gates_.normal()) && agreement_px <= static_cast<double>(config_.search_radius_px)) ||
        (PoseGates::passes(e, close) && agreement_px <= static_cast<double>(config_.refine_radius_px));
    if (!strict && !agreed) continue;
    lap(Stage::kReloc, &t, r);
    reloc_seed_ok_ = strict || agreement_px <= static_cast<double>(config_.refine_radius_px);
    report_relocalised(e, frame_index, config_.strict_frames, r);
    return;
  }
  lap(Stage::kReloc, &t, r);
  if (outline_near_guess) return;
  T_dead_reckoned_ = fits[0];
  lost_velocity_ = SE3::Identity();
  reloc_keyframes_.rank(map_, fits[0], (fits[0] * outline_search_.centre()).z());
}

// The silhouette searched from every side (OutlineSearch), two of its
// candidates fitted by the outline's lines from there; fits[]: those with
// contour_min_lines lines that fix the organ to contour_max_sigma_px,
// smallest chi2 per line first. Returns their number.
int TrackerImpl::search_outline(TrackResult* r, SE3* fits) {
  double t = now_ms();
  std::array<OutlineCandidate, kSearchTried> c;
  std::array<double, kSearchTried> chi2{};
  const int n = outline_search_.search(luma_, chroma_, valid_view_, c.data(), kSearchTried);
  r->outline_searched = outline_search_.stats().searched;
  if (n > 0) r->T_search = c[0].T_camera_model;
  // The best candidate and one of the others in turn: two fits a frame
  // (each ~5-7 ms at 1280x720) bound the frame's time; the candidates
  // change little from one lost frame to the next.
  int found = 0;
  const int others = std::max(0, n - 1);
  const int fitted[kSearchFits] = {0, others > 0 ? 1 + search_round_++ % others : -1};
  for (const int i : fitted) {
    if (i < 0) continue;
    SE3 T = c[static_cast<std::size_t>(i)].T_camera_model;
    ContourFit fit;
    if (!region_.estimate(luma_, chroma_, valid_view_, camera_, &T, &fit, config_.contour_min_lines)) continue;
    if (fit.lines < config_.contour_min_lines) continue;
    render_at(T);
    if (!(outline_sigma_px(T, fit) <= config_.contour_max_sigma_px)) continue;
    int pos = found++;
    for (; pos > 0 && chi2[static_cast<std::size_t>(pos - 1)] > fit.chi2_per_line; --pos) {
      chi2[static_cast<std::size_t>(pos)] = chi2[static_cast<std::size_t>(pos - 1)];
      fits[pos] = fits[pos - 1];
    }
    chi2[static_cast<std::size_t>(pos)] = fit.chi2_per_line;
    fits[pos] = T;
  }
  lap(Stage::kContour, &t, r);
  r->outline_search_found = found > 0;
  if (found > 0) r->T_search = fits[0];
  return found;
}

// The lost frame's outline, measured from the guess (track_by_outline()),
// placed the organ: contour_min_lines lines fixing it to
// contour_max_sigma_px.
bool TrackerImpl::outline_placed(const TrackResult& r) const {
  return r.outline_tried && r.contour_lines >= config_.contour_min_lines &&
         r.contour_sigma_px <= config_.contour_max_sigma_px;
}

// A lost frame's outline (track_by_outline() measured it) that is a guess
// of its own: enough lines, the organ fixed to contour_max_sigma_px by them
// alone, and the shading's pose unmeasured or farther than the wide search
// radius from it (where the two are that far apart, tracking from the
// shading's guess cannot reach the outline's pose).
bool TrackerImpl::outline_is_a_guess(const TrackResult& r) const {
  if (!config_.use_contour || !config_.outline_guess || r.features == 0 || !outline_placed(r)) return false;
  return r.modality_agreement_px < 0.0 || r.modality_agreement_px > static_cast<double>(config_.wide_radius_px);
}

// Brute-force matches of this frame against one keyframe's linked map
// points, a P3P RANSAC pose, then tracking by projection from it.
bool TrackerImpl::reloc_with_keyframe(int keyframe_id, PoseEstimate* e, TrackResult* r) {
  const FeatureSet& f = *features_;
  const int min_matches = config_.reloc_min_matches;
  if (reloc_keyframes_.match(map_, keyframe_id, f, min_matches, &matcher_) < min_matches) return false;
  int c = 0;
  for (int q = 0; q < f.count; ++q) {
    const int point = reloc_keyframes_.matched_point(q);
    if (point < 0) continue;
    const auto cs = static_cast<std::size_t>(c++);
    corr_point_[cs] = point;
    corr_p_[cs] = map_.point(corr_point_[cs]).p_model;
    corr_px_[cs] = kp_ideal_[static_cast<std::size_t>(q)];
    corr_info_[cs] = octave_info_[static_cast<std::size_t>(f.keypoints[static_cast<std::size_t>(q)].octave)];
    corr_kp_[cs] = q;
  }
  corr_count_ = c;
  if (c < min_matches) return false;
  const Correspondences corr{corr_p_.data(), corr_px_.data(), corr_info_.data(), c};
  SE3 T;
  PnpRansacSummary s;
  if (!ransac_.solve(corr, K_, &T, &s)) return false;
  return track_from_guess(T, e, r);
}

// Tracking by projection from a relocalisation's guess (a keyframe's
// RANSAC pose, a lost frame's outline): the raster at the guess, no
// inliers carried over from an earlier attempt, the normal search radius.
bool TrackerImpl::track_from_guess(const SE3& T_guess, PoseEstimate* e, TrackResult* r) {
  render_at(T_guess);
  for (int k = 0; k < features_->count; ++k) kp_inlier_[static_cast<std::size_t>(k)] = 0;
  return track_from(T_guess, config_.search_radius_px, e, r);
}

// A relocalised pose reported, followed by strict_frames frames under the
// strict gates.
void TrackerImpl::report_relocalised(const PoseEstimate& e, int frame_index, int strict_frames, TrackResult* r) {
  strict_frames_left_ = strict_frames;
  fill_measures(e, r);
  accept(e, frame_index, TrackState::kRelocalised, r);
}

}  // namespace st
