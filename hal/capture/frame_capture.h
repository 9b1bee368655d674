// Capture thread of a replay: reads Y4M frames (file, FIFO or pipe) into the
// reader's fixed ring and hands them to the tracking thread through a
// fixed-capacity SPSC queue. Back-pressure instead of dropping: the thread
// reads frame i only once frame i - ring_slots has been released, so a
// frame's pixels stay valid from pop() until release(). With pacing
// (fps > 0), frame i is handed over at start + i / fps, like a camera.
//
// Threads: open()/start()/join() on the owner; pop_wait()/release() on the
// one consumer (the tracking thread), which allocate nothing and never touch
// the file. The capture thread allocates nothing after open().
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <string>
#include <thread>

#include "hal/capture/y4m_reader.h"
#include "platform/spsc_queue.h"

namespace st {

struct CapturedFrame {
  enum class Kind : std::uint8_t { kFrame, kEnd, kError };
  Kind kind = Kind::kEnd;
  FrameRef frame;                 // valid for kFrame until release()
  std::int64_t t_handoff_ns = 0;  // monotonic time the frame entered the queue
};

class FrameCapture {
 public:
  FrameCapture() = default;
  ~FrameCapture();
  FrameCapture(const FrameCapture&) = delete;
  FrameCapture& operator=(const FrameCapture&) = delete;

  // Opens the video and reads its header (blocks on a FIFO until a writer
  // comes). ring_slots >= 2: frames that may be queued or in use at once.
  Status open(const std::filesystem::path& video, int ring_slots);
  const Y4mHeader& header() const { return reader_.header(); }

  // Spawns the capture thread. pace_fps > 0: hand frame i over no earlier
  // than start + i / pace_fps.
  void start(double pace_fps);
  // Consumer: the next frame, or the end of the stream (kEnd), or a read
  // error (kError: error() says which frame and why). Waits only while the
  // capture thread is still reading.
  void pop_wait(CapturedFrame* out) { queue_.pop_wait(out); }
  // Consumer: the oldest popped frame is no longer used.
  void release();
  // Waits for the capture thread to finish (after kEnd/kError was popped).
  void join();
  // Valid after kError was popped.
  const std::string& error() const { return error_; }
  int frames_read() const { return reader_.frames_read(); }

 private:
  void run(double pace_fps);
  void wait_for_free_slot(std::uint32_t frame);

  static constexpr std::size_t kQueueCapacity = 128;  // > kMaxRingSlots + the end marker
  Y4mReader reader_;
  platform::SpscQueue<CapturedFrame, kQueueCapacity> queue_;
  std::atomic<std::uint32_t> released_{0};  // frames the consumer is done with
  std::uint32_t ring_slots_ = 0;
  std::string error_;  // written by the capture thread before it queues kError
  std::thread thread_;
};

}  // namespace st
