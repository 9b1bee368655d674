#include "hal/capture/y4m_capture.h"

#include "platform/clock.h"

namespace st {

Y4mCapture::~Y4mCapture() { stop(); }

Status Y4mCapture::open(const std::filesystem::path& video, int ring_slots, double fps, double pace_fps) {
  if (ring_slots < 2)
    return make_error("capture ring of " + std::to_string(ring_slots) + " slots: at least 2 are needed");
  if (ring_slots > kMaxRingSlots)
    return make_error("capture ring of " + std::to_string(ring_slots) + " slots: at most " +
                      std::to_string(kMaxRingSlots));
  // One slot until start(): with a working size the ring is made at that
  // size, and a ring at the video's size allocated first would set the
  // peak of the resident memory however soon it is freed.
  if (Status s = reader_.open(video, 1); !s) return s;
  ring_slots_ = static_cast<std::uint32_t>(ring_slots);
  scaling_ = false;
  released_.store(0, std::memory_order_relaxed);
  stop_requested_.store(false, std::memory_order_relaxed);
  fps_ = fps > 0 ? fps : 0;
  pace_fps_ = pace_fps > 0 ? pace_fps : 0;
  error_.reserve(512);
  return Status::Ok();
}

Status Y4mCapture::set_working_size(int width, int height) {
  if (thread_.joinable()) return make_error("the Y4M capture's working size is set before it starts");
  const Y4mHeader& h = reader_.header();
  scaling_ = false;
  if (width == h.width && height == h.height) return Status::Ok();
  if (Status s = scaler_.configure(h.width, h.height, width, height); !s) return s;
  const auto slots = static_cast<std::size_t>(ring_slots_);
  work_y_.assign(slots, Image<std::uint8_t>(width, height));
  work_u_.assign(slots, Image<std::uint8_t>(FrameScaler::chroma_size(width), FrameScaler::chroma_size(height)));
  work_v_ = work_u_;  // (a mono video's frames have no chroma: these stay unused)
  // The frame at the video's size is needed only until it is scaled: the
  // reader keeps its one slot (1080p: 3.1 MB instead of 18.7 MB for 6
  // slots; 4K: 12.4 MB instead of 75).
  scaling_ = true;
  return Status::Ok();
}

// Frame number frame's working-size copy, into its ring slot's buffers.
void Y4mCapture::scale_to_working(std::uint32_t frame, FrameRef* f) {
  const std::size_t slot = frame % ring_slots_;
  bool chroma = false;
  scaler_.scale(f->y, f->u, f->v, work_y_[slot].view(), work_u_[slot].view(), work_v_[slot].view(), &chroma);
  f->y_work = work_y_[slot].cview();
  if (chroma) {
    f->u_work = work_u_[slot].cview();
    f->v_work = work_v_[slot].cview();
  }
  // The next read overwrites the reader's one slot: only the working size
  // is handed on.
  f->y = f->u = f->v = ImageView<const std::uint8_t>();
}

Status Y4mCapture::start() {
  if (thread_.joinable()) return make_error("the Y4M capture is already running");
  // Without a working size the frames are handed on from the reader's own
  // slots: the whole ring there.
  if (!scaling_ && reader_.ring_slots() != static_cast<int>(ring_slots_))
    if (Status s = reader_.set_ring_slots(static_cast<int>(ring_slots_)); !s) return s;
  thread_ = std::thread([this] { run(); });
  return Status::Ok();
}

void Y4mCapture::next(SourceFrame* out) {
  Message m;
  queue_.pop_wait(&m);
  out->kind = m.kind;
  out->frame = m.frame;
  out->t_ready_ns = m.t_handoff_ns;
  out->timestamp_s = fps_ > 0 ? m.frame.index / fps_ : 0.0;
}

void Y4mCapture::release() {
  released_.fetch_add(1, std::memory_order_release);
  released_.notify_one();
}

void Y4mCapture::stop() {
  if (!thread_.joinable()) return;
  stop_requested_.store(true, std::memory_order_release);
  released_.fetch_add(1, std::memory_order_release);  // wakes a wait for a free slot
  released_.notify_one();
  thread_.join();
}

// Frame n reuses the slot of frame n - ring_slots: wait until that one is
// released. Never waits when the consumer keeps up.
bool Y4mCapture::wait_for_free_slot(std::uint32_t frame) {
  for (;;) {
    if (stop_requested_.load(std::memory_order_acquire)) return false;
    const std::uint32_t released = released_.load(std::memory_order_acquire);
    if (frame - released < ring_slots_) return true;
    released_.wait(released, std::memory_order_acquire);
  }
}

void Y4mCapture::run() {
  const std::int64_t t0_ns = platform::monotonic_ns();
  for (std::uint32_t i = 0;; ++i) {
    Message msg;
    const bool go_on = wait_for_free_slot(i);
    const ReadResult r = go_on ? reader_.read_frame(&msg.frame) : ReadResult::kEndOfStream;
    if (r == ReadResult::kEndOfStream) {
      msg.kind = SourceFrame::Kind::kEnd;
    } else if (r == ReadResult::kError) {
      error_.assign(reader_.error());  // capacity reserved at open (messages are < 512 bytes)
      msg.kind = SourceFrame::Kind::kError;
    } else {
      msg.kind = SourceFrame::Kind::kFrame;
      if (scaling_) scale_to_working(i, &msg.frame);
      if (pace_fps_ > 0)
        platform::sleep_until_ns(t0_ns + static_cast<std::int64_t>(static_cast<double>(i) * 1e9 / pace_fps_));
    }
    msg.t_handoff_ns = platform::monotonic_ns();
    // At most ring_slots frames plus this marker are ever queued: never full.
    queue_.push_wait(msg);
    if (msg.kind != SourceFrame::Kind::kFrame) return;
  }
}

}  // namespace st
