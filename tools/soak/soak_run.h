// scopetrack-soak's work: one scopetrack process tracks a long sequence
// joined from simulated segments of every scenario (the organ leaving and
// coming back, smoke, instruments, fast swings; each join a restart of the
// scope's view), fed through a FIFO, with a console attached that
// disconnects and reconnects every few thousand frames. RSS and the map's
// pools are sampled every 1,000 frames; the run fails when RSS grows by
// more than 1 MB after the first 5,000 frames, the map-point pool stays
// full (the keyframe pool is a ring: full is its steady state), the
// tracking thread allocated, the console saw a bad message, or the lost
// fraction or the TRE drifts up from the first to the last quarter (a
// frame count of 4 x segments x segment frames makes the quarters whole
// passes). Host tool: allocates freely.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/base/result.h"

namespace st::soak {

struct SoakOptions {
  std::filesystem::path out_dir;
  int frames = 100000;
  int width = 640, height = 360;
  int segment_frames = 500;  // frames of each simulated segment
  std::uint64_t seed = 1;
  int reconnect_every = 3000;  // the console's poses per connection
  int ba_lag = 0;              // scopetrack --ba-lag N (0: live, as on the tower; N: a repeatable run)
  std::filesystem::path bin_dir;  // where scopetrack is
  bool progress = false;
};

struct SoakSample {
  int frames = 0;           // rows of frames.csv when sampled
  double rss_mb = 0;        // scopetrack's resident set
  double lost_pct = 0;      // over the 1,000 frames before the sample
  int map_points = 0, keyframes = 0;
};

struct QuarterResult {
  double lost_pct = 0, tre_median_px = 0;
  int wrong_frames = 0;
};

struct SoakResult {
  std::vector<SoakSample> samples;  // every 1,000 frames up to 1,000 before the end
  int frames = 0;  // rows of frames.csv: the frames the tracker processed
  QuarterResult quarters[4];
  double rss_baseline_mb = 0, rss_max_after_mb = 0;  // at 5,000 frames; the largest after
  int max_map_points = 0, max_keyframes = 0;         // the pools' capacities (summary.json)
  double map_full_pct = 0, keyframes_full_pct = 0;   // samples with the pool full
  std::int64_t tracking_thread_allocations = -1;
  double fps = 0, wall_s = 0;
  int console_connections = 0;
  std::int64_t console_poses = 0, console_rejected = 0;
  int exit_status = -1;
  std::vector<std::string> failures;  // empty: the soak passed
};

Result<SoakResult> run_soak(const SoakOptions& options);

// soak.csv and the report's text.
std::string format_samples_csv(const SoakResult& r);
std::string format_report(const SoakResult& r);
// A PNG plot of the samples (RSS, lost fraction, pool fill against frames).
Status write_plot(const SoakResult& r, const std::filesystem::path& png);

}  // namespace st::soak
