// The console link of a replay: the sink thread (hal/stream/stream_sink.h) and the
// texture thread (texture_worker.h) behind the replay's FrameObserver hook.
// On the tracking thread frame_done() pushes one POD PoseSample and, on
// frames chosen for texturing, offers a frame copy to the texture thread
// (skipped when its pool is busy); nothing there waits or allocates.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "firmware_app/texture_worker.h"
#include "firmware_app/replay.h"
#include "hal/stream/stream_sink.h"

namespace st::app {

struct StreamLinkConfig {
  platform::Endpoint endpoint;
  int wait_consoles = 0;  // start only once this many consoles are connected
  double wait_timeout_s = 30;
  int texture_every =
      0;  // 0: texture keyframes (and the initial frame); k: every k-th frame with a pose
  int texture_slots = 4;
  int texture_downscale = 0;   // 0: 1 up to 960 px wide, else 2 (of the frames textured)
  double flush_timeout_s = 5;  // at the end: time for consoles to read what is queued
};

// One frame's pose message: the tracker's result as the console receives
// it (lost unless a finite pose was reported; the outline's and the
// shading's evidence where they were measured). fps: the source's, for
// the time stamp (0: unknown).
PoseSample pose_sample(const FrameRef& frame, const TrackResult& r, double latency_ms, double fps);

class StreamLink : public FrameObserver {
 public:
  // frames: the camera of the frames frame_done() will get (the sequence's,
  // or the tracker's working camera when the capture scales to it).
  Status configure(const StreamLinkConfig& config, const LoadedSequence& sequence, const CameraModel& frames);
  const platform::Endpoint& endpoint() const { return sink_.endpoint(); }
  // Starts both threads; then waits for config.wait_consoles consoles
  // (an error when they do not come in time).
  Status start();
  void frame_done(const FrameRef& frame, const TrackResult& result, double latency_ms) override;
  // After the replay: textures what was submitted, flushes to the consoles,
  // closes; adds the link's figures to summary.json.
  void finish(std::vector<std::pair<std::string, double>>* summary_fields) override;
  // The same without the summary (idempotent; also on error paths).
  void stop();

 private:
  StreamLinkConfig config_;
  StreamSink sink_;
  TextureWorker texture_;
  double fps_ = 0;
  std::int64_t posed_frames_ = 0, texture_skips_ = 0;
};

}  // namespace st::app
