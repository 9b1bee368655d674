#include "hal/storage/file_io.h"

#include <cerrno>
#include <cstring>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

namespace st {

namespace {
std::string errno_text() { return std::strerror(errno); }

class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }

 private:
  int fd_;
};
}  // namespace

Result<std::string> read_file(const std::filesystem::path& path, std::int64_t max_bytes) {
  Fd fd(::open(path.c_str(), O_RDONLY | O_CLOEXEC));
  if (fd.get() < 0) return make_error("cannot open " + path.string() + ": " + errno_text());
  struct stat st {};
  if (::fstat(fd.get(), &st) != 0 || !S_ISREG(st.st_mode))
    return make_error(path.string() + " is not a regular file");
  if (st.st_size > max_bytes)
    return make_error(path.string() + " is " + std::to_string(st.st_size) +
                      " bytes, more than the " + std::to_string(max_bytes) + " accepted");
  std::string bytes(static_cast<std::size_t>(st.st_size), '\0');
  std::size_t got = 0;
  while (got < bytes.size()) {
    const ssize_t n = ::read(fd.get(), bytes.data() + got, bytes.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return make_error("cannot read " + path.string() + ": " + errno_text());
    if (n == 0) break;  // file shrank while reading
    got += static_cast<std::size_t>(n);
  }
  bytes.resize(got);
  return bytes;
}

Status write_file(const std::filesystem::path& path, std::string_view bytes) {
  const std::filesystem::path tmp = path.string() + ".tmp";
  Fd fd(::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644));
  if (fd.get() < 0) return make_error("cannot create " + tmp.string() + ": " + errno_text());
  std::size_t done = 0;
  while (done < bytes.size()) {
    const ssize_t n = ::write(fd.get(), bytes.data() + done, bytes.size() - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) return make_error("cannot write " + tmp.string() + ": " + errno_text());
    done += static_cast<std::size_t>(n);
  }
  if (::close(fd.release()) != 0) return make_error("cannot close " + tmp.string() + ": " + errno_text());
  if (::rename(tmp.c_str(), path.c_str()) != 0)
    return make_error("cannot rename " + tmp.string() + " to " + path.string() + ": " + errno_text());
  return Status::Ok();
}

}  // namespace st
