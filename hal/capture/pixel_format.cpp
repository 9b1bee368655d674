#include "hal/capture/pixel_format.h"

#include <cstring>
#include <string>

#include "core/base/capacity.h"

namespace st {

const char* to_string(CapturePixelFormat format) {
  return format == CapturePixelFormat::kNv12 ? "NV12" : "YUV420";
}

int plane_count(CapturePixelFormat format) { return format == CapturePixelFormat::kNv12 ? 2 : 3; }

std::size_t plane_row_bytes(CapturePixelFormat format, int plane, int width) {
  const auto w = static_cast<std::size_t>(width);
  if (plane == 0) return w;
  const std::size_t chroma_w = (w + 1) / 2;
  return format == CapturePixelFormat::kNv12 ? 2 * chroma_w : chroma_w;  // NV12: U V pairs
}

int plane_rows(int plane, int height) { return plane == 0 ? height : (height + 1) / 2; }

std::size_t chroma_stride(CapturePixelFormat format, std::size_t luma_stride) {
  return format == CapturePixelFormat::kNv12 ? luma_stride : (luma_stride + 1) / 2;
}

std::size_t min_plane_size(std::size_t row_bytes, int rows, std::size_t stride) {
  return rows <= 0 ? 0 : stride * static_cast<std::size_t>(rows - 1) + row_bytes;
}

const char* describe(PixelStatus status) {
  switch (status) {
    case PixelStatus::kOk: return "ok";
    case PixelStatus::kBadSize: return "frame size out of range";
    case PixelStatus::kMissingPlane: return "a plane has no data";
    case PixelStatus::kStrideTooSmall: return "a plane's stride is below its row bytes";
    case PixelStatus::kPlaneTooSmall: return "a plane is smaller than its rows need";
    case PixelStatus::kOutputMismatch: return "output planes do not match the frame size";
  }
  return "unknown";
}

namespace {

bool view_is(const ImageView<std::uint8_t>& v, int w, int h) {
  return v.data != nullptr && v.width == w && v.height == h && v.stride >= w;
}

// The first problem of plane p, with the numbers for a message.
struct PlaneCheck {
  PixelStatus status = PixelStatus::kOk;
  std::size_t row_bytes = 0, need = 0;
};
PlaneCheck check_plane(const RawFrame& raw, int p) {
  const RawPlane& plane = raw.planes[static_cast<std::size_t>(p)];
  PlaneCheck c;
  c.row_bytes = plane_row_bytes(raw.format, p, raw.width);
  c.need = min_plane_size(c.row_bytes, plane_rows(p, raw.height), plane.stride);
  if (plane.data == nullptr) c.status = PixelStatus::kMissingPlane;
  else if (plane.stride < c.row_bytes) c.status = PixelStatus::kStrideTooSmall;
  else if (plane.size < c.need) c.status = PixelStatus::kPlaneTooSmall;
  return c;
}

void copy_rows(const RawPlane& in, int rows, std::size_t row_bytes, const ImageView<std::uint8_t>& out) {
  for (int r = 0; r < rows; ++r) std::memcpy(out.row(r), in.data + static_cast<std::size_t>(r) * in.stride, row_bytes);
}

// NV12's second plane: U0 V0 U1 V1 ... per row.
void split_uv(const RawPlane& in, const PlanarFrame& out) {
  const int w = out.u.width;
  for (int r = 0; r < out.u.height; ++r) {
    const std::uint8_t* src = in.data + static_cast<std::size_t>(r) * in.stride;
    std::uint8_t* u = out.u.row(r);
    std::uint8_t* v = out.v.row(r);
    for (int x = 0; x < w; ++x) {
      u[x] = src[2 * x];
      v[x] = src[2 * x + 1];
    }
  }
}

}  // namespace

PixelStatus check_layout(const RawFrame& raw, const PlanarFrame& out) {
  if (raw.width <= 0 || raw.height <= 0 || raw.width > kMaxImageWidth || raw.height > kMaxImageHeight)
    return PixelStatus::kBadSize;
  for (int p = 0; p < plane_count(raw.format); ++p)
    if (const PlaneCheck c = check_plane(raw, p); c.status != PixelStatus::kOk) return c.status;
  const int cw = (raw.width + 1) / 2, ch = (raw.height + 1) / 2;
  if (!view_is(out.y, raw.width, raw.height) || !view_is(out.u, cw, ch) || !view_is(out.v, cw, ch))
    return PixelStatus::kOutputMismatch;
  return PixelStatus::kOk;
}

Status check_raw_frame(const RawFrame& raw, const PlanarFrame& out) {
  const std::string frame = std::string(to_string(raw.format)) + " " + std::to_string(raw.width) + "x" +
                            std::to_string(raw.height);
  if (raw.width <= 0 || raw.height <= 0 || raw.width > kMaxImageWidth || raw.height > kMaxImageHeight)
    return make_error(frame + ": frame size outside 1x1.." + std::to_string(kMaxImageWidth) + "x" +
                      std::to_string(kMaxImageHeight));
  static constexpr const char* kPlaneName[2][3] = {{"Y", "U", "V"}, {"Y", "UV", ""}};
  for (int p = 0; p < plane_count(raw.format); ++p) {
    const PlaneCheck c = check_plane(raw, p);
    const RawPlane& plane = raw.planes[static_cast<std::size_t>(p)];
    const std::string name = frame + " plane " + std::to_string(p) + " (" +
                             kPlaneName[raw.format == CapturePixelFormat::kNv12][p] + ")";
    if (c.status == PixelStatus::kMissingPlane) return make_error(name + " has no data");
    if (c.status == PixelStatus::kStrideTooSmall)
      return make_error(name + ": stride " + std::to_string(plane.stride) + " bytes is below its row of " +
                        std::to_string(c.row_bytes) + " bytes");
    if (c.status == PixelStatus::kPlaneTooSmall)
      return make_error(name + ": " + std::to_string(plane.size) + " bytes, but " +
                        std::to_string(plane_rows(p, raw.height)) + " rows at stride " +
                        std::to_string(plane.stride) + " need " + std::to_string(c.need));
  }
  if (check_layout(raw, out) == PixelStatus::kOutputMismatch)
    return make_error(frame + ": the output planes must be " + std::to_string(raw.width) + "x" +
                      std::to_string(raw.height) + " (Y) and " + std::to_string((raw.width + 1) / 2) + "x" +
                      std::to_string((raw.height + 1) / 2) + " (U, V), got " + std::to_string(out.y.width) + "x" +
                      std::to_string(out.y.height) + ", " + std::to_string(out.u.width) + "x" +
                      std::to_string(out.u.height) + ", " + std::to_string(out.v.width) + "x" +
                      std::to_string(out.v.height));
  return Status::Ok();
}

PixelStatus convert_to_planar(const RawFrame& raw, const PlanarFrame& out) {
  if (const PixelStatus s = check_layout(raw, out); s != PixelStatus::kOk) return s;
  copy_rows(raw.planes[0], raw.height, static_cast<std::size_t>(raw.width), out.y);
  if (raw.format == CapturePixelFormat::kNv12) {
    split_uv(raw.planes[1], out);
  } else {
    const auto cw = static_cast<std::size_t>(out.u.width);
    copy_rows(raw.planes[1], out.u.height, cw, out.u);
    copy_rows(raw.planes[2], out.v.height, cw, out.v);
  }
  return PixelStatus::kOk;
}

}  // namespace st
