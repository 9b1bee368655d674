// The tracker's side of bundle adjustment: which jobs to hand out, filling
// them from the map, applying the solved ones, and the calibration's focal
// test after the first window jobs.
//
// After a keyframe a window job is pending (and, while frame 0's keyframe
// carries the registration prior, a global one every
// ba_registration_keyframes keyframes); after a relocalisation a global
// one. submit() copies the relevant part of the map into a job buffer from
// the BaChannel and hands it over (global first: it covers the window
// too); a busy channel defers it to a later frame. At the start of a later
// frame apply() writes the solved job into the map (keyframe poses, point
// positions), skipping every entry whose slot was culled or reused in the
// meantime (frame stamps). One job is out at a time, so every job starts
// from the previous corrections; a job handed out before the last reset()
// is not applied.
//
// The focal test (TrackerConfig::check_calibration): after each of the
// first calibration_test_jobs window jobs is applied, a job of its own
// (BaKind::kFocalTest, the same window from the corrected map) when no
// correction is pending, so that the test's two solves do not delay a
// window's correction, or after kMaxFocalWaits window jobs went before it
// (a mapping thread that never catches up would starve it); nothing of it
// is written into the map. Each test's
// summary is a vote when its data fits focal lengths clearly off (F above
// calibration_min_f and |s - 1| above calibration_scale_error);
// calibration_votes votes in a row on the same side of 1 judge the
// calibration suspect.
//
// Thread: the tracking thread. configure() allocates the index arrays;
// nothing else allocates (the job buffers belong to the channel).
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/base/capacity.h"
#include "core/base/result.h"
#include "core/mapping/ba_channel.h"
#include "core/mapping/map.h"
#include "core/tracking/tracker.h"

namespace st {

class BaHandoff {
 public:
  Status configure(const TrackerConfig& config, const SE3& T_camera_model_init);
  void set_channel(BaChannel* channel) { channel_ = channel; }
  // A new run (Tracker::start()): nothing pending, the calibration test
  // restarts, jobs still out are not applied.
  void reset();

  // At the start of a frame, before anything uses the map: the solved job,
  // if any, into the map. True when one was applied.
  bool apply(TrackingMap* map);
  // The map was built anew from frame 0 (init_keyframe: its keyframe slot).
  void map_initialised(const TrackingMap& map, int init_keyframe);
  // What the frame's result asks for: a window job after a keyframe (and a
  // periodic global one while refining the registration), a global job
  // after a relocalisation, nothing for a fresh map.
  void frame_done(const TrackingMap& map, const TrackResult& r);
  // Hands out the pending job. False when nothing is pending, BA is off,
  // the map is not initialised, or the channel is busy.
  bool submit(const TrackingMap& map, bool initialised);

  const CalibrationCheck& calibration() const { return calibration_; }
  // The frame at which the calibration was first judged suspect.
  void note_frame(int frame_index);

 private:
  bool registration_free(const TrackingMap& map) const;
  void judge_calibration(const BaSummary& s);
  int add_job_keyframe(const TrackingMap& map, BaJob* job, int keyframe_id, bool fixed);
  void add_job_links(const TrackingMap& map, BaJob* job, int keyframe_id, int job_keyframe, bool add_points);
  void fill_job(const TrackingMap& map, BaJob* job, BaKind kind);

  TrackerConfig config_;
  SE3 T_init_;
  std::array<double, kMaxPyramidLevels> octave_info_{};  // per octave: 1 / sigma^2
  BaChannel* channel_ = nullptr;  // not owned
  static constexpr int kMaxFocalWaits = 3;  // window jobs a pending focal test lets go first
  bool window_pending_ = false, global_pending_ = false, focal_pending_ = false;
  int focal_waits_ = 0;  // window jobs handed out while the focal test was pending
  // Frame 0's keyframe (slot and stamp; -1: none) while it carries the
  // registration prior, and the keyframes since the last global job.
  int init_keyframe_ = -1, init_keyframe_frame_ = -1;
  int keyframes_since_global_ = 0;
  std::uint32_t version_ = 0;      // of the last job handed out (never reset)
  std::uint32_t min_version_ = 0;  // jobs below this came from before reset(): not applied
  int calibration_jobs_ = 0;       // focal-test jobs handed out
  CalibrationCheck calibration_;
  std::vector<std::int32_t> point_index_;     // per map point slot: its index in the job being filled
  std::vector<std::int32_t> keyframe_index_;  // per keyframe slot: likewise
  std::vector<std::int32_t> order_;           // keyframe slots, newest first
};

}  // namespace st
