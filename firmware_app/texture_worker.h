// The texture thread: colours the mesh from frames the tracking thread
// hands over (core/texture/mesh_texture.h, Algorithm 1) and passes the colour
// deltas to the console sink.
//
// Hand-over: a fixed pool of frame copies (Y, U, V) and two SPSC queues
// (free slots back to the tracking thread, filled slots to the worker).
// try_submit() runs on the tracking thread: it copies the frame into a free
// slot (a memcpy of the planes, only on frames chosen for texturing) or,
// when every slot is busy, skips the frame and says so; it never waits and
// never allocates. configure() allocates the pool; the worker thread
// allocates nothing after start(). Like the mapping thread, the worker
// lowers its own priority (platform::kBackgroundWorkerNice).
#pragma once

#include <atomic>
#include <cstdint>
#include <thread>
#include <vector>

#include "core/texture/mesh_texture.h"
#include "hal/stream/stream_sink.h"
#include "hal/capture/y4m_reader.h"
#include "platform/spsc_queue.h"

namespace st::app {

class TextureWorker {
 public:
  static constexpr int kMaxSlots = 16;

  TextureWorker() = default;
  ~TextureWorker();
  TextureWorker(const TextureWorker&) = delete;
  TextureWorker& operator=(const TextureWorker&) = delete;

  // sink may be null (texture kept locally only). slots: 1..kMaxSlots frame copies.
  Status configure(const Mesh& mesh, const CameraModel& camera, const TextureConfig& config,
                   int slots, StreamSink* sink);
  void start();
  // Tracking thread: false when no slot is free (the frame is skipped).
  bool try_submit(const FrameRef& frame, const SE3& T_camera_model);
  // Owner: textures every submitted frame, then ends the thread.
  void stop();

  std::int64_t frames_textured() const { return textured_.load(); }
  std::int64_t colours_sent() const { return colours_.load(); }
  std::int64_t worker_allocations() const { return worker_allocs_.load(); }
  int thread_nice() const { return thread_nice_.load(); }  // -1 until the thread runs
  // After stop(): the texture itself.
  const MeshTexture& texture() const { return texture_; }

 private:
  struct Slot {
    Image<std::uint8_t> y, u, v;
    bool mono = false;
    SE3 T_camera_model;
  };
  void run();

  MeshTexture texture_;
  StreamSink* sink_ = nullptr;
  std::vector<Slot> slots_;
  platform::SpscQueue<int, 32> free_;  // worker -> tracking thread
  platform::SpscQueue<int, 32> work_;  // tracking thread -> worker; -1 ends the thread
  std::atomic<std::int64_t> textured_{0}, colours_{0}, worker_allocs_{0};
  std::atomic<int> thread_nice_{-1};
  std::thread thread_;
};

}  // namespace st::app
