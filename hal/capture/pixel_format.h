// Camera pixel formats -> the tracker's planes. A capture buffer holds a
// frame as YUV420 (three planes: Y, U, V; "YU12") or NV12 (two planes: Y,
// interleaved UV), each plane with its own stride (row padding) and size.
// The tracker wants a luma plane (width x height) and 4:2:0 chroma planes
// U, V of ceil(width/2) x ceil(height/2) (the layout of a Y4M frame and of
// FrameRef in hal/capture/y4m_reader.h).
//
// Pure functions, no I/O: the libcamera capture (hal/capture/libcamera_capture.h)
// describes its mapped buffers as a RawFrame and calls these; tests feed
// synthetic buffers. check_raw_frame() explains a bad layout once, at
// configure time (allocates the message); convert_to_planar() runs per frame
// on the tracking thread and allocates nothing, also when it refuses.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "core/image/image.h"
#include "core/base/result.h"

namespace st {

enum class CapturePixelFormat : std::uint8_t { kYuv420, kNv12 };
const char* to_string(CapturePixelFormat format);
// Planes of a format: 3 for YUV420, 2 for NV12.
int plane_count(CapturePixelFormat format);

// One plane of a capture buffer: `size` readable bytes from `data`, rows
// `stride` bytes apart (stride >= the plane's row bytes; the rest is padding).
struct RawPlane {
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;
  std::size_t stride = 0;
};

struct RawFrame {
  CapturePixelFormat format = CapturePixelFormat::kYuv420;
  int width = 0, height = 0;  // pixels
  std::array<RawPlane, 3> planes{};  // plane_count(format) are used
};

// The tracker's planes (owned by the caller, e.g. a ring of Images).
struct PlanarFrame {
  ImageView<std::uint8_t> y;     // width x height
  ImageView<std::uint8_t> u, v;  // (width + 1) / 2 x (height + 1) / 2
};

// Bytes per row and rows of plane `plane` of a width x height frame.
std::size_t plane_row_bytes(CapturePixelFormat format, int plane, int width);
int plane_rows(int plane, int height);
// The stride libcamera reports is the luma plane's; chroma planes have
// half of it (YUV420) or the same (NV12).
std::size_t chroma_stride(CapturePixelFormat format, std::size_t luma_stride);
// Smallest plane size holding `rows` rows of `row_bytes` at `stride` (the
// last row needs no padding).
std::size_t min_plane_size(std::size_t row_bytes, int rows, std::size_t stride);

enum class PixelStatus : std::uint8_t {
  kOk,
  kBadSize,          // width or height <= 0 or above the image capacity (core/base/capacity.h)
  kMissingPlane,     // a plane without data
  kStrideTooSmall,   // stride below the plane's row bytes
  kPlaneTooSmall,    // size below stride * (rows - 1) + row bytes
  kOutputMismatch,   // the PlanarFrame views do not have the frame's sizes
};
// A fixed description (no allocation): for the tracking thread's counters.
const char* describe(PixelStatus status);

// Hot-path check of raw against out (allocation-free).
PixelStatus check_layout(const RawFrame& raw, const PlanarFrame& out);
// The same check with a message naming the plane, the numbers and what
// would fit (configure time).
Status check_raw_frame(const RawFrame& raw, const PlanarFrame& out);

// Copies luma row by row and copies (YUV420) or de-interleaves (NV12) the
// chroma; padding is never read into the output. On anything but kOk the
// output is left untouched. Allocation-free.
PixelStatus convert_to_planar(const RawFrame& raw, const PlanarFrame& out);

}  // namespace st
