// What scopetrack-studio sends a page besides JSON: video frames as JPEG
// (read in order from the sequence's Y4M, reopened to go back), the
// overlay layer as an RGBA PNG, the mesh as flat arrays. Host tool code.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>

#include "core/base/result.h"
#include "core/geometry/se3.h"
#include "core/mesh/mesh.h"
#include "hal/capture/y4m_reader.h"
#include "hal/storage/sequence_loader.h"
#include "tools/overlay/overlay.h"
#include "tools/overlay/overlay_draw.h"
#include "tools/studio/web_server.h"

namespace st::studio {

// Frames of a Y4M file by index: forward reads continue, an earlier frame
// reopens the file.
class VideoFrames {
 public:
  Status open(const std::filesystem::path& path);
  // The frame; errors: past the end (says how many frames the video has), a
  // truncated or corrupt frame (the reader's message).
  Result<FrameRef> frame(int index);
  const Y4mHeader& header() const { return reader_.header(); }
  // Frames in the file from its size (-1 when not a plain file or the size
  // does not divide).
  int count() const { return count_; }

 private:
  std::filesystem::path path_;
  Y4mReader reader_;
  FrameRef current_;
  bool has_current_ = false;
  int count_ = -1;
};

// A 4:2:0 (or mono) frame as JPEG, full-range BT.601 as the video carries it.
std::string encode_jpeg(const FrameRef& frame, int quality = 90);
// The layer as an RGBA PNG (alpha kept).
std::string encode_png(const overlay::OverlayLayer& layer);
// BinaryKind::kMesh's payload: uint32 nv, uint32 nt, float32 xyz per vertex,
// uint32 indices per triangle, little-endian.
std::string mesh_payload(const Mesh& mesh);
// A rigid transform as 16 row-major JSON numbers.
std::string matrix_json(const SE3& T);
// The "info" message a page gets first: the mode, the sequence's folder
// name, size, frames, the frame shown, fps, whether it has ground truth,
// T_camera_model_init, K and the distortion; extra_fields (",\"key\":value"
// pairs, the mode's own) are appended as they are.
std::string info_json(const LoadedSequence& seq, std::string_view mode, int frames, int frame,
                      std::string_view extra_fields);
// How the studio draws the organ: a light fill under the outline, no state
// border, no text (the page shows those itself).
overlay::OverlayStyle studio_overlay_style();

}  // namespace st::studio
