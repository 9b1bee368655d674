// Where the overlay video goes: a .y4m file written directly, or any other
// container (.mp4, .mkv, ...) encoded by ffmpeg running as a subprocess
// that reads Y4M on its stdin. Host tool code.
#pragma once

#include <cstdio>
#include <filesystem>
#include <string>

#include "core/image/image.h"
#include "core/base/result.h"
#include "core/formats/y4m.h"

namespace st::overlay {

class VideoSink {
 public:
  VideoSink() = default;
  ~VideoSink();
  VideoSink(const VideoSink&) = delete;
  VideoSink& operator=(const VideoSink&) = delete;

  // 4:2:0 output of width x height at fps_num/fps_den.
  Status open(const std::filesystem::path& path, int width, int height, int fps_num, int fps_den);
  Status write(ImageView<const std::uint8_t> y, ImageView<const std::uint8_t> u,
               ImageView<const std::uint8_t> v);
  // Flushes and, for ffmpeg, waits for it: its failure is reported here.
  Status close();
  bool through_ffmpeg() const { return pipe_; }

 private:
  Y4mHeader header_;
  std::string record_;
  std::filesystem::path path_;
  std::FILE* out_ = nullptr;
  bool pipe_ = false;
};

// The ffmpeg command line for an output path (exposed for tests).
std::string ffmpeg_command(const std::filesystem::path& out_path);

}  // namespace st::overlay
