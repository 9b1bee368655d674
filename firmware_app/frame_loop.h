// The one frame loop of scopetrack, the same for a replayed sequence and a
// live camera: frames from a FrameSource (hal/capture/frame_source.h)
// through a FrameProcessor (the tracker with its mapping thread), each
// frame's row to the RunWriter (trajectory.txt, frames.csv), an optional
// observer (the console link), and counts an owner thread may read.
//
// Thread: run() on the tracking thread, from the processor's start() to its
// stop(). Between them it allocates nothing (counted: the result is
// RunStats::tracking_thread_allocations, 0 is the requirement). Memory does
// not grow with the run: rows pass through the writer's fixed queue,
// latencies go into a fixed histogram.
#pragma once

#include <array>
#include <atomic>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "core/base/latency_histogram.h"
#include "core/tracking/tracker.h"
#include "hal/capture/frame_source.h"
#include "hal/storage/run_writer.h"

namespace st {

// What the tracking thread runs. start(), step() and stop() are called on
// the tracking thread; step() must not allocate (it is counted). step()
// gets the whole frame: luma, and chroma unless the video is Cmono (the
// tracker's occluder mask uses it).
class FrameProcessor {
 public:
  virtual ~FrameProcessor() = default;
  virtual void start() = 0;
  virtual TrackResult step(const FrameRef& frame) = 0;
  virtual void stop() = 0;
  // After stop(), on the calling thread: more numeric fields for
  // summary.json (e.g. mean stage times). May allocate.
  virtual void append_summary(std::vector<std::pair<std::string, double>>* fields) const { (void)fields; }
};

// Sees every frame on the tracking thread right after the processor, while
// the frame's pixels are still valid (the console link: a POD pose into a
// queue, a frame copy for texturing). Must not allocate, block or log.
class FrameObserver {
 public:
  virtual ~FrameObserver() = default;
  virtual void frame_done(const FrameRef& frame, const TrackResult& result, double latency_ms) = 0;
  // After the last frame, on the calling thread, before summary.json is
  // written: finish the observer's work (may wait, may allocate) and add
  // numeric fields to the summary.
  virtual void finish(std::vector<std::pair<std::string, double>>* summary_fields) { (void)summary_fields; }
};

struct RunStats {
  int frames = 0;  // frames processed (rows in frames.csv)
  int tracked = 0, lost = 0, initialised = 0, relocalised = 0;  // tracked: frames with a pose
  int confirmed = 0;  // reported under the relaxed inlier ratio, confirmed by direct alignment
  int by_outline = 0;  // reported from the outline and the shading (no feature pose)
  // Frames without a feature pose on which the outline and the shading were
  // tried, by verdict (core/tracking/modality_agreement.h), kAgree first.
  std::array<int, 5> outline_verdicts{};
  int outline_vetoes = 0;  // feature poses the outline refused (TrackResult::outline_vetoed)
  // Lost frames whose organ silhouette was searched from every side, and
  // those on which a candidate's outline fit placed the organ
  // (TrackResult::outline_searched, outline_search_found).
  int outline_searches = 0, outline_search_fits = 0;
  double wall_s = 0, fps = 0;
  double mean_latency_ms = 0, p99_latency_ms = 0, max_latency_ms = 0;
  double peak_rss_mb = 0;
  std::int64_t tracking_thread_allocations = 0;
  int writer_stalls = 0;  // frames on which the tracking thread waited for the writer
  // The capture's faults, as the frames' numbers and times show them (the
  // frames are tracked all the same; the tracker's state stays its own):
  int dropped_frames = 0;    // frames missing from the numbering (a jump of k counts k - 1)
  int timestamp_faults = 0;  // frames whose time is not after the previous frame's
  int stop_signal = 0;       // the signal that ended the run early (FrameLoop::stop_signal), else 0
  std::string error;         // empty: the whole stream was processed and written
};

// What an owner thread reads while the loop runs (a live status line).
struct LoopStatus {
  std::atomic<int> frames{0}, tracked{0}, lost{0};
  std::atomic<int> last_state{static_cast<int>(FrameState::kLost)};
  std::atomic<bool> calibration_suspect{false};  // TrackerConfig::check_calibration's verdict
  std::atomic<bool> done{false};                 // run() returned
};

// The tracking thread's state: everything it touches per frame, set up by
// the owner before run().
struct FrameLoop {
  FrameSource* source = nullptr;
  FrameProcessor* processor = nullptr;
  RunWriter* writer = nullptr;        // optional: rows to trajectory.txt / frames.csv
  FrameObserver* observer = nullptr;  // optional
  LoopStatus* status = nullptr;       // optional
  // Optional: set (to a signal number) by another thread to end the run
  // after the current frame, as if the stream had ended; the number goes to
  // stats.stop_signal.
  const std::atomic<int>* stop_signal = nullptr;
  LatencyHistogram latency;
  RunStats stats;
  bool source_error = false;  // the source ended with kError (its error() says why)

  // The processor's start(), every frame to the end of the stream or a
  // source error, the processor's stop(). Fills stats (frames, states,
  // wall time, allocations); the caller adds the error.
  void run();
  // After run(), on the owner thread: fps and latency mean/p99/max from the
  // histogram and wall time, and the process's peak RSS, into stats.
  void fill_timing();
};

// The tracker's state as frames.csv spells it.
FrameState frame_state(TrackState s);

// summary.json text for stats (the fields of docs/sequence-format.md, the
// run's own, then extra), with "error" last when the run broke off.
std::string format_run_summary(const RunStats& stats, bool realtime,
                               const std::vector<std::pair<std::string, double>>& extra);

}  // namespace st
