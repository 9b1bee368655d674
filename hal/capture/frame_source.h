// Where frames come from: the capture interface that every source
// implements (the Y4M file or pipe, hal/capture/y4m_capture.h; a libcamera
// camera, hal/capture/libcamera_capture.h), as each board implements an
// AP_HAL interface. The one frame loop (firmware_app/frame_loop.h) reads
// any of them the same way.
//
// Threads: start() and stop() on the owner; next() and release() on the
// one consumer, the tracking thread, where they allocate nothing and never
// touch a file or a device. A frame returned by next() stays valid until
// release().
#pragma once

#include <cstdint>
#include <string>

#include "core/base/result.h"
#include "hal/capture/y4m_reader.h"

namespace st {

struct SourceFrame {
  enum class Kind : std::uint8_t { kFrame, kEnd, kError };
  Kind kind = Kind::kEnd;
  FrameRef frame;             // kFrame: valid until release()
  double timestamp_s = 0;     // the frame's time in the stream (frame 0 at 0 s)
  std::int64_t t_ready_ns = 0;  // monotonic time the frame was there to take (latency counts from it)
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;
  // Owner: frames start flowing.
  virtual Status start() = 0;
  // Tracking thread: waits for the next frame, the end of the stream, or an
  // error (kError: error() says what, on the owner thread afterwards).
  virtual void next(SourceFrame* out) = 0;
  // Tracking thread: the frame of the last next() is no longer used.
  virtual void release() = 0;
  // Owner: ends the stream (next() then returns kEnd) and waits for the
  // source's threads. Also after the stream ended by itself.
  virtual void stop() = 0;
  // True when frames arrive at their own pace (a camera, a paced replay):
  // latency counts from t_ready_ns. False for a file read as fast as
  // possible, which runs ahead on purpose: latency then counts from when
  // the tracker could take the frame.
  virtual bool paced() const = 0;
  // After kError: what went wrong, naming the frame. May allocate.
  virtual std::string error() const = 0;
};

}  // namespace st
