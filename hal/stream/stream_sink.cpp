#include "hal/stream/stream_sink.h"

#include <poll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <bit>
#include <cerrno>
#include <cstring>

#include "core/base/capacity.h"
#include "platform/alloc_counter.h"
#include "platform/clock.h"

namespace st {

namespace {
constexpr std::uint32_t kColouredBit = 1u << 24;
constexpr int kMaxPollFds = 2 + 64;
// Room a colour delta of n triangles needs at most (vector + tables + prefix).
constexpr std::size_t colour_message_bytes(int n) { return 8 * static_cast<std::size_t>(n) + 128; }
constexpr std::size_t kHealthBytes = 128;
// Colours queue only while a console's unsent bytes are below this: the rest
// of its buffer stays free for poses, which must not wait behind a texture.
constexpr std::size_t kColourBacklogBytes = 64 * 1024;
}  // namespace

// One console connection; every buffer sized in configure().
struct StreamSink::Client {
  platform::Fd fd;
  std::vector<std::uint8_t> out;  // bytes waiting to be sent: [begin, end)
  std::size_t begin = 0, end = 0;
  bool has_pending_pose = false;  // a pose that did not fit (latest wins)
  PoseSample pending_pose;
  std::vector<std::uint64_t> dirty;  // triangles whose colour this console still needs
  std::vector<std::uint32_t> ids;    // scratch: the triangles of one delta
  std::uint32_t dropped = 0;

  std::size_t room() const { return out.size() - (end - begin); }
  bool append(std::span<const std::uint8_t> bytes) {
    if (bytes.size() > room()) return false;
    if (end + bytes.size() > out.size()) {  // compact: move the unsent bytes to the front
      std::memmove(out.data(), out.data() + begin, end - begin);
      end -= begin;
      begin = 0;
    }
    std::memcpy(out.data() + end, bytes.data(), bytes.size());
    end += bytes.size();
    return true;
  }
};

StreamSink::StreamSink() = default;
StreamSink::~StreamSink() { stop(0.0); }

Status StreamSink::configure(const StreamSinkConfig& config, const StreamHello& hello) {
  if (thread_.joinable()) return make_error("stream sink: configure() while running");
  if (config.max_clients < 1 || config.max_clients > kMaxPollFds - 2)
    return make_error("stream sink: max_clients must be 1.." + std::to_string(kMaxPollFds - 2));
  if (config.client_buffer_bytes < kMinClientBufferBytes)
    return make_error("stream sink: client_buffer_bytes must be at least " +
                      std::to_string(kMinClientBufferBytes));
  if (hello.mesh_triangle_count == 0 || hello.mesh_triangle_count > kMaxMeshTriangles)
    return make_error("stream sink: mesh triangle count out of range");
  config_ = config;
  hello_ = hello;
  triangles_ = hello.mesh_triangle_count;
  std::string error;
  listen_fd_ = platform::listen_on(config.endpoint, 16, &bound_, &error);
  if (!listen_fd_.valid()) return make_error("stream sink: " + error);
  wake_fd_ = platform::Fd(::eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC));
  if (!wake_fd_.valid())
    return make_error(std::string("stream sink: eventfd: ") + std::strerror(errno));
  const std::size_t words = (triangles_ + 63) / 64;
  colour_ = std::vector<std::atomic<std::uint32_t>>(triangles_);
  dirty_ = std::vector<std::atomic<std::uint64_t>>(words);
  coloured_.assign(words, 0);
  clients_ = std::vector<Client>(static_cast<std::size_t>(config.max_clients));
  for (Client& c : clients_) {
    c.out.assign(config.client_buffer_bytes, 0);
    c.dirty.assign(words, 0);
    c.ids.assign(kMaxColoursPerDelta, 0);
  }
  scratch_.assign(64 * 1024, 0);
  return Status::Ok();
}

void StreamSink::start() {
  if (thread_.joinable() || !listen_fd_.valid()) return;
  running_ = true;
  last_health_ns_ = platform::monotonic_ns();
  next_health_ns_ = last_health_ns_ + static_cast<std::int64_t>(config_.health_period_s * 1e9);
  thread_ = std::thread([this] { run(); });
}

void StreamSink::wake() {
  if (!wake_pending_.exchange(true, std::memory_order_acq_rel)) {
    const std::uint64_t one = 1;
    [[maybe_unused]] const ssize_t n = ::write(wake_fd_.get(), &one, sizeof(one));
  }
}

bool StreamSink::push_pose(const PoseSample& pose) {
  if (!poses_.try_push(pose)) {
    pose_overruns_.fetch_add(1, std::memory_order_relaxed);
    return false;
  }
  wake();
  return true;
}

void StreamSink::push_colours(std::span<const ColourUpdate> colours) {
  for (const ColourUpdate& c : colours) {
    if (c.triangle >= triangles_) continue;
    colour_[c.triangle].store(
        kColouredBit | (std::uint32_t{c.r} << 16) | (std::uint32_t{c.g} << 8) | c.b,
        std::memory_order_relaxed);
    // release: the sink that sees the bit sees the colour.
    dirty_[c.triangle / 64].fetch_or(std::uint64_t{1} << (c.triangle % 64),
                                     std::memory_order_release);
  }
  if (!colours.empty()) wake();
}

bool StreamSink::wait_for_consoles(int n, double timeout_s) const {
  const std::int64_t deadline =
      platform::monotonic_ns() + static_cast<std::int64_t>(timeout_s * 1e9);
  while (connected_.load() < n) {
    if (platform::monotonic_ns() > deadline) return false;
    platform::sleep_until_ns(platform::monotonic_ns() + 2'000'000);
  }
  return true;
}

void StreamSink::stop(double flush_timeout_s) {
  if (thread_.joinable()) {
    flush_timeout_s_ = flush_timeout_s;
    running_ = false;
    const std::uint64_t one = 1;
    [[maybe_unused]] const ssize_t n = ::write(wake_fd_.get(), &one, sizeof(one));
    thread_.join();
  }
  // Also when configured but never started: no socket file is left behind.
  if (bound_.kind == platform::Endpoint::Kind::kUnix && listen_fd_.valid())
    ::unlink(bound_.path.c_str());
  listen_fd_.reset();
}

StreamSinkStats StreamSink::stats() const {
  StreamSinkStats s;
  s.poses = poses_in_.load();
  s.pose_overruns = pose_overruns_.load();
  s.other_overruns = other_overruns_.load();
  s.consoles_accepted = accepted_.load();
  s.consoles_refused = refused_.load();
  s.dropped_messages = dropped_.load();
  s.sink_thread_allocations = sink_allocs_.load();
  s.consoles_connected = connected_.load();
  return s;
}

void StreamSink::run() {
  const std::uint64_t allocs0 = platform::thread_allocation_count();
  while (running_.load(std::memory_order_acquire)) {
    const std::int64_t to_health_ms = (next_health_ns_ - platform::monotonic_ns()) / 1'000'000;
    poll_once(static_cast<int>(std::clamp<std::int64_t>(to_health_ms, 0, 100)));
    sink_allocs_.store(platform::thread_allocation_count() - allocs0, std::memory_order_relaxed);
  }
  // Flush: what the producers queued before stop() reaches consoles that read.
  const std::int64_t deadline =
      platform::monotonic_ns() + static_cast<std::int64_t>(flush_timeout_s_ * 1e9);
  do {
    poll_once(10);
  } while (anything_pending() && platform::monotonic_ns() < deadline);
  sink_allocs_.store(platform::thread_allocation_count() - allocs0, std::memory_order_relaxed);
  for (Client& c : clients_) close_client(c);
}

void StreamSink::poll_once(int timeout_ms) {
  pollfd fds[kMaxPollFds];
  int slot_of[kMaxPollFds];
  int n = 0;
  fds[n++] = {wake_fd_.get(), POLLIN, 0};
  fds[n++] = {listen_fd_.get(), POLLIN, 0};
  for (std::size_t i = 0; i < clients_.size(); ++i) {
    const Client& c = clients_[i];
    if (!c.fd.valid()) continue;
    slot_of[n] = static_cast<int>(i);
    fds[n++] = {c.fd.get(), static_cast<short>(POLLIN | (c.end > c.begin ? POLLOUT : 0)), 0};
  }
  if (::poll(fds, static_cast<nfds_t>(n), timeout_ms) < 0 && errno != EINTR) return;
  if (fds[0].revents & POLLIN) {
    std::uint64_t v = 0;
    [[maybe_unused]] const ssize_t r = ::read(wake_fd_.get(), &v, sizeof(v));
  }
  wake_pending_.store(false, std::memory_order_release);
  if (fds[1].revents & POLLIN) accept_consoles();
  for (int k = 2; k < n; ++k) {
    Client& c = clients_[static_cast<std::size_t>(slot_of[k])];
    if (!(fds[k].revents & (POLLIN | POLLHUP | POLLERR))) continue;
    // Consoles send nothing we use: read to notice a close, discard the rest.
    const ssize_t r = ::recv(c.fd.get(), scratch_.data(), scratch_.size(), MSG_DONTWAIT);
    if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK && errno != EINTR))
      close_client(c);
  }
  drain_poses();
  collect_colours();
  if (platform::monotonic_ns() >= next_health_ns_) send_health();
  for (Client& c : clients_) {
    if (!c.fd.valid()) continue;
    fill_client(c);
    send_client(c);
  }
}

void StreamSink::accept_consoles() {
  for (;;) {
    platform::Fd fd = platform::accept_client(listen_fd_.get());
    if (!fd.valid()) return;
    auto free_slot = std::find_if(clients_.begin(), clients_.end(),
                                  [](const Client& c) { return !c.fd.valid(); });
    if (free_slot == clients_.end()) {
      refused_.fetch_add(1);
      continue;  // fd closes here: the console sees the connection end
    }
    Client& c = *free_slot;
    c.fd = std::move(fd);
    c.begin = c.end = 0;
    c.has_pending_pose = false;
    c.dropped = 0;
    c.append(encoder_.hello(hello_));
    std::copy(coloured_.begin(), coloured_.end(), c.dirty.begin());  // the texture so far
    accepted_.fetch_add(1);
    connected_.fetch_add(1);
  }
}

void StreamSink::drain_poses() {
  PoseSample p;
  while (poses_.try_pop(&p)) {
    poses_in_.fetch_add(1, std::memory_order_relaxed);
    ++frames_since_health_;
    std::span<const std::uint8_t> bytes;  // encoded once, for the first console that has room
    for (Client& c : clients_) {
      if (!c.fd.valid()) continue;
      if (!c.has_pending_pose) {
        if (bytes.empty()) bytes = encoder_.pose(p);
        if (c.append(bytes)) continue;
      } else {
        ++c.dropped;  // the waiting pose is replaced by this newer one
        dropped_.fetch_add(1, std::memory_order_relaxed);
      }
      c.has_pending_pose = true;
      c.pending_pose = p;
    }
  }
}

void StreamSink::collect_colours() {
  for (std::size_t w = 0; w < dirty_.size(); ++w) {
    if (dirty_[w].load(std::memory_order_relaxed) == 0) continue;
    const std::uint64_t bits = dirty_[w].exchange(0, std::memory_order_acquire);
    coloured_[w] |= bits;
    for (Client& c : clients_)
      if (c.fd.valid()) c.dirty[w] |= bits;
  }
}

void StreamSink::fill_client(Client& c) {
  if (c.has_pending_pose && c.append(encoder_.pose(c.pending_pose))) c.has_pending_pose = false;
  if (c.has_pending_pose) return;  // poses first: no colours while a pose waits
  std::size_t w = 0;
  while (c.room() >= colour_message_bytes(64) && c.end - c.begin < kColourBacklogBytes) {
    const int max_n =
        static_cast<int>(std::min<std::size_t>(kMaxColoursPerDelta, (c.room() - 128) / 8));
    int n = 0;
    for (; w < c.dirty.size() && n < max_n; ++w) {
      while (c.dirty[w] != 0 && n < max_n) {
        const int bit = std::countr_zero(c.dirty[w]);
        c.dirty[w] &= c.dirty[w] - 1;
        c.ids[static_cast<std::size_t>(n++)] =
            static_cast<std::uint32_t>(w * 64 + static_cast<std::size_t>(bit));
      }
      if (c.dirty[w] != 0) break;  // the delta is full: continue this word next time
    }
    if (n == 0) return;
    stream::TriangleColour* out = encoder_.begin_colours(n);
    for (int i = 0; i < n; ++i) {
      const std::uint32_t t = c.ids[static_cast<std::size_t>(i)];
      const std::uint32_t v = colour_[t].load(std::memory_order_relaxed);
      out[i] =
          stream::TriangleColour(t, static_cast<std::uint8_t>(v >> 16),
                                 static_cast<std::uint8_t>(v >> 8), static_cast<std::uint8_t>(v));
    }
    c.append(encoder_.finish_colours());  // fits: room was checked for n colours
  }
}

bool StreamSink::send_client(Client& c) {
  while (c.end > c.begin) {
    const ssize_t n =
        ::send(c.fd.get(), c.out.data() + c.begin, c.end - c.begin, MSG_NOSIGNAL | MSG_DONTWAIT);
    if (n > 0) {
      c.begin += static_cast<std::size_t>(n);
    } else if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
      return true;  // the console is not reading right now: keep the bytes
    } else {
      close_client(c);
      return false;
    }
  }
  c.begin = c.end = 0;
  return true;
}

void StreamSink::send_health() {
  const std::int64_t now = platform::monotonic_ns();
  const double period_s = static_cast<double>(now - last_health_ns_) * 1e-9;
  HealthSample h;
  h.fps = period_s > 0 ? static_cast<float>(frames_since_health_ / period_s) : 0.f;
  h.overruns = static_cast<std::uint32_t>(pose_overruns_.load() + other_overruns_.load());
  h.frames = static_cast<std::uint32_t>(poses_in_.load());
  h.calibration_suspect = calibration_suspect_.load(std::memory_order_acquire);
  h.calibration_focal_scale = calibration_scale_.load(std::memory_order_relaxed);
  for (Client& c : clients_) {
    if (!c.fd.valid()) continue;
    h.dropped_messages = c.dropped;
    if (c.room() < kHealthBytes || !c.append(encoder_.health(h))) {
      ++c.dropped;
      dropped_.fetch_add(1, std::memory_order_relaxed);
    }
  }
  frames_since_health_ = 0;
  last_health_ns_ = now;
  next_health_ns_ = now + static_cast<std::int64_t>(config_.health_period_s * 1e9);
}

void StreamSink::close_client(Client& c) {
  if (!c.fd.valid()) return;
  c.fd.reset();
  c.begin = c.end = 0;
  c.has_pending_pose = false;
  connected_.fetch_sub(1);
}

bool StreamSink::anything_pending() const {
  for (const Client& c : clients_) {
    if (!c.fd.valid()) continue;
    if (c.end > c.begin || c.has_pending_pose) return true;
    for (const std::uint64_t w : c.dirty)
      if (w) return true;
  }
  return poses_.size() > 0;
}

}  // namespace st
