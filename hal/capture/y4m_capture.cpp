#include "hal/capture/y4m_capture.h"

#include <algorithm>
#include <cstring>

#include "platform/clock.h"

namespace st {

Y4mCapture::~Y4mCapture() { stop(); }

Status Y4mCapture::open(const std::filesystem::path& video, int ring_slots, double fps, double pace_fps) {
  if (ring_slots < 2)
    return make_error("capture ring of " + std::to_string(ring_slots) + " slots: at least 2 are needed");
  if (ring_slots > kMaxRingSlots)
    return make_error("capture ring of " + std::to_string(ring_slots) + " slots: at most " +
                      std::to_string(kMaxRingSlots));
  // No slot until start(): with a working size the frames are read in
  // bands and no frame at the video's size is ever held, and a ring at
  // the video's size allocated first would set the peak of the resident
  // memory however soon it is freed.
  if (Status s = reader_.open(video, 0); !s) return s;
  ring_slots_ = static_cast<std::uint32_t>(ring_slots);
  scaling_ = scale_failed_ = false;
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
  // The frame at the video's size is never whole: it is read kBandRows
  // rows at a time into one band (plus the rows an output row straddling
  // two bands needs), each band scaled as it arrives (to 1280x720: 67 KB
  // from 1080p instead of a 3.1 MB frame, 138 KB from 4K instead of 12.4 MB).
  const auto band_bytes = [](const AreaScaler& a) {
    return static_cast<std::size_t>(a.in_width()) * static_cast<std::size_t>(kBandRows + a.max_rows_per_output());
  };
  band_.assign(std::max(band_bytes(scaler_.luma()), band_bytes(scaler_.chroma())), 0);
  scaling_ = true;
  return Status::Ok();
}

// One plane of the frame being read, from the reader in bands into out.
// Each band's output rows are made as soon as the rows they read are in;
// the rows the next output row still needs move to the band's top.
ReadResult Y4mCapture::read_plane_scaled(AreaScaler& scaler, ImageView<std::uint8_t> out) {
  const int w = scaler.in_width(), h = scaler.in_height(), out_h = scaler.out_height();
  const auto stride = static_cast<std::size_t>(w);
  const int capacity = static_cast<int>(band_.size() / stride);
  std::uint8_t* band = band_.data();
  int band_y0 = 0, held = 0, next_row = 0, j = 0;  // band rows: input rows [band_y0, band_y0 + held)
  while (next_row < h) {
    const int n = std::min(capacity - held, h - next_row);
    const ReadResult r = reader_.read_frame_data(band + static_cast<std::size_t>(held) * stride,
                                                 static_cast<std::size_t>(n) * stride);
    if (r != ReadResult::kFrame) return r;
    held += n;
    next_row += n;
    int j_end = j;
    while (j_end < out_h && scaler.input_row_end(j_end) <= next_row) ++j_end;
    if (!scaler.scale_rows(GrayView(band, w, held), band_y0, j, j_end, out)) {
      scale_failed_ = true;  // a band without the rows its output needs: not expected
      return ReadResult::kError;
    }
    j = j_end;
    const int keep = j < out_h ? scaler.input_row_begin(j) : next_row;
    held = next_row - keep;
    if (held > 0)
      std::memmove(band, band + static_cast<std::size_t>(keep - band_y0) * stride,
                   static_cast<std::size_t>(held) * stride);
    band_y0 = keep;
  }
  return ReadResult::kFrame;
}

// The next frame at the working size, into ring slot frame % ring_slots_.
ReadResult Y4mCapture::read_scaled(std::uint32_t frame, FrameRef* f) {
  int index = 0;
  if (const ReadResult r = reader_.begin_frame(&index); r != ReadResult::kFrame) return r;
  const std::size_t slot = frame % ring_slots_;
  if (const ReadResult r = read_plane_scaled(scaler_.luma(), work_y_[slot].view()); r != ReadResult::kFrame)
    return r;
  *f = FrameRef{};
  f->index = index;
  f->y_work = work_y_[slot].cview();
  if (reader_.header().chroma == Chroma::kMono) return ReadResult::kFrame;
  if (const ReadResult r = read_plane_scaled(scaler_.chroma(), work_u_[slot].view()); r != ReadResult::kFrame)
    return r;
  if (const ReadResult r = read_plane_scaled(scaler_.chroma(), work_v_[slot].view()); r != ReadResult::kFrame)
    return r;
  f->u_work = work_u_[slot].cview();
  f->v_work = work_v_[slot].cview();
  return ReadResult::kFrame;
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
    const ReadResult r = !go_on    ? ReadResult::kEndOfStream
                         : scaling_ ? read_scaled(i, &msg.frame)
                                    : reader_.read_frame(&msg.frame);
    if (r == ReadResult::kEndOfStream) {
      msg.kind = SourceFrame::Kind::kEnd;
    } else if (r == ReadResult::kError) {
      // Capacity reserved at open (messages are < 512 bytes).
      error_.assign(scale_failed_ ? "Y4M capture: a band of the frame could not be scaled to the working size"
                                  : reader_.error().c_str());
      msg.kind = SourceFrame::Kind::kError;
    } else {
      msg.kind = SourceFrame::Kind::kFrame;
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
