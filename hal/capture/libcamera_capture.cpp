// libcamera capture (libcamera_capture.h). Built against libcamera when the
// build links PkgConfig::LIBCAMERA (hal/CMakeLists.txt), else as a
// stand-in whose every call says that libcamera is missing from the build.
// NOT RUN ON HARDWARE (no camera on the development machine).
#include "hal/capture/libcamera_capture.h"

#include <cstdlib>

#include "platform/clock.h"

#if __has_include(<libcamera/libcamera.h>)
#define ST_HAVE_LIBCAMERA 1
#include <sys/mman.h>

#include <algorithm>
#include <atomic>
#include <thread>

#include <libcamera/libcamera.h>

#include "platform/spsc_queue.h"
#else
#define ST_HAVE_LIBCAMERA 0
#endif

namespace st {

std::string describe_cameras(const CameraListing& listing) {
  const std::string lib = "libcamera " + listing.libcamera_version;
  if (listing.ids.empty()) return "no camera found (" + lib + " found 0 cameras)";
  std::string s = lib + " found " + std::to_string(listing.ids.size()) +
                  (listing.ids.size() == 1 ? " camera:" : " cameras:");
  for (const std::string& id : listing.ids) s += " '" + id + "'";
  return s;
}

#if ST_HAVE_LIBCAMERA
namespace lc = libcamera;

namespace {

// libcamera logs INFO lines to stderr by default; keep its errors only,
// unless the user chose levels (LIBCAMERA_LOG_LEVELS, read at first use).
std::unique_ptr<lc::CameraManager> start_manager(Status* status) {
  ::setenv("LIBCAMERA_LOG_LEVELS", "*:ERROR", 0);
  auto manager = std::make_unique<lc::CameraManager>();
  if (const int ret = manager->start(); ret < 0) {
    *status = make_error("libcamera " + libcamera_version() + ": the camera manager did not start (error " +
                         std::to_string(ret) + ")");
    return nullptr;
  }
  return manager;
}

CameraListing listing_of(const lc::CameraManager& manager) {
  CameraListing l;
  l.libcamera_version = libcamera_version();
  for (const auto& camera : manager.cameras()) l.ids.push_back(camera->id());
  return l;
}

// A completed request as the callback hands it off.
struct Completed {
  int slot = -1;  // -1: end of capture
  bool ok = false;
  std::uint32_t sequence = 0;
  std::int64_t t_sensor_ns = 0;
};

struct Mapping {
  void* addr = nullptr;
  std::size_t length = 0;
};

constexpr int kMaxSlots = 32;

}  // namespace

std::string libcamera_version() {
  std::string v = lc::CameraManager::version();
  if (!v.empty() && v.front() == 'v') v.erase(0, 1);
  return v;
}

Result<CameraListing> list_cameras() {
  Status s;
  auto manager = start_manager(&s);
  if (!manager) return Error{s.message()};
  CameraListing l = listing_of(*manager);
  manager->stop();
  return l;
}

struct LibcameraCapture::Impl {
  std::unique_ptr<lc::CameraManager> manager;
  std::shared_ptr<lc::Camera> camera;
  bool acquired = false, started = false, connected = false;
  std::unique_ptr<lc::CameraConfiguration> config;
  lc::Stream* stream = nullptr;
  std::unique_ptr<lc::FrameBufferAllocator> allocator;
  std::vector<std::unique_ptr<lc::Request>> requests;  // slot i has cookie i
  std::vector<RawFrame> raw;                           // slot i's planes in the mappings
  std::vector<Mapping> mappings;
  CapturePixelFormat format = CapturePixelFormat::kYuv420;
  Image<std::uint8_t> y, u, v;  // the planar frame next_frame() returns
  // libcamera's thread -> tracking thread (after stop(): the owner pushes the end).
  platform::SpscQueue<Completed, 2 * kMaxSlots> completed;
  // tracking thread -> re-queue thread (after the tracking thread ended: the owner).
  platform::SpscQueue<int, 2 * kMaxSlots> returned;
  std::thread requeue_thread;
  std::atomic<bool> stopping{false};
  bool end_pending = false;  // tracking thread: the end marker came while draining
  std::atomic<std::uint64_t> n_completed{0}, n_skipped{0}, n_failed{0};

  Status find_camera(const std::string& id);
  Status configure_stream(const CaptureOptions& o);
  Status map_buffers();
  Status make_requests();
  void on_request_completed(lc::Request* request);
  void requeue_loop();
  void give_back(int slot) { (void)returned.try_push(slot); }  // capacity > slots: never full
  void shutdown();
};

Status LibcameraCapture::Impl::find_camera(const std::string& id) {
  Status s;
  manager = start_manager(&s);
  if (!manager) return s;
  const CameraListing l = listing_of(*manager);
  if (l.ids.empty()) return make_error(describe_cameras(l));
  camera = manager->get(id);
  if (!camera) return make_error("camera '" + id + "' not found; " + describe_cameras(l));
  if (camera->acquire() < 0) return make_error("camera '" + id + "' is in use by another process");
  acquired = true;
  return Status::Ok();
}

// YUV420 first (the tracker's own layout), NV12 second; the size must be
// the calibration's exactly (a scaled or cropped stream would invalidate K).
Status LibcameraCapture::Impl::configure_stream(const CaptureOptions& o) {
  std::string tried;
  for (const auto& [pf, ours] : {std::pair{lc::formats::YUV420, CapturePixelFormat::kYuv420},
                                 std::pair{lc::formats::NV12, CapturePixelFormat::kNv12}}) {
    config = camera->generateConfiguration({lc::StreamRole::VideoRecording});
    if (!config || config->size() != 1) return make_error("camera '" + o.camera_id + "' offers no video stream");
    lc::StreamConfiguration& sc = config->at(0);
    sc.pixelFormat = pf;
    sc.size = lc::Size(static_cast<unsigned>(o.width), static_cast<unsigned>(o.height));
    sc.bufferCount = static_cast<unsigned>(o.ring_slots);
    const lc::CameraConfiguration::Status validity = config->validate();
    if (validity != lc::CameraConfiguration::Invalid && sc.pixelFormat == pf &&
        sc.size == lc::Size(static_cast<unsigned>(o.width), static_cast<unsigned>(o.height)) &&
        sc.bufferCount <= static_cast<unsigned>(kMaxSlots)) {
      if (camera->configure(config.get()) < 0) return make_error("camera '" + o.camera_id + "': configure failed");
      format = ours;
      stream = sc.stream();
      return Status::Ok();
    }
    tried += std::string(tried.empty() ? "" : "; ") + to_string(ours) + " -> " + sc.toString();
  }
  return make_error("camera '" + o.camera_id + "' cannot deliver YUV420 or NV12 at the calibration size " +
                    std::to_string(o.width) + "x" + std::to_string(o.height) + " (it offered: " + tried + ")");
}

// Maps every dmabuf once (planes of a buffer often share one fd at
// different offsets) and describes each buffer as a RawFrame. A buffer
// given as one plane holds the colour planes one after another.
Status LibcameraCapture::Impl::map_buffers() {
  const lc::StreamConfiguration& sc = config->at(0);
  const auto& buffers = allocator->buffers(stream);
  for (const auto& buffer : buffers) {
    const auto& planes = buffer->planes();
    RawFrame r;
    r.format = format;
    r.width = static_cast<int>(sc.size.width);
    r.height = static_cast<int>(sc.size.height);
    std::size_t fd_length = 0;
    for (const auto& p : planes) fd_length = std::max(fd_length, static_cast<std::size_t>(p.offset) + p.length);
    // One mapping per distinct fd; offsets index into it.
    std::vector<std::pair<int, const std::uint8_t*>> mapped;
    for (std::size_t i = 0; i < planes.size() && i < 3; ++i) {
      const int fd = planes[i].fd.get();
      const std::uint8_t* base = nullptr;
      for (const auto& [f, b] : mapped)
        if (f == fd) base = b;
      if (base == nullptr) {
        void* addr = ::mmap(nullptr, fd_length, PROT_READ, MAP_SHARED, fd, 0);
        if (addr == MAP_FAILED) return make_error("mmap of a camera buffer failed (" + std::to_string(fd_length) + " bytes)");
        mappings.push_back({addr, fd_length});
        base = static_cast<const std::uint8_t*>(addr);
        mapped.emplace_back(fd, base);
      }
      const std::size_t stride = i == 0 ? sc.stride : chroma_stride(format, sc.stride);
      r.planes[i] = {base + planes[i].offset, planes[i].length, stride};
    }
    if (planes.size() == 1) {  // contiguous planes in one: split by the strides
      const std::size_t y_size = static_cast<std::size_t>(sc.stride) * sc.size.height;
      const std::size_t c_stride = chroma_stride(format, sc.stride);
      const std::size_t c_size = c_stride * static_cast<std::size_t>(plane_rows(1, r.height));
      const std::uint8_t* base = r.planes[0].data;
      const std::size_t total = r.planes[0].size;
      r.planes[0].size = std::min(total, y_size);
      for (int p = 1; p < plane_count(format); ++p) {
        const std::size_t off = y_size + static_cast<std::size_t>(p - 1) * c_size;
        r.planes[static_cast<std::size_t>(p)] = {base + std::min(off, total), total > off ? total - off : 0, c_stride};
      }
    }
    if (Status s = check_raw_frame(r, {y.view(), u.view(), v.view()}); !s)
      return make_error("camera buffer layout not usable: " + s.message());
    raw.push_back(r);
  }
  return Status::Ok();
}

Status LibcameraCapture::Impl::make_requests() {
  const auto& buffers = allocator->buffers(stream);
  for (std::size_t i = 0; i < buffers.size(); ++i) {
    std::unique_ptr<lc::Request> request = camera->createRequest(i);
    if (!request) return make_error("libcamera could not create a request");
    if (request->addBuffer(stream, buffers[i].get()) < 0) return make_error("libcamera refused a buffer for a request");
    requests.push_back(std::move(request));
  }
  return Status::Ok();
}

// libcamera's thread. Hands off only: no conversion, no allocation.
void LibcameraCapture::Impl::on_request_completed(lc::Request* request) {
  if (request->status() == lc::Request::RequestCancelled) return;  // stop() in progress
  const lc::FrameBuffer* buffer = request->findBuffer(stream);
  Completed c;
  c.slot = static_cast<int>(request->cookie());
  c.ok = buffer != nullptr && buffer->metadata().status == lc::FrameMetadata::FrameSuccess;
  if (buffer != nullptr) {
    c.sequence = buffer->metadata().sequence;
    c.t_sensor_ns = static_cast<std::int64_t>(buffer->metadata().timestamp);
  }
  (void)completed.try_push(c);  // capacity > slots: never full
}

// The re-queue thread: hands returned buffers back to the camera.
void LibcameraCapture::Impl::requeue_loop() {
  for (;;) {
    int slot = -1;
    returned.pop_wait(&slot);
    if (slot < 0) return;
    if (stopping.load(std::memory_order_acquire)) continue;
    lc::Request* r = requests[static_cast<std::size_t>(slot)].get();
    r->reuse(lc::Request::ReuseBuffers);
    (void)camera->queueRequest(r);  // fails only while stopping
  }
}

void LibcameraCapture::Impl::shutdown() {
  if (started) {
    stopping.store(true, std::memory_order_release);
    camera->stop();
    started = false;
  }
  if (connected) {
    camera->requestCompleted.disconnect(this);
    connected = false;
  }
  if (requeue_thread.joinable()) {
    (void)returned.try_push(-1);
    requeue_thread.join();
  }
  requests.clear();
  for (const Mapping& m : mappings) ::munmap(m.addr, m.length);
  mappings.clear();
  if (allocator && stream) allocator->free(stream);
  allocator.reset();
  config.reset();
  if (acquired) camera->release();
  acquired = false;
  camera.reset();
  if (manager) manager->stop();
  manager.reset();
}

LibcameraCapture::LibcameraCapture() : impl_(std::make_unique<Impl>()) {}
LibcameraCapture::~LibcameraCapture() { impl_->shutdown(); }

Status LibcameraCapture::open(const CaptureOptions& o) {
  if (o.width <= 0 || o.height <= 0) return make_error("capture size must be positive");
  if (o.ring_slots < 2 || o.ring_slots > kMaxSlots)
    return make_error("capture ring must have 2.." + std::to_string(kMaxSlots) + " buffers");
  Impl& m = *impl_;
  if (Status s = m.find_camera(o.camera_id); !s) return s;
  if (Status s = m.configure_stream(o); !s) return s;
  m.y.allocate(o.width, o.height);
  m.u.allocate((o.width + 1) / 2, (o.height + 1) / 2);
  m.v.allocate((o.width + 1) / 2, (o.height + 1) / 2);
  m.allocator = std::make_unique<lc::FrameBufferAllocator>(m.camera);
  if (m.allocator->allocate(m.stream) < 2) return make_error("camera '" + o.camera_id + "': could not allocate 2+ buffers");
  if (Status s = m.map_buffers(); !s) return s;
  return m.make_requests();
}

CapturePixelFormat LibcameraCapture::pixel_format() const { return impl_->format; }

Status LibcameraCapture::start() {
  Impl& m = *impl_;
  if (m.requests.empty()) return make_error("capture not opened");
  m.camera->requestCompleted.connect(&m, &Impl::on_request_completed);
  m.connected = true;
  if (m.camera->start() < 0) return make_error("camera '" + m.camera->id() + "' did not start");
  m.started = true;
  m.requeue_thread = std::thread([&m] { m.requeue_loop(); });
  for (auto& r : m.requests)
    if (m.camera->queueRequest(r.get()) < 0) return make_error("camera '" + m.camera->id() + "' refused a request");
  return Status::Ok();
}

void LibcameraCapture::next_frame(LiveFrame* out) {
  Impl& m = *impl_;
  for (;;) {
    Completed c;
    if (m.end_pending) c.slot = -1;
    else m.completed.pop_wait(&c);
    // Latest wins: anything newer already waiting replaces c.
    for (Completed newer; c.slot >= 0 && !m.end_pending && m.completed.try_pop(&newer);) {
      if (newer.slot < 0) {
        m.end_pending = true;
        break;
      }
      m.give_back(c.slot);
      m.n_skipped.fetch_add(1, std::memory_order_relaxed);
      c = newer;
    }
    if (c.slot < 0) {
      m.end_pending = true;
      *out = LiveFrame{};
      return;
    }
    if (!c.ok) {  // a corrupt frame from the camera: count it and wait for the next
      m.n_failed.fetch_add(1, std::memory_order_relaxed);
      m.give_back(c.slot);
      continue;
    }
    const PlanarFrame planar{m.y.view(), m.u.view(), m.v.view()};
    const PixelStatus ps = convert_to_planar(m.raw[static_cast<std::size_t>(c.slot)], planar);
    m.give_back(c.slot);
    m.n_completed.fetch_add(1, std::memory_order_relaxed);
    out->kind = ps == PixelStatus::kOk ? LiveFrame::Kind::kFrame : LiveFrame::Kind::kError;
    out->pixel_status = ps;
    out->sequence = c.sequence;
    out->t_sensor_ns = c.t_sensor_ns;
    out->frame.index = static_cast<int>(m.n_completed.load(std::memory_order_relaxed) - 1);
    out->frame.y = m.y.cview();
    out->frame.u = m.u.cview();
    out->frame.v = m.v.cview();
    return;
  }
}

// After camera->stop() returns libcamera emits nothing more, so the owner
// may push the end marker as the completion queue's (new) only producer.
void LibcameraCapture::stop() {
  Impl& m = *impl_;
  if (!m.started) return;
  m.stopping.store(true, std::memory_order_release);
  m.camera->stop();
  m.started = false;
  m.camera->requestCompleted.disconnect(&m);
  m.connected = false;
  (void)m.completed.try_push(Completed{});
}

CaptureCounters LibcameraCapture::counters() const {
  return {impl_->n_completed.load(), impl_->n_skipped.load(), impl_->n_failed.load()};
}

#else  // built without libcamera

namespace {
Error missing() {
  return make_error("this scopetrack was built without libcamera (install libcamera-dev and re-run cmake)");
}
}  // namespace

std::string libcamera_version() { return "none"; }
Result<CameraListing> list_cameras() { return missing(); }
struct LibcameraCapture::Impl {};
LibcameraCapture::LibcameraCapture() : impl_(std::make_unique<Impl>()) {}
LibcameraCapture::~LibcameraCapture() = default;
Status LibcameraCapture::open(const CaptureOptions&) { return missing(); }
CapturePixelFormat LibcameraCapture::pixel_format() const { return CapturePixelFormat::kYuv420; }
Status LibcameraCapture::start() { return missing(); }
void LibcameraCapture::next_frame(LiveFrame* out) { *out = LiveFrame{}; }
void LibcameraCapture::stop() {}
CaptureCounters LibcameraCapture::counters() const { return {}; }

#endif

// Both builds: the frame source over next_frame().
void LibcameraCapture::next(SourceFrame* out) {
  LiveFrame in;
  next_frame(&in);
  out->kind = in.kind == LiveFrame::Kind::kFrame  ? SourceFrame::Kind::kFrame
              : in.kind == LiveFrame::Kind::kEnd ? SourceFrame::Kind::kEnd
                                                 : SourceFrame::Kind::kError;
  out->frame = in.frame;
  if (in.kind == LiveFrame::Kind::kError) error_status_ = in.pixel_status;
  if (in.kind != LiveFrame::Kind::kFrame) return;
  const std::int64_t now_ns = platform::monotonic_ns();
  const std::int64_t age_ns = now_ns - in.t_sensor_ns;
  out->t_ready_ns = age_ns >= 0 && age_ns < 1'000'000'000 ? in.t_sensor_ns : now_ns;
  if (t_first_sensor_ns_ < 0) t_first_sensor_ns_ = in.t_sensor_ns;
  out->timestamp_s = static_cast<double>(in.t_sensor_ns - t_first_sensor_ns_) * 1e-9;
}

std::string LibcameraCapture::error() const {
  return error_status_ == PixelStatus::kOk ? std::string("the camera stopped with an error")
                                           : std::string("camera buffer: ") + describe(error_status_);
}

}  // namespace st
