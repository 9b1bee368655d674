#include "firmware_app/texture_worker.h"

#include <cstring>

#include "platform/alloc_counter.h"
#include "platform/realtime.h"

namespace st::app {

namespace {

// Copies a plane row by row into an owned image of the same size.
void copy_plane(GrayView src, Image<std::uint8_t>* dst) {
  for (int y = 0; y < src.height; ++y)
    std::memcpy(dst->data() + static_cast<std::ptrdiff_t>(y) * dst->width(), src.row(y),
                static_cast<std::size_t>(src.width));
}

}  // namespace

TextureWorker::~TextureWorker() { stop(); }

Status TextureWorker::configure(const Mesh& mesh, const CameraModel& camera,
                                const TextureConfig& config, int slots, StreamSink* sink) {
  if (thread_.joinable()) return make_error("texture worker: configure() while running");
  if (slots < 1 || slots > kMaxSlots)
    return make_error("texture worker: slots must be 1.." + std::to_string(kMaxSlots));
  if (Status s = texture_.configure(mesh, camera, config); !s) return s;
  sink_ = sink;
  slots_ = std::vector<Slot>(static_cast<std::size_t>(slots));
  const int cw = (config.width + 1) / 2, ch = (config.height + 1) / 2;
  for (int i = 0; i < slots; ++i) {
    Slot& s = slots_[static_cast<std::size_t>(i)];
    s.y.allocate(config.width, config.height);
    s.u.allocate(cw, ch);
    s.v.allocate(cw, ch);
    if (!free_.try_push(i)) return make_error("texture worker: free-slot queue too small");
  }
  return Status::Ok();
}

void TextureWorker::start() {
  if (!thread_.joinable() && !slots_.empty()) thread_ = std::thread([this] { run(); });
}

bool TextureWorker::try_submit(const FrameRef& frame, const SE3& T_camera_model) {
  const TextureConfig& c = texture_.config();
  // The frame at the working size when the source made one (the camera
  // given to configure() must be that size's).
  const bool work = !frame.y_work.empty();
  const GrayView y = work ? frame.y_work : frame.y, u = work ? frame.u_work : frame.u, v = work ? frame.v_work : frame.v;
  if (!thread_.joinable() || y.width != c.width || y.height != c.height) return false;
  int i = -1;
  if (!free_.try_pop(&i)) return false;
  Slot& s = slots_[static_cast<std::size_t>(i)];
  copy_plane(y, &s.y);
  s.mono = u.empty() || v.empty();
  if (!s.mono) {
    copy_plane(u, &s.u);
    copy_plane(v, &s.v);
  }
  s.T_camera_model = T_camera_model;
  work_.try_push(i);  // cannot fail: at most slots_.size() (< capacity) indices circulate
  return true;
}

void TextureWorker::stop() {
  if (!thread_.joinable()) return;
  work_.push_wait(-1);
  thread_.join();
}

void TextureWorker::run() {
  thread_nice_.store(platform::become_background_thread());  // allocates: before the count
  const std::uint64_t allocs0 = platform::thread_allocation_count();
  for (;;) {
    int i = -1;
    work_.pop_wait(&i);
    if (i < 0) break;
    Slot& s = slots_[static_cast<std::size_t>(i)];
    YuvFrameView f{s.y.cview(), s.mono ? GrayView{} : s.u.cview(),
                   s.mono ? GrayView{} : s.v.cview()};
    const int changed = texture_.add_frame(f, s.T_camera_model);
    free_.try_push(i);
    if (sink_ && changed > 0) sink_->push_colours(texture_.changed());
    textured_.fetch_add(1);
    colours_.fetch_add(changed);
    worker_allocs_.store(static_cast<std::int64_t>(platform::thread_allocation_count() - allocs0));
  }
}

}  // namespace st::app
