// Relocalisation when lost: features over the whole valid image; first a
// cheap attempt by projection from the last good pose with the wide radius,
// then brute-force matching against a bounded number of keyframes per frame
// (round robin, the reference keyframe first), P3P RANSAC, LM, and the same
// projection tracking at the found pose. Every candidate must pass the
// strict gates (more inliers, spread, mask agreement). Tracking thread;
// allocates nothing.
#include <algorithm>

#include "core/tracker_impl.h"

namespace st {

TrackResult TrackerImpl::relocalise(GrayView luma, int frame_index) {
  TrackResult r;
  double t = now_ms();
  ++lost_frames_;
  render_at(T_last_);
  lap(Stage::kRaster, &t, &r);
  extract(luma, false, &r);  // whole valid image: the organ may be anywhere
  lap(Stage::kDetect, &t, &r);
  const QualityGates strict = gates(true);
  PoseEstimate e;
  bool found = track_from(T_last_, config_.wide_radius_px, &e, &r) && passes(e, strict);
  PoseEstimate best = e;  // reported measures when nothing passes: the attempt with most inliers
  t = now_ms();
  for (int j = 0; !found && j < config_.reloc_keyframes_per_frame && r.features > 0; ++j) {
    int kf = -1;
    if (j == 0 && lost_frames_ == 1 && ref_keyframe_ >= 0 && map_.keyframe(ref_keyframe_).alive) {
      kf = ref_keyframe_;
    } else {
      for (int n = 0; n < map_.keyframe_capacity() && kf < 0; ++n) {
        reloc_cursor_ = (reloc_cursor_ + 1) % map_.keyframe_capacity();
        if (map_.keyframe(reloc_cursor_).alive) kf = reloc_cursor_;
      }
    }
    if (kf < 0) break;
    e = PoseEstimate{};
    found = reloc_with_keyframe(kf, &e, &r) && passes(e, strict);
    if (found || e.inliers > best.inliers) best = e;
  }
  lap(Stage::kReloc, &t, &r);
  fill_measures(best, &r);
  if (found) {
    strict_frames_left_ = config_.strict_frames;
    accept(best, frame_index, TrackState::kRelocalised, &r);
  } else {
    r.state = TrackState::kLost;
  }
  return r;
}

// Brute-force matches of this frame against one keyframe's linked map
// points, a P3P RANSAC pose, then tracking by projection from it.
bool TrackerImpl::reloc_with_keyframe(int keyframe_id, PoseEstimate* e, TrackResult* r) {
  const Keyframe& kf = map_.keyframe(keyframe_id);
  FeatureSet& train = *train_;
  train.clear();
  train.width = config_.width;
  train.height = config_.height;
  int n = 0;
  for (int i = 0; i < kf.link_count && n < kMaxKeypoints; ++i) {
    const KeyframeLink& l = kf.links[i];
    const MapPoint* p = map_.linked_point(l);
    if (!p) continue;
    const auto ns = static_cast<std::size_t>(n++);
    train.keypoints[ns] = Keypoint{l.x, l.y, l.angle_deg, 0.f, l.octave};
    train.descriptors[ns] = p->descriptor;
    train_point_[ns] = l.point;
  }
  train.count = n;
  if (n < config_.min_inliers) return false;
  const FeatureSet& f = *features_;
  matcher_.match_brute_force(f, train, match_of_query_.data(), nullptr);
  int c = 0;
  for (int q = 0; q < f.count; ++q) {
    const int m = match_of_query_[static_cast<std::size_t>(q)];
    if (m < 0) continue;
    const auto cs = static_cast<std::size_t>(c++);
    corr_point_[cs] = train_point_[static_cast<std::size_t>(m)];
    corr_p_[cs] = map_.point(corr_point_[cs]).p_model;
    corr_px_[cs] = kp_ideal_[static_cast<std::size_t>(q)];
    corr_info_[cs] = octave_info_[static_cast<std::size_t>(f.keypoints[static_cast<std::size_t>(q)].octave)];
    corr_kp_[cs] = q;
  }
  corr_count_ = c;
  if (c < config_.min_inliers) return false;
  const Correspondences corr{corr_p_.data(), corr_px_.data(), corr_info_.data(), c};
  SE3 T;
  PnpRansacSummary s;
  if (!ransac_.solve(corr, K_, &T, &s)) return false;
  render_at(T);
  for (int k = 0; k < f.count; ++k) kp_inlier_[static_cast<std::size_t>(k)] = 0;
  return track_from(T, config_.search_radius_px, e, r);
}

}  // namespace st
