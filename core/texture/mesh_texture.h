// Mesh texturing, Algorithm 1 of the paper (docs/paper-notes.md): for a
// frame at its tracked pose, every triangle that is visible (the
// rasteriser's triangle-id buffer: occlusion exact) and front-facing (the
// rasteriser culls back faces by their winding on screen, which is the
// facing test against the pixel's ray) gets the mean colour c' of its
// pixels; its stored colour becomes c = (w c + c') / (w + 1), then
// w = min(w + 1, max_weight) (the cap, not the paper's misprinted max, keeps
// colours adapting).
//
// Frames are Y4M 4:2:0 Y'CbCr, BT.601: full range for C420jpeg (the
// simulator, ffmpeg's yuvj420p), studio range (16-235/240) for the other
// 4:2:0 tags (ffmpeg's yuv420p); Cmono gives grey.
//
// Lifecycle: configure() allocates every array (per triangle, per raster
// pixel) once; add_frame() allocates nothing. Single-threaded: one texture
// thread owns an instance (it is not the tracking thread).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "core/geometry/camera.h"
#include "core/image/image.h"
#include "core/mesh/mesh.h"
#include "core/raster/rasterizer.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

// One triangle's colour, 8-bit RGB.
struct TriangleRgb {
  std::uint32_t triangle = 0;
  std::uint8_t r = 0, g = 0, b = 0;
};

struct TextureConfig {
  int width = 0, height = 0;  // frame size = calibration size
  int downscale =
      1;  // 1, 2 or 4: the id buffer's resolution; a raster pixel samples the frame at its centre
  int max_weight = 10;  // Algorithm 1's cap on the running weight
  int min_pixels =
      3;  // a triangle seen on fewer raster pixels in a frame is left alone (edges, slivers)
  bool full_range = true;  // Y'CbCr range (see above)
};

// A 4:2:0 frame: y full size, u/v (w+1)/2 x (h+1)/2; u/v empty for mono.
struct YuvFrameView {
  GrayView y, u, v;
};

// BT.601 Y'CbCr -> RGB, clamped to 0..255 (the 8-bit form rounds).
void yuv_to_rgb(float y, float u, float v, bool full_range, float rgb[3]);
void yuv_to_rgb(int y, int u, int v, bool full_range, std::uint8_t rgb[3]);

class MeshTexture {
 public:
  // Copies the mesh into the rasteriser; precomputes where every raster
  // pixel samples the (distorted) frame.
  Status configure(const Mesh& mesh, const CameraModel& camera, const TextureConfig& config);
  // One frame at its tracked pose. Returns the number of triangles whose
  // 8-bit colour changed (listed in changed() until the next call). A frame
  // of another size than configured changes nothing. Allocates nothing.
  int add_frame(const YuvFrameView& frame, const SE3& T_camera_model);
  std::span<const TriangleRgb> changed() const { return {changed_.data(), changed_count_}; }

  int triangle_count() const { return static_cast<int>(weight_.size()); }
  // Frames that have coloured triangle t so far, capped at max_weight (0: never seen).
  int weight(int t) const { return weight_[static_cast<std::size_t>(t)]; }
  TriangleRgb colour(int t) const;
  // Frames counted per triangle without the cap (diagnostics and tests).
  int frames_seen(int t) const { return seen_[static_cast<std::size_t>(t)]; }
  const TextureConfig& config() const { return config_; }

 private:
  void accumulate(const YuvFrameView& frame);
  void update_touched();

  TextureConfig config_;
  CameraModel camera_;
  MeshRasterizer raster_;
  std::vector<std::int32_t>
      sample_of_pixel_;  // raster pixel -> frame pixel x | y << 16, -1 outside
  std::vector<std::uint32_t>
      sum_;  // per triangle: Y', Cb, Cr sums and the pixel count of this frame
  std::vector<std::int32_t> touched_;  // triangles with count_ > 0 this frame
  std::size_t touched_count_ = 0;
  std::vector<float> colour_;       // per triangle: running mean R, G, B (0..255)
  std::vector<std::uint8_t> rgb8_;  // per triangle: the colour as last reported
  std::vector<std::uint8_t> weight_;
  std::vector<std::uint32_t> seen_;
  std::vector<TriangleRgb> changed_;
  std::size_t changed_count_ = 0;
};

}  // namespace st
