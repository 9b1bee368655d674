// Fuzzes the Y4M stream parsers: the header, then FRAME records walked the
// way the reader walks a stream (FRAME line, then frame_bytes of pixels).
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/formats/y4m.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  std::string_view bytes(reinterpret_cast<const char*>(data), size);
  const st::Result<st::Y4mHeader> h = st::parse_y4m_header(bytes);
  if (!h) return 0;
  if (h->header_bytes > bytes.size() || h->frame_bytes() == 0) __builtin_trap();
  bytes.remove_prefix(h->header_bytes);
  while (!bytes.empty()) {
    const st::Result<std::size_t> line = st::parse_y4m_frame_line(bytes);
    if (!line) break;
    if (line.value() > bytes.size()) __builtin_trap();
    bytes.remove_prefix(line.value());
    if (bytes.size() < h->frame_bytes()) break;  // truncated frame
    bytes.remove_prefix(h->frame_bytes());
  }
  return 0;
}
