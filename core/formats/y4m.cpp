#include "core/formats/y4m.h"

#include <charconv>
#include <cstring>

#include "core/base/capacity.h"

namespace st {

std::size_t Y4mHeader::luma_bytes() const {
  return static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
}
std::size_t Y4mHeader::chroma_plane_bytes() const {
  return static_cast<std::size_t>(chroma_width()) * static_cast<std::size_t>(chroma_height());
}
std::size_t Y4mHeader::frame_bytes() const { return luma_bytes() + 2 * chroma_plane_bytes(); }

namespace {

// Whole-token positive integer; false on anything else (sign, junk, overflow).
bool parse_positive(std::string_view s, long long max_value, int* out) {
  if (s.empty() || s.front() < '0' || s.front() > '9') return false;
  long long v = 0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || v <= 0 || v > max_value) return false;
  *out = static_cast<int>(v);
  return true;
}

std::string printable(std::string_view s) {
  std::string out;
  for (char c : s.substr(0, 40)) out += (c >= 32 && c < 127) ? c : '?';
  return out;
}

Status parse_chroma(std::string_view tag, Y4mHeader* h) {
  h->chroma_tag = std::string(tag);
  if (tag == "420jpeg" || tag == "420paldv" || tag == "420mpeg2" || tag == "420") {
    h->chroma = Chroma::k420;
  } else if (tag == "mono") {
    h->chroma = Chroma::kMono;
  } else {
    return make_error("Y4M colour space C" + printable(tag) +
                      " is not supported (4:2:0 or mono only): convert with "
                      "ffmpeg -i in -pix_fmt yuv420p -f yuv4mpegpipe out.y4m");
  }
  return Status::Ok();
}

Status parse_frame_rate(std::string_view value, Y4mHeader* h) {
  const std::size_t colon = value.find(':');
  if (colon == std::string_view::npos ||
      !parse_positive(value.substr(0, colon), 1'000'000'000, &h->fps_num) ||
      !parse_positive(value.substr(colon + 1), 1'000'000'000, &h->fps_den))
    return make_error("Y4M frame rate F" + printable(value) + " is not of the form num:den > 0");
  return Status::Ok();
}

// One header parameter token (first letter = tag). Unknown and X tags are ignored.
Status parse_header_token(std::string_view tok, Y4mHeader* h) {
  const char tag = tok.front();
  const std::string_view value = tok.substr(1);
  if (tag == 'W' && !parse_positive(value, kMaxImageWidth, &h->width))
    return make_error("Y4M width W" + printable(value) + " is not an integer in 1.." +
                      std::to_string(kMaxImageWidth));
  if (tag == 'H' && !parse_positive(value, kMaxImageHeight, &h->height))
    return make_error("Y4M height H" + printable(value) + " is not an integer in 1.." +
                      std::to_string(kMaxImageHeight));
  if (tag == 'F') return parse_frame_rate(value, h);
  if (tag == 'C') return parse_chroma(value, h);
  return Status::Ok();  // I (interlacing), A (aspect), X (extensions): not needed
}

}  // namespace

Result<Y4mHeader> parse_y4m_header(std::string_view bytes) {
  constexpr std::string_view kMagic = "YUV4MPEG2";
  if (bytes.substr(0, kMagic.size()) != kMagic)
    return make_error("not a Y4M stream: it must start with 'YUV4MPEG2', found '" +
                      printable(bytes.substr(0, kMagic.size())) + "'");
  const std::size_t eol = bytes.substr(0, kMaxY4mLineBytes).find('\n');
  if (eol == std::string_view::npos)
    return make_error("Y4M header line has no end within " + std::to_string(kMaxY4mLineBytes) +
                      " bytes (truncated or not a Y4M stream)");
  Y4mHeader h;
  h.header_bytes = eol + 1;
  h.width = h.height = 0;
  std::string_view rest = bytes.substr(kMagic.size(), eol - kMagic.size());
  if (!rest.empty() && rest.front() != ' ')
    return make_error("not a Y4M stream: 'YUV4MPEG2' must be followed by a space");
  while (!rest.empty()) {
    const std::size_t start = rest.find_first_not_of(' ');
    if (start == std::string_view::npos) break;
    rest = rest.substr(start);
    const std::size_t end = std::min(rest.find(' '), rest.size());
    if (Status s = parse_header_token(rest.substr(0, end), &h); !s) return Error{s.message()};
    rest = rest.substr(end);
  }
  if (h.width == 0 || h.height == 0)
    return make_error("Y4M header lacks the frame size (W and H are required)");
  return h;
}

Result<std::size_t> parse_y4m_frame_line(std::string_view bytes) {
  constexpr std::string_view kFrame = "FRAME";
  if (bytes.substr(0, kFrame.size()) != kFrame)
    return make_error("expected a Y4M 'FRAME' record, found '" +
                      printable(bytes.substr(0, kFrame.size())) + "'");
  const std::size_t eol = bytes.substr(0, kMaxY4mLineBytes).find('\n');
  if (eol == std::string_view::npos)
    return make_error("Y4M FRAME line has no end within " + std::to_string(kMaxY4mLineBytes) +
                      " bytes");
  if (eol != kFrame.size() && bytes[kFrame.size()] != ' ')
    return make_error("Y4M FRAME tag must be followed by a space or a newline");
  return eol + 1;
}

std::string format_y4m_header(int width, int height, int fps_num, int fps_den, Chroma chroma) {
  std::string s = "YUV4MPEG2 W" + std::to_string(width) + " H" + std::to_string(height) + " F" +
                  std::to_string(fps_num) + ":" + std::to_string(fps_den) + " Ip A1:1 C";
  s += chroma == Chroma::kMono ? "mono" : "420jpeg";
  s += '\n';
  return s;
}

std::string format_y4m_header(const Y4mHeader& h) {
  return format_y4m_header(h.width, h.height, h.fps_num, h.fps_den, h.chroma);
}

namespace {
bool plane_matches(ImageView<const std::uint8_t> p, int w, int h) {
  return p.data != nullptr && p.width == w && p.height == h && p.stride >= w;
}
void append_plane(ImageView<const std::uint8_t> p, std::string* out) {
  for (int y = 0; y < p.height; ++y)
    out->append(reinterpret_cast<const char*>(p.row(y)), static_cast<std::size_t>(p.width));
}
}  // namespace

Status append_y4m_frame(const Y4mHeader& h, ImageView<const std::uint8_t> y,
                        ImageView<const std::uint8_t> u, ImageView<const std::uint8_t> v,
                        std::string* out) {
  if (!plane_matches(y, h.width, h.height))
    return make_error("Y4M frame: luma plane is " + std::to_string(y.width) + "x" +
                      std::to_string(y.height) + ", the stream is " + std::to_string(h.width) +
                      "x" + std::to_string(h.height));
  const bool colour = h.chroma != Chroma::kMono;
  if (colour && (!plane_matches(u, h.chroma_width(), h.chroma_height()) ||
                 !plane_matches(v, h.chroma_width(), h.chroma_height())))
    return make_error("Y4M frame: chroma planes must be " + std::to_string(h.chroma_width()) +
                      "x" + std::to_string(h.chroma_height()) + " for 4:2:0");
  out->append("FRAME\n");
  append_plane(y, out);
  if (colour) {
    append_plane(u, out);
    append_plane(v, out);
  }
  return Status::Ok();
}

}  // namespace st
