// YUV4MPEG2 (Y4M) as bytes: the stream header, FRAME records, and writers.
// Parsers take bytes and never allocate more than the header line's tag
// string; frame sizes are capped at core/base/capacity.h before the caller sizes
// any buffer from them. Supported colour spaces: 4:2:0 (C420jpeg,
// C420paldv, C420mpeg2, C420, or no C tag) and Cmono (8-bit luma only).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include "core/image/image.h"
#include "core/base/result.h"

namespace st {

enum class Chroma { k420, kMono };

struct Y4mHeader {
  int width = 0, height = 0;
  int fps_num = 25, fps_den = 1;
  Chroma chroma = Chroma::k420;
  std::string chroma_tag;      // as written after 'C' ("420jpeg", "mono"); empty if absent
  std::size_t header_bytes = 0;  // the header line including its '\n'

  int chroma_width() const { return chroma == Chroma::kMono ? 0 : (width + 1) / 2; }
  int chroma_height() const { return chroma == Chroma::kMono ? 0 : (height + 1) / 2; }
  std::size_t luma_bytes() const;
  std::size_t chroma_plane_bytes() const;  // one of U, V; 0 for mono
  // Bytes of pixel data in one frame (without the FRAME line).
  std::size_t frame_bytes() const;
  double fps() const { return fps_den > 0 ? static_cast<double>(fps_num) / fps_den : 0.0; }
};

// Longest header or FRAME line we accept before calling the input garbage.
inline constexpr std::size_t kMaxY4mLineBytes = 4096;

// Parses the stream header at the start of `bytes` ("YUV4MPEG2 W.. H.. ...\n").
// `bytes` may hold more than the header (it is not read past the '\n').
// Rejects: wrong magic, no '\n' within kMaxY4mLineBytes, missing/zero/
// oversized W or H, bad F, colour spaces other than 4:2:0 and mono.
Result<Y4mHeader> parse_y4m_header(std::string_view bytes);

// Parses a FRAME line at the start of `bytes` ("FRAME" [params] "\n") and
// returns its length including the '\n'. Per-frame params are accepted and
// ignored. Does not allocate on success.
Result<std::size_t> parse_y4m_frame_line(std::string_view bytes);

// "YUV4MPEG2 W.. H.. F..:.. Ip A1:1 C420jpeg\n" (or Cmono).
std::string format_y4m_header(int width, int height, int fps_num, int fps_den,
                              Chroma chroma = Chroma::k420);
std::string format_y4m_header(const Y4mHeader& h);

// Appends one FRAME record ("FRAME\n" + Y [+ U + V] planes, rows packed)
// to *out. Plane sizes must match the header (U, V ignored for mono).
// Allocates only if *out lacks capacity: reserve once and reuse.
Status append_y4m_frame(const Y4mHeader& h, ImageView<const std::uint8_t> y,
                        ImageView<const std::uint8_t> u, ImageView<const std::uint8_t> v,
                        std::string* out);

}  // namespace st
