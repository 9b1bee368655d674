// Y4M capture from a file, a FIFO or a pipe (path "-" = stdin, or an fd).
// Lifecycle: open() reads the header and sizes a ring of N frame slots and
// one input buffer (the only allocations); read_frame() then fills the next
// slot, or begin_frame() and read_frame_data() hand the frame over in
// pieces, and allocate nothing, on success or on error (messages are
// formatted into storage reserved at open). A FrameRef stays valid until
// N further read_frame() calls reuse its slot. Single-threaded: the capture
// thread owns the reader.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "core/image/image.h"
#include "core/base/result.h"
#include "core/formats/y4m.h"

namespace st {

struct FrameRef {
  int index = -1;                      // 0-based frame number in the stream
  ImageView<const std::uint8_t> y;     // luma, width x height
  ImageView<const std::uint8_t> u, v;  // 4:2:0 chroma (half size, rounded up); empty for mono
  // The same frame at the tracker's working size, when the source made it
  // (Y4mCapture::set_working_size: then y, u and v are empty, the frame at
  // the source's size is not kept); empty otherwise.
  ImageView<const std::uint8_t> y_work, u_work, v_work;
};

enum class ReadResult { kFrame, kEndOfStream, kError };

inline constexpr int kMaxRingSlots = 64;

class Y4mReader {
 public:
  Y4mReader() = default;
  ~Y4mReader();
  Y4mReader(const Y4mReader&) = delete;
  Y4mReader& operator=(const Y4mReader&) = delete;

  // path "-" reads stdin. Blocks on a FIFO until a writer opens it and the
  // header arrives. ring_slots 0: no slot, frames read in pieces only
  // (begin_frame()).
  Status open(const std::filesystem::path& path, int ring_slots = 3);
  // Reads from an already open descriptor (a pipe); closes it on close()
  // when take_ownership.
  Status open_fd(int fd, bool take_ownership, int ring_slots = 3, const std::string& name = "fd");

  const Y4mHeader& header() const { return header_; }
  // kFrame: *out refers to the new frame. kEndOfStream: the stream ended
  // cleanly at a frame boundary. kError: error() says what (truncated frame:
  // which frame and how many bytes are missing; a bad FRAME line; an I/O
  // error); the reader stays in error.
  ReadResult read_frame(FrameRef* out);
  // The next frame in pieces, into the caller's buffers (a reader opened
  // with no slots reads this way only): begin_frame() reads the FRAME line
  // (kFrame: *index is the frame's number), then read_frame_data() takes
  // the frame's bytes in order (the planes as header() lays them out), n at
  // a time, header().frame_bytes() in all; the frame counts as read once
  // its last byte is. Errors as read_frame()'s: a frame that ends early
  // says how many of its bytes were present.
  ReadResult begin_frame(int* index);
  ReadResult read_frame_data(std::uint8_t* dst, std::size_t n);
  const std::string& error() const { return error_; }
  int frames_read() const { return frames_read_; }
  int ring_slots() const { return static_cast<int>(slots_.size()); }
  // After open(), before the first read_frame(): a ring of ring_slots
  // frames instead (allocates; the old slots are freed).
  Status set_ring_slots(int ring_slots);
  void close();

 private:
  Status start(int ring_slots);
  Status read_header_line(std::string* line);
  ReadResult read_frame_line();  // the FRAME line of frame frames_read_
  // Fills dst with n bytes (buffer first, then the descriptor); returns the count read.
  std::size_t read_bytes(std::uint8_t* dst, std::size_t n);
  // Reads one line ('\n' included) into line_buf_; returns its length, 0 at EOF.
  std::size_t read_line(bool* too_long);
  bool refill();
  ReadResult fail(const char* fmt, ...) __attribute__((format(printf, 2, 3)));

  Y4mHeader header_;
  std::vector<std::vector<std::uint8_t>> slots_;
  std::vector<char> in_buf_;  // buffered input, consumed from in_pos_ to in_end_
  std::size_t in_pos_ = 0, in_end_ = 0;
  std::vector<char> line_buf_;
  std::string name_;
  std::string error_;  // capacity reserved at open
  int fd_ = -1;
  bool owns_fd_ = false;
  bool failed_ = false;
  bool io_error_ = false;
  int io_errno_ = 0;
  int frames_read_ = 0;
  std::size_t piece_bytes_ = 0;  // of the frame begin_frame() started (0: none started)
  std::size_t piece_got_ = 0;
};

}  // namespace st
