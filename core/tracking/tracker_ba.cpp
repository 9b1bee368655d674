// Bundle-adjustment hand-off of the tracker: after a keyframe (window BA)
// or a relocalisation (global BA), the tracker copies the relevant part of
// its map into a job buffer from the BaChannel and submits it; at the start
// of a later frame it applies the solved job to the map (poses of the
// optimised keyframes, positions of the points), skipping every entry
// whose slot was culled or reused in the meantime (frame stamps). Only one
// job is out at a time, so every job starts from the previous corrections.
// Tracking thread; allocates nothing (the job buffers belong to the
// channel, the index arrays are sized in configure()).
#include <algorithm>
#include <cmath>

#include "core/base/capacity.h"
#include "core/tracking/tracker_impl.h"

namespace st {

bool TrackerImpl::apply_ba() {
  if (!ba_channel_) return false;
  const BaJob* job = ba_channel_->solved_job();
  if (!job) return false;
  const bool usable = job->summary.usable && job->version >= ba_min_version_;
  if (usable && job->summary.focal_tested) judge_calibration(job->summary);
  if (usable) {
    for (int i = 0; i < job->keyframe_count; ++i) {
      const BaKeyframe& k = job->keyframes[static_cast<std::size_t>(i)];
      if (k.fixed || k.id < 0 || k.id >= map_.keyframe_capacity()) continue;
      Keyframe& kf = map_.keyframe(k.id);
      if (kf.alive && kf.frame == k.frame) kf.T_camera_model = job->pose(i);
    }
    for (int i = 0; i < job->point_count; ++i) {
      const BaPoint& p = job->points[static_cast<std::size_t>(i)];
      if (p.id < 0 || p.id >= map_.point_capacity()) continue;
      MapPoint& mp = map_.point(p.id);
      if (mp.alive && mp.created_frame == p.created_frame) mp.p_model = job->point(i);
    }
  }
  ba_channel_->release_job(job);
  return usable;
}

// One focal test's vote (TrackerConfig::check_calibration): a significant
// fit (F) to focal lengths clearly off (|s - 1|), on the same side as the
// votes before it; anything else resets the count.
void TrackerImpl::judge_calibration(const BaSummary& s) {
  CalibrationCheck& c = calibration_;
  ++c.tests;
  c.max_f = std::max(c.max_f, s.focal_f);
  const bool against =
      s.focal_f > config_.calibration_min_f && std::abs(s.focal_scale - 1.0) > config_.calibration_scale_error;
  const bool same_side = (s.focal_scale > 1.0) == (c.last_scale > 1.0);
  c.votes = against ? (c.votes > 0 && same_side ? c.votes + 1 : 1) : 0;
  c.last_scale = s.focal_scale;
  if (c.suspect) return;  // the verdict's figures stay
  c.focal_scale = s.focal_scale;
  c.focal_f = s.focal_f;
  if (c.votes >= config_.calibration_votes) c.suspect = true;
}

bool TrackerImpl::registration_free() const {
  if (!(config_.registration_sigma_deg > 0) || init_keyframe_ < 0 ||
      init_keyframe_ >= map_.keyframe_capacity())
    return false;
  const Keyframe& kf = map_.keyframe(init_keyframe_);
  return kf.alive && kf.frame == init_keyframe_frame_;
}

// Hands out the pending job (global first: it covers the window too).
// False when nothing is pending, BA is off, or the channel is busy (the
// job stays pending: deferred to a later frame).
bool TrackerImpl::submit_ba() {
  if (!ba_channel_ || !config_.use_ba || !initialised_ || (!ba_window_pending_ && !ba_global_pending_)) return false;
  BaJob* job = ba_channel_->acquire_job();
  if (!job) return false;
  const bool global = ba_global_pending_;
  fill_job(job, global);
  ba_window_pending_ = ba_global_pending_ = false;
  ba_channel_->submit_job(job);  // an empty job comes back unusable (BundleAdjuster refuses it)
  return true;
}

int TrackerImpl::add_job_keyframe(BaJob* job, int keyframe_id, bool fixed) {
  int& index = ba_keyframe_index_[static_cast<std::size_t>(keyframe_id)];
  if (index < 0) {
    const Keyframe& kf = map_.keyframe(keyframe_id);
    index = job->add_keyframe(keyframe_id, kf.frame, kf.T_camera_model, fixed);
  }
  return index;
}

// Observations of one keyframe. add_points: its points join the job (a
// window or global keyframe); otherwise only links to points already in
// the job count (an older, fixed keyframe), and the keyframe joins the job
// on its first such link.
void TrackerImpl::add_job_links(BaJob* job, int keyframe_id, int job_keyframe, bool add_points) {
  const Keyframe& kf = map_.keyframe(keyframe_id);
  for (int i = 0; i < kf.link_count; ++i) {
    const KeyframeLink& l = kf.links[i];
    const MapPoint* p = map_.linked_point(l);
    if (!p) continue;
    int& point = ba_point_index_[static_cast<std::size_t>(l.point)];
    if (point < 0) {
      if (!add_points) continue;
      point = job->add_point(l.point, p->created_frame, p->p_model);
      if (point < 0) continue;  // job full
    }
    if (job_keyframe < 0) job_keyframe = add_job_keyframe(job, keyframe_id, true);
    if (job_keyframe < 0) return;
    const int octave = std::clamp(static_cast<int>(l.octave), 0, kMaxPyramidLevels - 1);
    if (!job->add_observation(job_keyframe, point, Vec2(static_cast<double>(l.x_ideal), static_cast<double>(l.y_ideal)),
                              octave_info_[static_cast<std::size_t>(octave)]))
      return;
  }
}

// Window: the newest ba_window_keyframes keyframes and their points free,
// older keyframes that see those points fixed. Global: every keyframe and
// point free (BundleAdjuster holds the oldest keyframe for the gauge).
void TrackerImpl::fill_job(BaJob* job, bool global) {
  job->clear();
  job->kind = global ? BaKind::kGlobal : BaKind::kWindow;
  job->version = ++ba_version_;
  // The first window jobs also test the calibration's focal length.
  if (!global && config_.check_calibration && config_.ba.w_shape > 0 &&
      calibration_jobs_ < config_.calibration_test_jobs) {
    job->test_focal = true;
    ++calibration_jobs_;
  }
  int n = 0;
  for (int k = 0; k < map_.keyframe_capacity(); ++k)
    if (map_.keyframe(k).alive) ba_order_[static_cast<std::size_t>(n++)] = k;
  std::sort(ba_order_.begin(), ba_order_.begin() + n,
            [this](std::int32_t a, std::int32_t b) { return map_.keyframe(a).frame > map_.keyframe(b).frame; });
  const int window = global ? n : std::min(n, config_.ba_window_keyframes);
  for (int j = 0; j < window; ++j) {
    const int id = ba_order_[static_cast<std::size_t>(j)];
    const int index = add_job_keyframe(job, id, false);
    if (index >= 0) add_job_links(job, id, index, true);
  }
  for (int j = window; j < n; ++j) add_job_links(job, ba_order_[static_cast<std::size_t>(j)], -1, false);
  // The registration prior, when frame 0's keyframe is free in this job.
  if (registration_free()) {
    const int index = ba_keyframe_index_[static_cast<std::size_t>(init_keyframe_)];
    if (index >= 0 && !job->keyframes[static_cast<std::size_t>(index)].fixed)
      job->set_prior(index, T_init_, config_.registration_sigma_deg * M_PI / 180.0,
                     config_.registration_sigma_mm);
  }
  // Reset the index arrays for the next job.
  for (int i = 0; i < job->point_count; ++i) ba_point_index_[static_cast<std::size_t>(job->points[static_cast<std::size_t>(i)].id)] = -1;
  for (int i = 0; i < job->keyframe_count; ++i)
    ba_keyframe_index_[static_cast<std::size_t>(job->keyframes[static_cast<std::size_t>(i)].id)] = -1;
}

}  // namespace st
