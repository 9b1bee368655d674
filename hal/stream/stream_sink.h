// The console link's sink: one thread that serves any number of consoles
// (up to max_clients) over a TCP or Unix socket with FlatBuffers messages
// (hal/stream/stream_protocol.h). A console gets a Hello when it connects, then
// every pose, the colours of every triangle coloured so far, then colour
// deltas, and Health once per period.
//
// Threads and queues (nothing ever waits on a console):
// - tracking thread: push_pose() copies a POD PoseSample into a fixed SPSC
//   ring and pokes an eventfd; no lock, no allocation. Ring full (the sink
//   thread is starved for seconds): the pose is dropped and counted.
// - texture thread: push_colours() writes each colour into an atomic
//   per-triangle table and sets its dirty bit: coalesced by construction
//   (a triangle changed ten times is sent once, with its latest colour).
// - sink thread: owns the sockets; per console a fixed send buffer. A pose
//   that does not fit waits in a one-pose slot where a newer pose replaces
//   it (latest wins, the replaced one counts as dropped for that console);
//   colours wait as dirty bits. A console that never reads costs a full
//   buffer and drop counts, nothing else.
// configure() allocates everything; after start() the sink thread
// allocates nothing either (counted: stats().sink_thread_allocations).
#pragma once

#include <atomic>
#include <cstdint>
#include <span>
#include <thread>
#include <vector>

#include "core/base/result.h"
#include "hal/stream/stream_protocol.h"
#include "platform/socket.h"
#include "platform/spsc_queue.h"

namespace st {

// Room for two full colour deltas beside the poses.
inline constexpr std::size_t kMinClientBufferBytes = 128 * 1024;

struct StreamSinkConfig {
  platform::Endpoint endpoint;
  int max_clients = 4;
  std::size_t client_buffer_bytes = 512 * 1024;  // per console, >= kMinClientBufferBytes
  double health_period_s = 1.0;
};

struct StreamSinkStats {
  std::uint64_t poses = 0;           // poses the sink took from the tracking thread
  std::uint64_t pose_overruns = 0;   // poses dropped because the sink ring was full
  std::uint64_t other_overruns = 0;  // reported by note_overrun() (e.g. texture frames skipped)
  std::uint64_t consoles_accepted = 0;
  std::uint64_t consoles_refused = 0;         // all slots were taken
  std::uint64_t dropped_messages = 0;         // over all consoles (latest-wins replacements)
  std::uint64_t sink_thread_allocations = 0;  // heap allocations of the sink thread after start()
  int consoles_connected = 0;
};

class StreamSink {
 public:
  StreamSink();
  ~StreamSink();
  StreamSink(const StreamSink&) = delete;
  StreamSink& operator=(const StreamSink&) = delete;

  // Listens on config.endpoint and sizes every buffer (triangle tables from
  // hello.mesh_triangle_count). The endpoint is bound when this returns.
  Status configure(const StreamSinkConfig& config, const StreamHello& hello);
  // The bound endpoint (a TCP port 0 becomes the port chosen).
  const platform::Endpoint& endpoint() const { return bound_; }
  void start();
  // Tracking thread (one producer): never blocks, never allocates. False if dropped.
  bool push_pose(const PoseSample& pose);
  // Texture thread (any one thread): never blocks, never allocates.
  void push_colours(std::span<const ColourUpdate> colours);
  // Any thread: a frame whose work was skipped somewhere (shown in Health).
  void note_overrun() { other_overruns_.fetch_add(1, std::memory_order_relaxed); }
  // Any thread: the tracker judged the calibration suspect (shown in Health
  // from then on, with the focal scale the video fits).
  void note_calibration_suspect(float focal_scale) {
    calibration_scale_.store(focal_scale, std::memory_order_relaxed);
    calibration_suspect_.store(true, std::memory_order_release);
  }
  // Owner: waits until at least n consoles are connected or timeout_s passes.
  bool wait_for_consoles(int n, double timeout_s) const;
  // Owner: sends what is queued to consoles that read (up to flush_timeout_s),
  // closes every connection and the listening socket (a Unix socket's file
  // is removed), joins the thread. Idempotent; the destructor calls it.
  void stop(double flush_timeout_s = 2.0);
  StreamSinkStats stats() const;

 private:
  struct Client;
  void run();
  void poll_once(int timeout_ms);
  void accept_consoles();
  void drain_poses();
  void collect_colours();
  void fill_client(Client& c);
  bool send_client(Client& c);
  void send_health();
  void close_client(Client& c);
  bool anything_pending() const;
  void wake();

  StreamSinkConfig config_;
  platform::Endpoint bound_;
  StreamHello hello_;
  platform::Fd listen_fd_, wake_fd_;
  std::vector<Client> clients_;
  StreamEncoder encoder_;
  std::vector<std::uint8_t> scratch_;  // received bytes are discarded here
  platform::SpscQueue<PoseSample, 1024> poses_;
  // Shared colour table: bit 24 set = coloured; dirty bits per triangle.
  std::vector<std::atomic<std::uint32_t>> colour_;
  std::vector<std::atomic<std::uint64_t>> dirty_;
  std::vector<std::uint64_t> coloured_;  // sink thread: triangles ever coloured (for new consoles)
  std::uint32_t triangles_ = 0;
  std::atomic<bool> running_{false};
  std::atomic<bool> wake_pending_{false};
  std::atomic<int> connected_{0};
  std::atomic<std::uint64_t> poses_in_{0}, pose_overruns_{0}, other_overruns_{0};
  std::atomic<bool> calibration_suspect_{false};
  std::atomic<float> calibration_scale_{1.f};
  std::atomic<std::uint64_t> accepted_{0}, refused_{0}, dropped_{0}, sink_allocs_{0};
  double flush_timeout_s_ = 2.0;
  std::uint32_t frames_since_health_ = 0;
  std::int64_t next_health_ns_ = 0, last_health_ns_ = 0;
  std::thread thread_;
};

}  // namespace st
