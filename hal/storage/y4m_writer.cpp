#include "hal/storage/y4m_writer.h"

#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <unistd.h>

#include "core/base/capacity.h"

namespace st {

Y4mWriter::~Y4mWriter() { (void)close(); }

Status Y4mWriter::open(const std::filesystem::path& path, const Y4mHeader& header) {
  if (Status s = close(); !s) return s;
  if (header.width <= 0 || header.height <= 0 || header.width > kMaxImageWidth ||
      header.height > kMaxImageHeight || header.fps_num <= 0 || header.fps_den <= 0)
    return make_error("Y4M writer: bad stream parameters " + std::to_string(header.width) + "x" +
                      std::to_string(header.height) + " at " + std::to_string(header.fps_num) +
                      ":" + std::to_string(header.fps_den) + " fps");
  path_ = path.string();
  if (path_ == "-") {
    fd_ = STDOUT_FILENO;
    owns_fd_ = false;
  } else {
    fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd_ < 0) return make_error("cannot create " + path_ + ": " + std::strerror(errno));
    owns_fd_ = true;
  }
  header_ = header;
  const std::string line = format_y4m_header(header);
  header_.header_bytes = line.size();
  header_.chroma_tag = header.chroma == Chroma::kMono ? "mono" : "420jpeg";
  record_.clear();
  record_.reserve(header_.frame_bytes() + 16);
  frames_ = 0;
  return write_all(line);
}

Status Y4mWriter::write(ImageView<const std::uint8_t> y, ImageView<const std::uint8_t> u,
                        ImageView<const std::uint8_t> v) {
  if (fd_ < 0) return make_error("Y4M writer: write() before open()");
  record_.clear();
  if (Status s = append_y4m_frame(header_, y, u, v, &record_); !s) return s;
  if (Status s = write_all(record_); !s) return s;
  ++frames_;
  return Status::Ok();
}

Status Y4mWriter::write_all(std::string_view bytes) {
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd_, bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return make_error("cannot write " + path_ + ": " + std::strerror(errno));
    done += static_cast<std::size_t>(n);
  }
  return Status::Ok();
}

Status Y4mWriter::close() {
  if (fd_ < 0) return Status::Ok();
  const int fd = fd_;
  fd_ = -1;
  if (owns_fd_ && ::close(fd) != 0) return make_error("cannot close " + path_ + ": " + std::strerror(errno));
  return Status::Ok();
}

}  // namespace st
