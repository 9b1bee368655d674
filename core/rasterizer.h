// Scanline mesh rasteriser: organ mask, depth and triangle id.
// The heart of the paper's contributions: the mask is the pseudo-
// segmentation, the depth initialises the map and gives every keyframe
// metric points, the triangle ids give exact visibility for texturing.
//
// configure() allocates every buffer once; render() and all helpers after it
// allocate nothing. Single-threaded: one instance per thread that renders.
#pragma once

#include <cstdint>
#include <vector>

#include "core/camera.h"
#include "core/image.h"
#include "core/mesh.h"
#include "core/result.h"
#include "core/se3.h"

namespace st {

struct RasterConfig {
  int width = 0;           // full-resolution image size, pixels
  int height = 0;
  int downscale = 1;       // 1, 2 or 4: the raster is width/downscale x height/downscale
  double near_mm = 1.0;    // near clipping plane, mm along the optical axis
  bool cull_backfaces = true;  // closed organ: back faces are never visible
};

class MeshRasterizer {
 public:
  // Copies the mesh (structure of arrays) and sizes every buffer.
  Status configure(const Mesh& mesh, const RasterConfig& config);

  // Renders the mesh seen from T_camera_model through the full-resolution
  // ideal pinhole K_full (scaled internally to the raster size).
  void render(const SE3& T_camera_model, const Pinhole& K_full);

  const RasterConfig& config() const { return config_; }
  // The pinhole of the raster (K_full scaled by 1/downscale).
  const Pinhole& camera() const { return camera_; }
  const SE3& T_camera_model() const { return T_camera_model_; }

  ImageView<const float> depth() const;              // mm along z; 0 where no organ
  ImageView<const std::int32_t> triangle_id() const; // -1 where no organ
  ImageView<const std::uint8_t> mask() const;        // 255 organ, 0 elsewhere
  int covered_pixels() const { return covered_pixels_; }

  // Full-resolution pixel -> raster pixel (pixel centres at integers).
  Vec2 full_to_raster(const Vec2& px_full) const;
  // Depth at a sub-pixel raster position: bilinear over the 4 neighbours if
  // all are covered by the same surface, else nearest covered pixel within
  // 0.5 px; false where the organ is not there.
  bool depth_at(const Vec2& px_raster, float* depth_mm) const;
  // Raster pixel + depth -> point in the model frame (through the last pose).
  Vec3 model_point(const Vec2& px_raster, double depth_mm) const;
  // Mask eroded (k < 0) or dilated (k > 0) by |k| pixels (square structuring
  // element) into a caller-owned buffer of the raster size.
  void morph_mask(int k, ImageView<std::uint8_t> out) const;
  // Ids of the triangles visible in the last render (at least one pixel),
  // written to out (capacity entries), sorted ascending; returns the count.
  int visible_triangles(std::int32_t* out, int capacity) const;

 private:
  // (implementation state: transformed vertices, buffers, scratch)
  RasterConfig config_;
  Pinhole camera_;
  SE3 T_camera_model_;
  int covered_pixels_ = 0;
};

}  // namespace st
