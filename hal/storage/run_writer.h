// Writer thread of a replay: streams trajectory.txt (TUM, frames with a
// pose) and frames.csv (every frame) row by row as the tracking thread
// produces them, flushing whenever it has caught up, so whatever happens
// later (a truncated video, a kill) the rows written so far are on disk.
// Memory is fixed: rows pass through a fixed-capacity SPSC queue and are
// formatted one at a time. Optionally prints a progress line (a terminal).
//
// Threads: open()/start()/finish() on the owner; push() on the one
// producer (the tracking thread), which allocates nothing and waits only if
// the queue is full (counted as a stall). The writer thread allocates
// freely (formatting), off the real-time path.
#pragma once

#include <atomic>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>
#include <thread>

#include "core/base/result.h"
#include "core/geometry/se3.h"
#include "core/formats/trajectory.h"
#include "platform/spsc_queue.h"

namespace st {

struct FrameRow {
  FrameRecord record;
  bool pose_valid = false;
  SE3 T_model_camera;  // valid when pose_valid
  bool end = false;    // marker: no rows follow
};

struct ProgressOptions {
  bool enabled = false;       // print a progress line to stderr
  int expected_frames = 0;    // 0: unknown (a pipe)
  double interval_s = 0.25;   // between updates
};

class RunWriter {
 public:
  static constexpr std::size_t kQueueCapacity = 1024;

  RunWriter() = default;
  ~RunWriter();
  RunWriter(const RunWriter&) = delete;
  RunWriter& operator=(const RunWriter&) = delete;

  // Creates out_dir and the two files (with the frames.csv header).
  Status open(const std::filesystem::path& out_dir);
  void start(const ProgressOptions& progress);
  // Producer (tracking thread). Returns true when the queue was full and it
  // had to wait for the writer.
  bool push(const FrameRow& row) { return queue_.push_wait(row); }
  // Owner: queues the end marker, waits for the thread, closes the files.
  // The first write error, if any.
  Status finish();

  std::int64_t rows_written() const { return rows_written_.load(std::memory_order_relaxed); }

 private:
  void run(ProgressOptions progress);
  void write_row(const FrameRow& row);
  void flush();
  void print_progress(const ProgressOptions& p, bool final_line);
  void close_files();

  platform::SpscQueue<FrameRow, kQueueCapacity> queue_;
  std::FILE* trajectory_ = nullptr;
  std::FILE* frames_ = nullptr;
  std::filesystem::path out_dir_;
  std::string write_error_;  // first error; read by finish() after the join
  std::atomic<std::int64_t> rows_written_{0};
  // Progress (writer thread only).
  int counts_[4] = {0, 0, 0, 0};  // by FrameState
  std::int64_t t_start_ns_ = 0, t_last_print_ns_ = 0;
  std::thread thread_;
};

}  // namespace st
