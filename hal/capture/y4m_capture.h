// The Y4M file, FIFO or pipe as a frame source (hal/capture/frame_source.h):
// a capture thread reads frames into the reader's fixed ring and hands them
// to the tracking thread through a fixed-capacity SPSC queue.
// Back-pressure instead of dropping: the thread reads frame i only once
// frame i - ring_slots has been released, so a frame's pixels stay valid
// from next() until release(). With pacing (pace_fps > 0), frame i is
// handed over at start + i / pace_fps, like a camera.
//
// With set_working_size(), the capture thread brings each frame to the
// tracker's working size (core/image/area_scale.h) into a ring of working
// buffers and hands on that frame alone (FrameRef::y_work etc.; y, u and v
// empty): the frame at the video's size is read a band of rows at a time
// and each band scaled as it arrives, so the memory the capture takes
// follows the working size, not the video's (the texture thread takes the
// working frame too).
//
// Threads: open()/set_working_size()/start()/stop() on the owner (start()
// allocates the ring at the video's size when no working size was set);
// next()/release() on the one consumer (the tracking thread), which
// allocate nothing and never touch the file. The capture thread allocates
// nothing after open() and set_working_size().
#pragma once

#include <atomic>
#include <cstdint>
#include <filesystem>
#include <string>
#include <thread>
#include <vector>

#include "core/image/area_scale.h"
#include "hal/capture/frame_source.h"
#include "hal/capture/y4m_reader.h"
#include "platform/spsc_queue.h"

namespace st {

class Y4mCapture final : public FrameSource {
 public:
  Y4mCapture() = default;
  ~Y4mCapture() override;
  Y4mCapture(const Y4mCapture&) = delete;
  Y4mCapture& operator=(const Y4mCapture&) = delete;

  // Opens the video and reads its header (blocks on a FIFO until a writer
  // comes). ring_slots >= 2: frames that may be queued or in use at once.
  // fps: the stream's rate, for the frames' timestamps (0: unknown, all 0).
  // pace_fps > 0: hand frame i over no earlier than start + i / pace_fps.
  Status open(const std::filesystem::path& video, int ring_slots, double fps, double pace_fps);
  // After open(), before start(): frames also at width x height (at most
  // the video's size; the video's own size: nothing is made). Allocates
  // the ring's working buffers.
  Status set_working_size(int width, int height);
  const Y4mHeader& header() const { return reader_.header(); }
  int frames_read() const { return reader_.frames_read(); }

  // FrameSource. stop() waits for the capture thread, which ends at the end
  // of the stream or an error; a stop before then ends it before its next
  // read (a read blocked on a FIFO finishes first).
  Status start() override;
  void next(SourceFrame* out) override;
  void release() override;
  void stop() override;
  bool paced() const override { return pace_fps_ > 0; }
  std::string error() const override { return error_; }

 private:
  struct Message {
    SourceFrame::Kind kind = SourceFrame::Kind::kEnd;
    FrameRef frame;
    std::int64_t t_handoff_ns = 0;
  };
  void run();
  ReadResult read_scaled(std::uint32_t frame, FrameRef* f);
  ReadResult read_plane_scaled(AreaScaler& scaler, ImageView<std::uint8_t> out);
  bool wait_for_free_slot(std::uint32_t frame);  // false: stop() was asked

  static constexpr std::size_t kQueueCapacity = 128;  // > kMaxRingSlots + the end marker
  Y4mReader reader_;
  platform::SpscQueue<Message, kQueueCapacity> queue_;
  std::atomic<std::uint32_t> released_{0};  // frames the consumer is done with
  std::atomic<bool> stop_requested_{false};
  std::uint32_t ring_slots_ = 0;
  double fps_ = 0, pace_fps_ = 0;
  std::string error_;  // written by the capture thread before it queues kError
  std::thread thread_;
  // The working size's scalers (capture thread) and one frame per ring slot.
  bool scaling_ = false;
  FrameScaler scaler_;
  std::vector<Image<std::uint8_t>> work_y_, work_u_, work_v_;
  static constexpr int kBandRows = 32;  // input rows read and scaled at a time
  std::vector<std::uint8_t> band_;      // rows of the plane being read (the video's width)
  bool scale_failed_ = false;
};

}  // namespace st
