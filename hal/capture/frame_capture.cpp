#include "hal/capture/frame_capture.h"

#include "platform/clock.h"

namespace st {

FrameCapture::~FrameCapture() { join(); }

Status FrameCapture::open(const std::filesystem::path& video, int ring_slots) {
  if (ring_slots < 2)
    return make_error("capture ring of " + std::to_string(ring_slots) + " slots: at least 2 are needed");
  if (Status s = reader_.open(video, ring_slots); !s) return s;
  ring_slots_ = static_cast<std::uint32_t>(reader_.ring_slots());
  released_.store(0, std::memory_order_relaxed);
  error_.reserve(512);
  return Status::Ok();
}

void FrameCapture::start(double pace_fps) {
  thread_ = std::thread([this, pace_fps] { run(pace_fps); });
}

void FrameCapture::release() {
  released_.fetch_add(1, std::memory_order_release);
  released_.notify_one();
}

void FrameCapture::join() {
  if (thread_.joinable()) thread_.join();
}

// Frame n reuses the slot of frame n - ring_slots: wait until that one is
// released. Never waits when the consumer keeps up.
void FrameCapture::wait_for_free_slot(std::uint32_t frame) {
  for (;;) {
    const std::uint32_t released = released_.load(std::memory_order_acquire);
    if (frame - released < ring_slots_) return;
    released_.wait(released, std::memory_order_acquire);
  }
}

void FrameCapture::run(double pace_fps) {
  const std::int64_t t0_ns = platform::monotonic_ns();
  for (std::uint32_t i = 0;; ++i) {
    wait_for_free_slot(i);
    CapturedFrame msg;
    const ReadResult r = reader_.read_frame(&msg.frame);
    if (r == ReadResult::kEndOfStream) {
      msg.kind = CapturedFrame::Kind::kEnd;
    } else if (r == ReadResult::kError) {
      error_.assign(reader_.error());  // capacity reserved at open (messages are < 512 bytes)
      msg.kind = CapturedFrame::Kind::kError;
    } else {
      msg.kind = CapturedFrame::Kind::kFrame;
      if (pace_fps > 0)
        platform::sleep_until_ns(t0_ns + static_cast<std::int64_t>(static_cast<double>(i) * 1e9 / pace_fps));
    }
    msg.t_handoff_ns = platform::monotonic_ns();
    // At most ring_slots frames plus this marker are ever queued: never full.
    queue_.push_wait(msg);
    if (msg.kind != CapturedFrame::Kind::kFrame) return;
  }
}

}  // namespace st
