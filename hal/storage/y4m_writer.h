// Writes a Y4M video (4:2:0 C420jpeg or Cmono) frame by frame to a file,
// or to stdout with path "-". open() sizes the one frame buffer; write()
// then allocates nothing.
#pragma once

#include <filesystem>
#include <string>

#include "core/image/image.h"
#include "core/base/result.h"
#include "core/formats/y4m.h"

namespace st {

class Y4mWriter {
 public:
  Y4mWriter() = default;
  ~Y4mWriter();
  Y4mWriter(const Y4mWriter&) = delete;
  Y4mWriter& operator=(const Y4mWriter&) = delete;

  // Only width, height, fps_num, fps_den and chroma of `header` are used.
  Status open(const std::filesystem::path& path, const Y4mHeader& header);
  // U and V are ignored (may be empty) for mono.
  Status write(ImageView<const std::uint8_t> y, ImageView<const std::uint8_t> u = {},
               ImageView<const std::uint8_t> v = {});
  Status close();
  int frames_written() const { return frames_; }
  const Y4mHeader& header() const { return header_; }

 private:
  Status write_all(std::string_view bytes);
  Y4mHeader header_;
  std::string record_;  // one FRAME record, capacity reserved at open
  std::string path_;
  int fd_ = -1;
  bool owns_fd_ = false;
  int frames_ = 0;
};

}  // namespace st
