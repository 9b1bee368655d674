// Live capture from a camera through libcamera (Debian 12 ships 0.0.3).
// NOT RUN ON HARDWARE: this machine has no camera; only the no-camera paths
// and the pixel-format conversion (hal/capture/pixel_format.h) are tested here.
//
// Lifecycle, top to bottom as libcamera's simple-cam reads:
//   open(): CameraManager start -> get(id) -> acquire -> generateConfiguration
//           (VideoRecording) -> YUV420, else NV12, at the calibration size ->
//           validate -> configure -> FrameBufferAllocator -> mmap every
//           buffer's planes once -> one Request per buffer -> planar output
//           buffers. Everything is allocated here.
//   start(): connect requestCompleted, camera start, queue every request.
//   next_frame(): tracking thread, see below.
//   stop(): camera stop (cancels what is queued), wakes the tracking
//           thread with kEnd, joins the re-queue thread.
//   ~LibcameraCapture(): unmap, free, release, CameraManager stop.
//
// Threads: libcamera's own thread runs the completion callback, which only
// pushes the request's slot into a fixed SPSC queue (no processing, no
// allocation). The tracking thread calls next_frame(): it takes the newest
// completed frame (older ones waiting behind it are handed back unread:
// latest wins, so latency does not build up when tracking is slower than
// the camera), converts it into the planar frame it returns and hands the
// request back at once. A small re-queue thread calls Request::reuse
// (ReuseBuffers) and Camera::queueRequest, which post messages inside
// libcamera (they allocate), so the tracking thread never calls libcamera.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/base/result.h"
#include "hal/capture/frame_source.h"
#include "hal/capture/pixel_format.h"
#include "hal/capture/y4m_reader.h"

namespace st {

// The libcamera version this binary runs with, e.g. "0.0.3" (or "none"
// when built without libcamera).
std::string libcamera_version();

struct CameraListing {
  std::string libcamera_version;
  std::vector<std::string> ids;  // Camera::id(), stable across reboots
};
// Starts a CameraManager, lists its cameras, stops it. Error only when the
// manager cannot start (or libcamera is missing from the build).
Result<CameraListing> list_cameras();
// "no camera found (libcamera 0.0.3 found 0 cameras)" or the ids found.
std::string describe_cameras(const CameraListing& listing);

struct CaptureOptions {
  std::string camera_id;
  int width = 0, height = 0;  // the calibration's image size: the stream must match it exactly
  int ring_slots = 4;         // camera buffers (= requests); libcamera may raise it
};

struct LiveFrame {
  enum class Kind : std::uint8_t { kFrame, kEnd, kError };
  Kind kind = Kind::kEnd;
  FrameRef frame;                 // kFrame: valid until the next next_frame() call
  std::uint32_t sequence = 0;     // the camera's frame counter (gaps: frames the sensor dropped)
  std::int64_t t_sensor_ns = 0;   // FrameMetadata timestamp (start of exposure, monotonic)
  PixelStatus pixel_status = PixelStatus::kOk;  // kError: why the buffer could not be read
};

struct CaptureCounters {
  std::uint64_t completed = 0;  // requests completed with a frame
  std::uint64_t skipped = 0;    // completed frames handed back unread (latest wins)
  std::uint64_t failed = 0;     // buffers with an error status from the camera
};

// A camera as a frame source (hal/capture/frame_source.h): next() wraps
// next_frame() (a frame stays valid until the next call, so release() has
// nothing to do), timestamps from the sensor's clock, paced by the camera.
class LibcameraCapture final : public FrameSource {
 public:
  LibcameraCapture();
  ~LibcameraCapture() override;
  LibcameraCapture(const LibcameraCapture&) = delete;
  LibcameraCapture& operator=(const LibcameraCapture&) = delete;

  // Errors say what was found: no camera at all, the id not among those
  // listed, a camera that cannot deliver YUV420/NV12 at the size, a buffer
  // layout the converter refuses, mmap failures.
  Status open(const CaptureOptions& options);
  CapturePixelFormat pixel_format() const;
  Status start() override;
  // Tracking thread: waits for a frame (or kEnd after stop(), or kError
  // after a failed buffer). Allocation-free.
  void next_frame(LiveFrame* out);
  // Owner thread (e.g. on SIGINT): ends the capture; next_frame() then
  // returns kEnd.
  void stop() override;
  CaptureCounters counters() const;

  // FrameSource: the frame's time from its sensor timestamp (frame 0 at 0 s);
  // latency counts from the sensor timestamp when it is plausible (on
  // CLOCK_MONOTONIC, under a second old), else from the hand-off.
  void next(SourceFrame* out) override;
  void release() override {}
  bool paced() const override { return true; }
  std::string error() const override;

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  std::int64_t t_first_sensor_ns_ = -1;     // tracking thread
  PixelStatus error_status_ = PixelStatus::kOk;  // the buffer that ended the stream, if any
};

}  // namespace st
