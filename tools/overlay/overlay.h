// scopetrack-overlay's work: every frame of a sequence with the tracked
// organ drawn over it, so a person can see what the tracker did.
// - the organ's silhouette (green) and, faintly, its visible triangles at
//   the tracked pose, rendered with the project's rasteriser in the ideal
//   image and mapped through the lens distortion into the captured frame;
// - the markers at the tracked pose (yellow dots) and at the ground truth
//   (magenta rings) when the sequence has them;
// - a red border on frames the tracker reported lost (orange: relocalised);
// - the frame number and state as text.
// Host tool code (allocates per frame where convenient).
#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <vector>

#include "core/geometry/camera.h"
#include "core/raster/rasterizer.h"
#include "core/base/result.h"
#include "core/formats/trajectory.h"
#include "hal/storage/sequence_loader.h"
#include "tools/overlay/overlay_draw.h"

namespace st::overlay {

struct OverlayStyle {
  bool wireframe = true;
  bool text = true;
  bool markers = true;
  Rgb silhouette{0, 255, 0};
  Rgb tracked_marker{255, 230, 0};
  Rgb truth_marker{255, 0, 255};
  Rgb lost_border{255, 0, 0};
  Rgb relocalised_border{255, 140, 0};
  double wireframe_alpha = 0.3;
  double fill_alpha = 0.0;  // > 0: the organ's area tinted with the silhouette colour
  bool state = true;        // the lost / relocalised border and, with text, the frame line
};

// What to draw on one frame.
struct FrameAnnotations {
  int index = 0;
  const SE3* T_model_camera = nullptr;     // tracked pose; nullptr: none
  const SE3* T_model_camera_gt = nullptr;  // ground truth; nullptr: none
  std::optional<FrameState> state;         // from frames.csv; nullopt: unknown
};

class OverlayRenderer {
 public:
  // Sizes the rasteriser (padded so that the organ is found in the corners
  // of a barrel-distorted frame) and the distortion lookup, once.
  Status configure(const LoadedSequence& sequence, const OverlayStyle& style);
  // Draws into the 4:2:0 planes of one frame (modified in place).
  void draw(const FrameAnnotations& a, ImageView<std::uint8_t> y, ImageView<std::uint8_t> u,
            ImageView<std::uint8_t> v);
  // Draws only the layer (transparent where nothing is drawn), for a viewer
  // that composites it itself.
  const OverlayLayer& draw_layer(const FrameAnnotations& a);
  // Organ labels of the last draw() with a pose (visible triangle id per
  // frame pixel, -1 where no organ): for tests.
  ImageView<const std::int32_t> labels() const { return labels_.cview(); }

 private:
  Status build_distortion_lookup();
  void render_labels(const SE3& T_model_camera);
  void draw_markers(const SE3& T_model_camera, Rgb colour, bool ring);
  void draw_state(const FrameAnnotations& a);

  OverlayStyle style_;
  CameraModel camera_;
  std::vector<Marker> markers_;
  int width_ = 0, height_ = 0;
  int pad_x_ = 0, pad_y_ = 0;  // raster margin around the ideal image
  Pinhole K_raster_;
  std::unique_ptr<MeshRasterizer> raster_;
  std::vector<std::int32_t> raster_index_;  // per frame pixel: raster pixel of its ideal position, or -1
  Image<std::int32_t> labels_;
  OverlayLayer layer_;
};

struct OverlayOptions {
  std::filesystem::path sequence_dir, run_dir, video_out;
  OverlayStyle style;
  int max_frames = -1;  // -1: all
};

struct OverlayReport {
  int frames = 0, frames_with_pose = 0, frames_with_groundtruth = 0;
  bool through_ffmpeg = false;
  std::string error;  // the video broke off: frames before it were written
};

Result<OverlayReport> render_overlay(const OverlayOptions& options);

}  // namespace st::overlay
