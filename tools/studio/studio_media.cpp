#include "tools/studio/studio_media.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <system_error>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

namespace st::studio {

Status VideoFrames::open(const std::filesystem::path& path) {
  path_ = path;
  has_current_ = false;
  reader_.close();
  if (Status s = reader_.open(path, 2); !s) return s;
  std::error_code ec;
  const auto size = std::filesystem::file_size(path, ec);
  const std::size_t frame_with_line = reader_.header().frame_bytes() + 6;  // "FRAME\n"
  count_ = -1;
  if (!ec && size >= reader_.header().header_bytes &&
      (size - reader_.header().header_bytes) % frame_with_line == 0)
    count_ = static_cast<int>((size - reader_.header().header_bytes) / frame_with_line);
  return Status::Ok();
}

Result<FrameRef> VideoFrames::frame(int index) {
  if (index < 0) return make_error("frame " + std::to_string(index) + ": frames count from 0");
  if (has_current_ && current_.index == index) return current_;
  if (has_current_ && current_.index > index) {
    if (Status s = open(path_); !s) return make_error(s.message());
  }
  for (;;) {
    FrameRef f;
    const ReadResult r = reader_.read_frame(&f);
    if (r == ReadResult::kEndOfStream)
      return make_error("frame " + std::to_string(index) + " is past the end of the video (" +
                        std::to_string(reader_.frames_read()) + " frames)");
    if (r == ReadResult::kError) {
      const std::string e = reader_.error();
      (void)open(path_);  // start over next time rather than stay in error
      return make_error("video: " + e);
    }
    current_ = f;
    has_current_ = true;
    if (f.index == index) return f;
  }
}

std::string encode_jpeg(const FrameRef& f, int quality) {
  const int w = f.y.width, h = f.y.height;
  cv::Mat bgr(h, w, CV_8UC3);
  const bool mono = f.u.empty();
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* Y = f.y.row(y);
    const std::uint8_t* U = mono ? nullptr : f.u.row(y / 2);
    const std::uint8_t* V = mono ? nullptr : f.v.row(y / 2);
    auto* out = bgr.ptr<std::uint8_t>(y);
    for (int x = 0; x < w; ++x) {
      const double l = Y[x];
      const double cb = mono ? 0.0 : U[x / 2] - 128.0, cr = mono ? 0.0 : V[x / 2] - 128.0;
      const auto u8 = [](double v) { return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0l, 255l)); };
      out[3 * x + 0] = u8(l + 1.772 * cb);
      out[3 * x + 1] = u8(l - 0.344136 * cb - 0.714136 * cr);
      out[3 * x + 2] = u8(l + 1.402 * cr);
    }
  }
  std::vector<std::uint8_t> bytes;
  cv::imencode(".jpg", bgr, bytes, {cv::IMWRITE_JPEG_QUALITY, quality});
  return {bytes.begin(), bytes.end()};
}

std::string encode_png(const overlay::OverlayLayer& layer) {
  std::vector<std::uint8_t> bytes;
  // Fast compression: the layer is mostly transparent and sent per frame.
  cv::imencode(".png", const_cast<overlay::OverlayLayer&>(layer).bgra(), bytes, {cv::IMWRITE_PNG_COMPRESSION, 1});
  return {bytes.begin(), bytes.end()};
}

std::string matrix_json(const SE3& T) {
  const Mat3& R = T.rotation();
  const Vec3& t = T.translation();
  std::string s = "[";
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) {
      const double v = r == 3 ? (c == 3 ? 1.0 : 0.0) : (c == 3 ? t(r) : R(r, c));
      s += json_number(v);
      s += (r == 3 && c == 3) ? "]" : ",";
    }
  return s;
}

std::string mesh_payload(const Mesh& mesh) {
  const auto nv = static_cast<std::uint32_t>(mesh.vertex_count());
  const auto nt = static_cast<std::uint32_t>(mesh.triangle_count());
  std::string out(8 + 12 * static_cast<std::size_t>(nv) + 12 * static_cast<std::size_t>(nt), '\0');
  char* p = out.data();
  const auto put32 = [&p](std::uint32_t v) {
    for (int i = 0; i < 4; ++i) *p++ = static_cast<char>((v >> (8 * i)) & 0xff);
  };
  const auto putf = [&put32](float f) {
    std::uint32_t bits;
    std::memcpy(&bits, &f, 4);
    put32(bits);
  };
  put32(nv);
  put32(nt);
  for (std::uint32_t i = 0; i < nv; ++i) {
    putf(mesh.x[i]);
    putf(mesh.y[i]);
    putf(mesh.z[i]);
  }
  for (const std::int32_t t : mesh.tri) put32(static_cast<std::uint32_t>(t));
  return out;
}

std::string info_json(const LoadedSequence& seq, std::string_view mode, int frames, int frame,
                      std::string_view extra_fields) {
  const SequenceConfig& c = seq.config;
  std::string s = "{\"type\":\"info\",\"mode\":" + json_string(mode) + ",\"sequence\":" +
                  json_string(std::filesystem::absolute(seq.dir).filename().string()) +
                  ",\"width\":" + std::to_string(c.width) + ",\"height\":" + std::to_string(c.height) +
                  ",\"frames\":" + std::to_string(frames) + ",\"frame\":" + std::to_string(frame) +
                  ",\"fps\":" + json_number(c.fps) +
                  ",\"has_groundtruth\":" + (seq.groundtruth.empty() ? "false" : "true") +
                  ",\"T_camera_model_init\":" + matrix_json(c.T_camera_model_init) + ",\"K\":[" +
                  json_number(c.K.fx) + "," + json_number(c.K.fy) + "," + json_number(c.K.cx) + "," +
                  json_number(c.K.cy) + "],\"distortion\":[";
  for (int i = 0; i < 5; ++i) s += json_number(c.distortion.k[static_cast<std::size_t>(i)]) + (i < 4 ? "," : "]");
  s.append(extra_fields);
  s += "}";
  return s;
}

overlay::OverlayStyle studio_overlay_style() {
  overlay::OverlayStyle style;
  style.fill_alpha = 0.2;
  style.state = false;
  style.text = false;
  return style;
}

}  // namespace st::studio
