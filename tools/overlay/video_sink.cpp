#include "tools/overlay/video_sink.h"

#include <cerrno>
#include <csignal>
#include <cstring>
#include <sys/wait.h>

namespace st::overlay {

namespace {
// Single quotes for /bin/sh, with embedded quotes escaped.
std::string shell_quoted(const std::string& s) {
  std::string out = "'";
  for (const char c : s) out += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return out + "'";
}
}  // namespace

std::string ffmpeg_command(const std::filesystem::path& out_path) {
  return shell_quoted(SCOPETRACK_FFMPEG) +
         " -hide_banner -loglevel error -y -f yuv4mpegpipe -i - -c:v libx264 -preset veryfast -crf 20"
         " -pix_fmt yuv420p -movflags +faststart " +
         shell_quoted(out_path.string());
}

VideoSink::~VideoSink() { (void)close(); }

Status VideoSink::open(const std::filesystem::path& path, int width, int height, int fps_num, int fps_den) {
  path_ = path;
  header_.width = width;
  header_.height = height;
  header_.fps_num = fps_num;
  header_.fps_den = fps_den;
  header_.chroma = Chroma::k420;
  pipe_ = path.extension() != ".y4m";
  if (pipe_) {
    if (std::strlen(SCOPETRACK_FFMPEG) == 0)
      return make_error("writing " + path.string() + " needs ffmpeg, which was not found: write a .y4m instead");
    std::signal(SIGPIPE, SIG_IGN);  // ffmpeg dying must be an error here, not kill us
    out_ = ::popen(ffmpeg_command(path).c_str(), "w");
  } else {
    out_ = std::fopen(path.c_str(), "wb");
  }
  if (!out_) return make_error("cannot write " + path.string() + ": " + std::strerror(errno));
  const std::string head = format_y4m_header(width, height, fps_num, fps_den, Chroma::k420);
  record_.reserve(header_.frame_bytes() + 16);
  if (std::fwrite(head.data(), 1, head.size(), out_) != head.size())
    return make_error("cannot write " + path.string());
  return Status::Ok();
}

Status VideoSink::write(ImageView<const std::uint8_t> y, ImageView<const std::uint8_t> u,
                        ImageView<const std::uint8_t> v) {
  if (!out_) return make_error("video sink is not open");
  record_.clear();
  if (Status s = append_y4m_frame(header_, y, u, v, &record_); !s) return s;
  if (std::fwrite(record_.data(), 1, record_.size(), out_) != record_.size())
    return make_error("writing " + path_.string() + " failed" + (pipe_ ? " (ffmpeg stopped reading)" : ""));
  return Status::Ok();
}

Status VideoSink::close() {
  if (!out_) return Status::Ok();
  std::FILE* f = out_;
  out_ = nullptr;
  if (!pipe_) {
    if (std::fclose(f) != 0) return make_error("closing " + path_.string() + " failed");
    return Status::Ok();
  }
  const int status = ::pclose(f);
  if (status == -1 || !WIFEXITED(status) || WEXITSTATUS(status) != 0)
    return make_error("ffmpeg could not encode " + path_.string() + " (exit status " +
                      std::to_string(WIFEXITED(status) ? WEXITSTATUS(status) : -1) + ")");
  return Status::Ok();
}

}  // namespace st::overlay
