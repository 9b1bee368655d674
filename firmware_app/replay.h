// Replay of a sequence's video through a per-frame processor (the tracker),
// on three threads: capture (hal/capture/frame_capture.h) -> tracking (the calling
// thread) -> writer (hal/storage/run_writer.h). Writes into the output folder
// trajectory.txt, frames.csv (streamed, flushed as rows come) and
// summary.json (docs/sequence-format.md "Tracker output"), also when the
// video breaks off: then summary.json covers the frames processed and
// carries an "error" field.
//
// Memory does not grow with the sequence: frames live in the capture ring,
// rows pass through fixed queues, latencies go into a fixed histogram. The
// tracking thread's heap allocations between FrameProcessor::start() and
// the end of the stream are counted and reported
// ("tracking_thread_allocations": 0 is the requirement).
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "core/image/image.h"
#include "core/base/latency_histogram.h"
#include "core/base/result.h"
#include "core/tracking/tracker.h"
#include "hal/storage/run_writer.h"
#include "hal/storage/sequence_loader.h"
#include "hal/capture/y4m_reader.h"

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

struct ReplayOptions {
  std::filesystem::path out_dir;
  bool realtime = false;   // pace frames to the sequence's fps; else as fast as possible
  bool progress = false;   // progress line on stderr (the caller checks isatty)
  int ring_slots = 6;      // capture ring: frames queued or in use at once
  FrameObserver* observer = nullptr;  // optional, called on the tracking thread
  // More numeric fields for summary.json (configuration, for the record).
  std::vector<std::pair<std::string, double>> summary_extra;
};

struct ReplayStats {
  int frames = 0;  // frames processed (rows in frames.csv)
  int tracked = 0, lost = 0, initialised = 0, relocalised = 0;  // tracked: frames with a pose
  int confirmed = 0;  // reported under the relaxed inlier ratio, confirmed by direct alignment
  double wall_s = 0, fps = 0;
  double mean_latency_ms = 0, p99_latency_ms = 0, max_latency_ms = 0;
  double peak_rss_mb = 0;
  std::int64_t tracking_thread_allocations = 0;
  int writer_stalls = 0;  // frames on which the tracking thread waited for the writer
  std::string error;      // empty: the whole video was processed and written
};

// Errors before the first frame (cannot open the video, cannot create the
// output) are returned as Error and nothing is tracked. Errors during the
// replay (truncated video, read or write error) end the replay: the result
// then holds the stats of what was processed and stats.error says what
// happened; summary.json is written either way.
Result<ReplayStats> run_replay(const LoadedSequence& sequence, FrameProcessor& processor,
                               const ReplayOptions& options);

// summary.json text for stats (fields of the spec + the replay's own).
std::string format_replay_summary(const ReplayStats& stats, const ReplayOptions& options);

// The tracker's state as frames.csv spells it (also used by live capture).
FrameState frame_state(TrackState s);

// One frame's result as the writer's row (the pose only when valid and
// finite), counted into stats (frames, tracked, lost, ...). Shared by the
// replay and the live camera loop; allocates nothing.
FrameRow record_frame(int frame, double timestamp_s, const TrackResult& r, double latency_ms,
                      ReplayStats* stats);

// After a run: wall time, fps, latency mean/p99/max from the histogram and
// the process's peak RSS into stats (frames already counted).
void fill_timing(const LatencyHistogram& latency, double wall_s, ReplayStats* stats);

// Frames in a Y4M file estimated from its size (0 for a pipe or unknown).
int estimate_frame_count(const LoadedSequence& sequence);

}  // namespace st
