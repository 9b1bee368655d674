// Replay of a sequence's video through a frame processor (the tracker):
// the Y4M capture (hal/capture/y4m_capture.h, its own thread) -> the frame
// loop (firmware_app/frame_loop.h, on the calling thread) -> the writer
// (hal/storage/run_writer.h, its own thread). Writes into the output folder
// trajectory.txt, frames.csv (streamed, flushed as rows come) and
// summary.json (docs/sequence-format.md "Tracker output"), also when the
// video breaks off: then summary.json covers the frames processed and
// carries an "error" field.
#pragma once

#include <atomic>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "core/base/result.h"
#include "firmware_app/frame_loop.h"
#include "hal/storage/sequence_loader.h"

namespace st {

struct ReplayOptions {
  std::filesystem::path out_dir;
  bool realtime = false;   // pace frames to the sequence's fps; else as fast as possible
  bool progress = false;   // progress line on stderr (the caller checks isatty)
  int ring_slots = 4;      // capture ring: frames queued or in use at once
  // The tracker's working size (TrackerProcessor::working_pinhole): when
  // smaller than the video's, the capture thread makes each frame at it
  // too (FrameRef::y_work). 0: not made.
  int working_width = 0, working_height = 0;
  FrameObserver* observer = nullptr;  // optional, called on the tracking thread
  // Optional: set to a signal number by another thread to end the replay
  // after the current frame (FrameLoop::stop_signal); what was tracked is
  // written and summary.json says "stop_signal".
  const std::atomic<int>* stop_signal = nullptr;
  // More numeric fields for summary.json (configuration, for the record).
  std::vector<std::pair<std::string, double>> summary_extra;
};

// Errors before the first frame (cannot open the video, cannot create the
// output) are returned as Error and nothing is tracked. Errors during the
// replay (truncated video, read or write error) end the replay: the result
// then holds the stats of what was processed and stats.error says what
// happened; summary.json is written either way.
Result<RunStats> run_replay(const LoadedSequence& sequence, FrameProcessor& processor,
                            const ReplayOptions& options);

// Frames in a Y4M file estimated from its size (0 for a pipe or unknown).
int estimate_frame_count(const LoadedSequence& sequence);

}  // namespace st
