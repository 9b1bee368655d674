#include "hal/capture/y4m_reader.h"

#include <algorithm>
#include <cerrno>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <fcntl.h>
#include <unistd.h>

namespace st {

namespace {
constexpr std::size_t kInputBufferBytes = 64 * 1024;
constexpr std::size_t kMaxRingBytes = std::size_t{2} << 30;  // all slots together

Status check_ring_slots(int ring_slots) {
  if (ring_slots < 0 || ring_slots > kMaxRingSlots)
    return make_error("Y4M reader: ring of " + std::to_string(ring_slots) + " slots, must be 0.." +
                      std::to_string(kMaxRingSlots) + " (0: frames read in pieces)");
  return Status::Ok();
}
}  // namespace

Y4mReader::~Y4mReader() { close(); }

void Y4mReader::close() {
  if (fd_ >= 0 && owns_fd_) ::close(fd_);
  fd_ = -1;
  owns_fd_ = false;
}

Status Y4mReader::open(const std::filesystem::path& path, int ring_slots) {
  if (path == "-") return open_fd(STDIN_FILENO, false, ring_slots, "stdin");
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) return make_error("cannot open video " + path.string() + ": " + std::strerror(errno));
  return open_fd(fd, true, ring_slots, path.string());
}

Status Y4mReader::open_fd(int fd, bool take_ownership, int ring_slots, const std::string& name) {
  close();
  fd_ = fd;
  owns_fd_ = take_ownership;
  name_ = name;
  failed_ = io_error_ = false;
  frames_read_ = 0;
  piece_bytes_ = piece_got_ = 0;
  in_pos_ = in_end_ = 0;
  Status s = start(ring_slots);
  if (!s) close();
  return s;
}

Status Y4mReader::start(int ring_slots) {
  if (Status s = check_ring_slots(ring_slots); !s) return s;  // before any read
  in_buf_.assign(kInputBufferBytes, 0);
  line_buf_.assign(kMaxY4mLineBytes + 1, 0);
  error_.reserve(512);
  std::string line;
  if (Status s = read_header_line(&line); !s) return s;
  Result<Y4mHeader> h = parse_y4m_header(line);
  if (!h) return make_error(name_ + ": " + h.message());
  header_ = h.value();
  return set_ring_slots(ring_slots);
}

Status Y4mReader::set_ring_slots(int ring_slots) {
  if (Status s = check_ring_slots(ring_slots); !s) return s;
  if (frames_read_ > 0) return make_error(name_ + ": the ring is sized before the first frame is read");
  if (header_.frame_bytes() * static_cast<std::size_t>(ring_slots) > kMaxRingBytes)
    return make_error(name_ + ": a ring of " + std::to_string(ring_slots) + " frames of " +
                      std::to_string(header_.frame_bytes()) + " bytes is too large");
  // One slot at a time: no prototype frame beside the ring (at 4K one
  // more frame, 12 MB, at the peak of the resident memory).
  std::vector<std::vector<std::uint8_t>>().swap(slots_);
  slots_.resize(static_cast<std::size_t>(ring_slots));
  for (std::vector<std::uint8_t>& s : slots_) s.assign(header_.frame_bytes(), 0);
  return Status::Ok();
}

Status Y4mReader::read_header_line(std::string* line) {
  bool too_long = false;
  const std::size_t n = read_line(&too_long);
  if (io_error_) return make_error(name_ + ": read error: " + std::strerror(io_errno_));
  if (n == 0) return make_error(name_ + ": empty stream (no Y4M header)");
  line->assign(line_buf_.data(), n);
  if (too_long || line->back() != '\n') {
    // Let the parser explain (wrong magic vs. an unterminated header).
    Result<Y4mHeader> h = parse_y4m_header(*line);
    return make_error(name_ + ": " + (h ? std::string("Y4M header line is not terminated") : h.message()));
  }
  return Status::Ok();
}

bool Y4mReader::refill() {
  in_pos_ = 0;
  in_end_ = 0;
  for (;;) {
    const ssize_t n = ::read(fd_, in_buf_.data(), in_buf_.size());
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) {
      io_error_ = true;
      io_errno_ = errno;
      return false;
    }
    in_end_ = static_cast<std::size_t>(n);
    return n > 0;
  }
}

std::size_t Y4mReader::read_line(bool* too_long) {
  std::size_t n = 0;
  *too_long = false;
  while (n < kMaxY4mLineBytes) {
    if (in_pos_ == in_end_ && !refill()) return n;
    const char c = in_buf_[in_pos_++];
    line_buf_[n++] = c;
    if (c == '\n') return n;
  }
  *too_long = true;
  return n;
}

std::size_t Y4mReader::read_bytes(std::uint8_t* dst, std::size_t n) {
  std::size_t got = std::min(n, in_end_ - in_pos_);
  std::memcpy(dst, in_buf_.data() + in_pos_, got);
  in_pos_ += got;
  while (got < n) {  // large planes go straight from the descriptor into the slot
    const ssize_t r = ::read(fd_, dst + got, n - got);
    if (r < 0 && errno == EINTR) continue;
    if (r < 0) {
      io_error_ = true;
      io_errno_ = errno;
      break;
    }
    if (r == 0) break;
    got += static_cast<std::size_t>(r);
  }
  return got;
}

ReadResult Y4mReader::fail(const char* fmt, ...) {
  char buf[512];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(buf, sizeof buf, fmt, args);
  va_end(args);
  error_.assign(buf);  // fits the reserved capacity: no allocation
  failed_ = true;
  return ReadResult::kError;
}

ReadResult Y4mReader::read_frame_line() {
  const int index = frames_read_;
  bool too_long = false;
  const std::size_t n = read_line(&too_long);
  if (io_error_) return fail("%.200s: read error before frame %d: %s", name_.c_str(), index, std::strerror(io_errno_));
  if (n == 0) return ReadResult::kEndOfStream;
  const Result<std::size_t> line = parse_y4m_frame_line(std::string_view(line_buf_.data(), n));
  if (!line || too_long)
    return fail("%.200s: frame %d does not start with a FRAME line (%zu bytes: corrupt or truncated stream)",
                name_.c_str(), index, n);
  return ReadResult::kFrame;
}

ReadResult Y4mReader::begin_frame(int* index) {
  if (failed_) return ReadResult::kError;
  if (fd_ < 0) return fail("Y4M reader: begin_frame() before a successful open()");
  if (piece_bytes_ != 0)
    return fail("Y4M reader: begin_frame() with %zu bytes of frame %d still unread", piece_bytes_ - piece_got_,
                frames_read_);
  if (const ReadResult r = read_frame_line(); r != ReadResult::kFrame) return r;
  piece_bytes_ = header_.frame_bytes();
  piece_got_ = 0;
  *index = frames_read_;
  return ReadResult::kFrame;
}

ReadResult Y4mReader::read_frame_data(std::uint8_t* dst, std::size_t n) {
  if (failed_) return ReadResult::kError;
  if (piece_bytes_ == 0 || n > piece_bytes_ - piece_got_)
    return fail("Y4M reader: read_frame_data() of %zu bytes past the end of frame %d", n, frames_read_);
  const std::size_t got = read_bytes(dst, n);
  if (io_error_)
    return fail("%.200s: read error in frame %d: %s", name_.c_str(), frames_read_, std::strerror(io_errno_));
  piece_got_ += got;
  if (got < n)
    return fail("%.200s: frame %d is truncated: %zu of %zu bytes present, %zu missing", name_.c_str(),
                frames_read_, piece_got_, piece_bytes_, piece_bytes_ - piece_got_);
  if (piece_got_ == piece_bytes_) {
    piece_bytes_ = piece_got_ = 0;
    ++frames_read_;
  }
  return ReadResult::kFrame;
}

ReadResult Y4mReader::read_frame(FrameRef* out) {
  if (failed_) return ReadResult::kError;
  if (fd_ < 0) return fail("Y4M reader: read_frame() before a successful open()");
  if (slots_.empty()) return fail("Y4M reader: read_frame() on a reader opened without slots (begin_frame())");
  if (piece_bytes_ != 0) return fail("Y4M reader: read_frame() inside a frame read in pieces");
  const int index = frames_read_;
  if (const ReadResult r = read_frame_line(); r != ReadResult::kFrame) return r;
  std::vector<std::uint8_t>& slot = slots_[static_cast<std::size_t>(index) % slots_.size()];
  const std::size_t got = read_bytes(slot.data(), slot.size());
  if (io_error_) return fail("%.200s: read error in frame %d: %s", name_.c_str(), index, std::strerror(io_errno_));
  if (got < slot.size())
    return fail("%.200s: frame %d is truncated: %zu of %zu bytes present, %zu missing", name_.c_str(),
                index, got, slot.size(), slot.size() - got);
  const Y4mHeader& h = header_;
  const std::uint8_t* p = slot.data();
  out->index = index;
  out->y = ImageView<const std::uint8_t>(p, h.width, h.height);
  if (h.chroma == Chroma::kMono) {
    out->u = out->v = ImageView<const std::uint8_t>();
  } else {
    out->u = ImageView<const std::uint8_t>(p + h.luma_bytes(), h.chroma_width(), h.chroma_height());
    out->v = ImageView<const std::uint8_t>(p + h.luma_bytes() + h.chroma_plane_bytes(),
                                           h.chroma_width(), h.chroma_height());
  }
  ++frames_read_;
  return ReadResult::kFrame;
}

}  // namespace st
