// The mapping thread: solves the tracker's bundle-adjustment jobs
// (core/mapping/bundle_adjustment.h) off the tracking thread. Implements
// core/mapping/ba_channel.h with one job buffer and a fixed-capacity SPSC queue of
// job slots (platform/spsc_queue.h): while the buffer is away the tracker
// gets nullptr from acquire_job() and defers its job; the solved job comes
// back through an atomic state the tracker reads at the start of a frame
// (no lock, nothing held across a frame). With TrackerConfig::ba_lag_frames
// N > 0 (deterministic replays) the job comes back exactly N frames after
// it was handed over (a focal-test job, which writes nothing into the map,
// at the next frame: handed over at the end of a frame, it is back at the
// start of the next, before any window could wait for it): solved_job()
// then waits for the solve, the one place the tracking thread may block,
// and solves are bounded by iterations only.
//
// Threads: configure() on the owner (allocates the job buffer, the BA
// pools and the closest-point index); start()/stop() on the tracking
// thread (start spawns the mapping thread, stop joins it); the BaChannel
// calls on the tracking thread (allocate nothing, never block); solving
// on the mapping thread (Ceres allocates there, bounded by the job size;
// counted per solve in stats()). The mapping thread lowers its own priority
// (platform::kBackgroundWorkerNice) so that, on a shared core, it takes the
// time the tracking thread leaves instead of delaying frames.
#pragma once

#include <atomic>
#include <cstdint>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "core/mapping/ba_channel.h"
#include "core/mapping/bundle_adjustment.h"
#include "core/base/latency_histogram.h"
#include "core/tracking/tracker.h"
#include "platform/spsc_queue.h"

namespace st::app {

struct MappingStats {
  int window_solves = 0, global_solves = 0, focal_tests = 0, unusable = 0;
  double solve_median_ms = 0, solve_p99_ms = 0, solve_max_ms = 0;  // wall time of solve()
  std::uint64_t max_allocations_per_solve = 0;  // mapping thread, inside solve()
  std::uint64_t thread_allocations = 0;         // mapping thread, from its start to its last job
  double mean_surface_distance_mm = -1;         // of the last usable job's points after the solve
  double mean_window_observations = 0;          // reprojection residuals per window solve
  double mean_window_fixed_observations = 0;    // of those: from fixed keyframes
  int thread_nice = -1;                         // the mapping thread's nice value (-1: never ran)
  // The registration prior (TrackerConfig::registration_sigma_deg): jobs
  // that tested it, how many of those freed frame 0's pose, and for the
  // last that did, frame 0's pose against T_camera_model_init (rotation,
  // camera centre) and the test's F.
  int registration_tests = 0, registration_releases = 0;
  double registration_shift_deg = 0, registration_shift_mm = 0, registration_f = 0;
};

class MappingWorker final : public BaChannel {
 public:
  MappingWorker() = default;
  ~MappingWorker() override { stop(); }
  MappingWorker(const MappingWorker&) = delete;
  MappingWorker& operator=(const MappingWorker&) = delete;

  // Sizes the job for the tracker's pools and configures the adjuster.
  Status configure(const TrackerConfig& config, const Mesh& mesh, const Pinhole& K);
  void start();
  void stop();  // finishes the solve in progress, then joins

  BaJob* acquire_job() override;
  void submit_job(BaJob* job) override;
  const BaJob* solved_job() override;
  void release_job(const BaJob* job) override;

  // After stop().
  MappingStats stats() const;
  void append_summary(std::vector<std::pair<std::string, double>>* fields) const;

 private:
  enum State : int { kFree, kQueued, kSolved };
  void run();
  void solve_one();

  TrackerConfig config_;
  BundleAdjuster adjuster_;
  BaJob job_;
  std::atomic<int> state_{kFree};
  int frames_out_ = 0;  // solved_job() calls since the job was handed over (ba_lag_frames)
  platform::SpscQueue<std::int32_t, 2> queue_;  // job slot, or -1: stop
  std::thread thread_;
  bool configured_ = false;
  // Written by the mapping thread only; read after stop().
  MappingStats stats_;
  LatencyHistogram solve_ms_;
  std::int64_t window_observations_ = 0, window_fixed_observations_ = 0;
};

}  // namespace st::app
