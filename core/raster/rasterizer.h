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

#include "core/geometry/camera.h"
#include "core/image/image.h"
#include "core/image/mask_morphology.h"
#include "core/mesh/mesh.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

namespace raster {
struct Target;
struct Counters;
struct FixedTriangle;
struct DepthPlane;
}  // namespace raster

struct RasterConfig {
  int width = 0;  // full-resolution image size, pixels
  int height = 0;
  int downscale = 1;           // 1, 2 or 4: the raster is width/downscale x height/downscale
  double near_mm = 1.0;        // near clipping plane, mm along the optical axis
  bool cull_backfaces = true;  // closed organ: back faces are never visible
  bool use_simd = true;        // false forces the portable forms of both kernels (the scanline
                               // span and the small-triangle box) and of the resolve pass
  bool allow_avx512 = true;    // with use_simd: the AVX-512 kernels where the CPU has them
};

// What the last render() did (for tests, the bench and diagnostics).
struct RasterStats {
  int triangles_outside = 0;   // rejected by the frustum test (all vertices beyond one plane)
  int triangles_culled = 0;    // back-facing, degenerate, or between pixel centres
  int triangles_clipped = 0;   // crossed the near plane or the guard band
  int triangles_drawn = 0;     // reached the scanline stage (clipped ones count once)
  std::int64_t fragments = 0;  // pixels inside drawn triangles, before the depth test
};

class MeshRasterizer {
 public:
  // Copies the mesh (structure of arrays) and sizes every buffer.
  Status configure(const Mesh& mesh, const RasterConfig& config);

  // Renders the mesh seen from T_camera_model through the full-resolution
  // ideal pinhole K_full (scaled internally to the raster size).
  // Defined degraded state: before configure(), or with a non-finite pose or
  // a pinhole without positive finite focal lengths, the render is empty.
  // Only K_full's intrinsics are used; the raster size comes from configure().
  void render(const SE3& T_camera_model, const Pinhole& K_full);
  const RasterStats& stats() const { return stats_; }
  // True if this build runs the SIMD kernels (config.use_simd permitting).
  static bool simd_available();
  // True if the AVX-512 kernels run here (x86-64 build, CPU with AVX-512F;
  // config.use_simd and config.allow_avx512 permitting).
  static bool avx512_available();

  const RasterConfig& config() const { return config_; }
  // The pinhole of the raster (K_full scaled by 1/downscale).
  const Pinhole& camera() const { return camera_; }
  const SE3& T_camera_model() const { return T_camera_model_; }

  ImageView<const float> depth() const;               // mm along z; 0 where no organ
  ImageView<const std::int32_t> triangle_id() const;  // -1 where no organ
  ImageView<const std::uint8_t> mask() const;         // 255 organ, 0 elsewhere
  int covered_pixels() const { return covered_pixels_; }
  // Triangles of the configured mesh (0 before configure()).
  int triangle_count() const { return static_cast<int>(tri_id_.size()); }

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
  // The image border neither erodes nor dilates (OpenCV's default). An out
  // of another size is left untouched. Uses internal scratch: not reentrant.
  void morph_mask(int k, ImageView<std::uint8_t> out) const;
  // Ids of the triangles visible in the last render (at least one pixel),
  // written to out (capacity entries), sorted ascending; returns the count.
  // If the count exceeds capacity, only the first capacity ids are written
  // (the return value still says how many there are).
  int visible_triangles(std::int32_t* out, int capacity) const;

  // Depth spread (relative) up to which 4 neighbours count as one surface in
  // depth_at(): a 2% step across one pixel is a fold or an occluding edge.
  static constexpr double kSameSurfaceRelDepth = 0.02;

 private:
  void order_for_locality(const Mesh& mesh);
  void clear_rows(int y_first, int y_last);
  raster::Target target();
  void transform_vertices();
  void draw_snapped(int t, bool front, const raster::Target& tgt, raster::Counters* counters);
  void draw_clipped(int t, const raster::Target& tgt, raster::Counters* counters);
  void emit(const raster::FixedTriangle& ft, const raster::DepthPlane& plane, std::int32_t id,
            const raster::Target& tgt, raster::Counters* counters);
  void resolve_rows(int y_first, int y_last);

  RasterConfig config_;
  Pinhole camera_;
  SE3 T_camera_model_;
  int covered_pixels_ = 0;
  RasterStats stats_;
  bool configured_ = false;
  bool rendered_ = false;
  bool use_avx512_ = false;  // the AVX-512 kernels (config and CPU permitting)
  int raster_width_ = 0, raster_height_ = 0;

  // The mesh, copied at configure().
  std::vector<float> model_x_, model_y_, model_z_;
  // corner_[j][k]: vertex j of the k-th triangle in draw order (see
  // order_for_locality), after the vertices' renumbering.
  std::vector<std::int32_t> corner_[3];
  std::vector<std::int32_t> tri_id_;  // draw order -> the mesh's triangle id
  // Per render, per vertex: camera frame (mm), frustum outcode, snapped
  // pixel position (1/4096 px; valid where the outcode has no clip bit).
  std::vector<double> cam_x_, cam_y_, cam_z_;
  std::vector<std::uint32_t> outcode_;  // raster_cull.h's bits
  std::vector<std::int32_t> snap_x_, snap_y_;
  // Output buffers, stride = raster width, padded at the end (SIMD groups).
  std::vector<float> depth_buf_;
  std::vector<std::int32_t> id_buf_;
  std::vector<std::uint8_t> mask_buf_;
  // Per raster row, the columns the last render wrote (cleared next time).
  std::vector<std::int32_t> dirty_x0_, dirty_x1_;
  // Scratch for the const helpers (sized at configure; single-threaded use).
  mutable std::vector<std::uint64_t> visible_bits_;
  mutable MorphBuffers morph_;
};

}  // namespace st
