#include "core/tracking/ba_handoff.h"

#include <algorithm>
#include <cmath>

#include "core/pose/correspondences.h"

namespace st {

Status BaHandoff::configure(const TrackerConfig& config, const SE3& T_camera_model_init) {
  config_ = config;
  T_init_ = T_camera_model_init;
  for (int o = 0; o < kMaxPyramidLevels; ++o)
    octave_info_[static_cast<std::size_t>(o)] = octave_information(o, static_cast<double>(config.features.scale_factor));
  point_index_.assign(static_cast<std::size_t>(config.max_map_points), -1);
  keyframe_index_.assign(static_cast<std::size_t>(config.max_keyframes), -1);
  order_.assign(static_cast<std::size_t>(config.max_keyframes), -1);
  reset();
  return Status::Ok();
}

void BaHandoff::reset() {
  window_pending_ = global_pending_ = focal_pending_ = false;
  focal_waits_ = 0;
  init_keyframe_ = init_keyframe_frame_ = -1;
  keyframes_since_global_ = 0;
  calibration_jobs_ = 0;
  calibration_ = CalibrationCheck{};
  min_version_ = version_ + 1;  // a job still out refers to the map just cleared
}

bool BaHandoff::apply(TrackingMap* map) {
  if (!channel_) return false;
  const BaJob* job = channel_->solved_job();
  if (!job) return false;
  const bool usable = job->summary.usable && job->version >= min_version_;
  if (usable && job->summary.focal_tested) judge_calibration(job->summary);
  if (job->kind == BaKind::kFocalTest) {  // a test: nothing to write into the map
    channel_->release_job(job);
    return false;
  }
  // The first window jobs are each followed by a focal test from their solution.
  if (usable && job->kind == BaKind::kWindow && config_.check_calibration && config_.ba.w_shape > 0 &&
      calibration_jobs_ < config_.calibration_test_jobs)
    focal_pending_ = true;
  if (usable) {
    for (int i = 0; i < job->keyframe_count; ++i) {
      const BaKeyframe& k = job->keyframes[static_cast<std::size_t>(i)];
      if (k.fixed || k.id < 0 || k.id >= map->keyframe_capacity()) continue;
      Keyframe& kf = map->keyframe(k.id);
      if (kf.alive && kf.frame == k.frame) kf.T_camera_model = job->pose(i);
    }
    for (int i = 0; i < job->point_count; ++i) {
      const BaPoint& p = job->points[static_cast<std::size_t>(i)];
      if (p.id < 0 || p.id >= map->point_capacity()) continue;
      MapPoint& mp = map->point(p.id);
      if (mp.alive && mp.created_frame == p.created_frame) mp.p_model = job->point(i);
    }
  }
  channel_->release_job(job);
  return usable;
}

void BaHandoff::map_initialised(const TrackingMap& map, int init_keyframe) {
  init_keyframe_ = init_keyframe;
  init_keyframe_frame_ = init_keyframe >= 0 ? map.keyframe(init_keyframe).frame : -1;
  keyframes_since_global_ = 0;
}

void BaHandoff::frame_done(const TrackingMap& map, const TrackResult& r) {
  if (r.keyframe) {
    window_pending_ = true;
    if (config_.ba_registration_keyframes > 0 && registration_free(map) &&
        ++keyframes_since_global_ >= config_.ba_registration_keyframes) {
      global_pending_ = true;
      keyframes_since_global_ = 0;
    }
  }
  if (r.state == TrackState::kRelocalised && config_.ba_global_after_reloc) global_pending_ = true;
  if (r.state == TrackState::kInitialised) window_pending_ = global_pending_ = false;  // a fresh map
}

void BaHandoff::note_frame(int frame_index) {
  if (calibration_.suspect && calibration_.suspect_frame < 0) calibration_.suspect_frame = frame_index;
}

// One focal test's vote: a significant fit (F) to focal lengths clearly
// off (|s - 1|), on the same side as the votes before it; anything else
// resets the count.
void BaHandoff::judge_calibration(const BaSummary& s) {
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

// The registration prior applies: sigmas > 0 and frame 0's keyframe alive.
bool BaHandoff::registration_free(const TrackingMap& map) const {
  if (!(config_.registration_sigma_deg > 0) || init_keyframe_ < 0 || init_keyframe_ >= map.keyframe_capacity())
    return false;
  const Keyframe& kf = map.keyframe(init_keyframe_);
  return kf.alive && kf.frame == init_keyframe_frame_;
}

bool BaHandoff::submit(const TrackingMap& map, bool initialised) {
  if (!channel_ || !config_.use_ba || !initialised || (!window_pending_ && !global_pending_ && !focal_pending_))
    return false;
  BaJob* job = channel_->acquire_job();
  if (!job) return false;
  // Corrections first (a global job covers the window too), the test when
  // neither is pending or when it has waited behind kMaxFocalWaits window
  // jobs (a mapping thread that never catches up still tests the
  // calibration).
  const bool focal_due = focal_pending_ && focal_waits_ >= kMaxFocalWaits;
  const BaKind kind = global_pending_                                 ? BaKind::kGlobal
                      : focal_pending_ && (!window_pending_ || focal_due) ? BaKind::kFocalTest
                                                                          : BaKind::kWindow;
  fill_job(map, job, kind);
  if (kind == BaKind::kFocalTest) {
    focal_pending_ = false;
    focal_waits_ = 0;
    ++calibration_jobs_;
  } else {
    if (focal_pending_) ++focal_waits_;
    window_pending_ = global_pending_ = false;
  }
  channel_->submit_job(job);  // an empty job comes back unusable (BundleAdjuster refuses it)
  return true;
}

int BaHandoff::add_job_keyframe(const TrackingMap& map, BaJob* job, int keyframe_id, bool fixed) {
  int& index = keyframe_index_[static_cast<std::size_t>(keyframe_id)];
  if (index < 0) {
    const Keyframe& kf = map.keyframe(keyframe_id);
    index = job->add_keyframe(keyframe_id, kf.frame, kf.T_camera_model, fixed);
  }
  return index;
}

// Observations of one keyframe. add_points: its points join the job (a
// window or global keyframe); otherwise only links to points already in
// the job count (an older, fixed keyframe), and the keyframe joins the job
// on its first such link.
void BaHandoff::add_job_links(const TrackingMap& map, BaJob* job, int keyframe_id, int job_keyframe,
                              bool add_points) {
  const Keyframe& kf = map.keyframe(keyframe_id);
  for (int i = 0; i < kf.link_count; ++i) {
    const KeyframeLink& l = kf.links[i];
    const MapPoint* p = map.linked_point(l);
    if (!p) continue;
    int& point = point_index_[static_cast<std::size_t>(l.point)];
    if (point < 0) {
      if (!add_points) continue;
      point = job->add_point(l.point, p->created_frame, p->p_model);
      if (point < 0) continue;  // job full
    }
    if (job_keyframe < 0) job_keyframe = add_job_keyframe(map, job, keyframe_id, true);
    if (job_keyframe < 0) return;
    const int octave = std::clamp(static_cast<int>(l.octave), 0, kMaxPyramidLevels - 1);
    if (!job->add_observation(job_keyframe, point, Vec2(static_cast<double>(l.x_ideal), static_cast<double>(l.y_ideal)),
                              octave_info_[static_cast<std::size_t>(octave)]))
      return;
  }
}

// Window (and focal test): the newest ba_window_keyframes keyframes and
// their points free, older keyframes that see those points fixed. Global:
// every keyframe and point free (BundleAdjuster holds the oldest keyframe
// for the gauge).
void BaHandoff::fill_job(const TrackingMap& map, BaJob* job, BaKind kind) {
  job->clear();
  job->kind = kind;
  job->version = ++version_;
  job->test_focal = kind == BaKind::kFocalTest;
  const bool global = kind == BaKind::kGlobal;
  int n = 0;
  for (int k = 0; k < map.keyframe_capacity(); ++k)
    if (map.keyframe(k).alive) order_[static_cast<std::size_t>(n++)] = k;
  std::sort(order_.begin(), order_.begin() + n,
            [&map](std::int32_t a, std::int32_t b) { return map.keyframe(a).frame > map.keyframe(b).frame; });
  const int window = global ? n : std::min(n, config_.ba_window_keyframes);
  for (int j = 0; j < window; ++j) {
    const int id = order_[static_cast<std::size_t>(j)];
    const int index = add_job_keyframe(map, job, id, false);
    if (index >= 0) add_job_links(map, job, id, index, true);
  }
  for (int j = window; j < n; ++j) add_job_links(map, job, order_[static_cast<std::size_t>(j)], -1, false);
  // The registration prior, when frame 0's keyframe is free in this job
  // (the focal test's solves take none).
  if (kind != BaKind::kFocalTest && registration_free(map)) {
    const int index = keyframe_index_[static_cast<std::size_t>(init_keyframe_)];
    if (index >= 0 && !job->keyframes[static_cast<std::size_t>(index)].fixed)
      job->set_prior(index, T_init_, config_.registration_sigma_deg * M_PI / 180.0, config_.registration_sigma_mm);
  }
  // Reset the index arrays for the next job.
  for (int i = 0; i < job->point_count; ++i)
    point_index_[static_cast<std::size_t>(job->points[static_cast<std::size_t>(i)].id)] = -1;
  for (int i = 0; i < job->keyframe_count; ++i)
    keyframe_index_[static_cast<std::size_t>(job->keyframes[static_cast<std::size_t>(i)].id)] = -1;
}

}  // namespace st
