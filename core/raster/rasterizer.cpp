#include "core/raster/rasterizer.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/base/capacity.h"
#include "core/image/mask_morphology.h"
#include "core/raster/clip.h"
#include "core/raster/cull.h"
#include "core/raster/triangle.h"

namespace st {
namespace {

using raster::ClipPlane;
using raster::ClipPoint;

constexpr int kBufferPad = raster::kTargetPad;

// Planes through the camera centre with lo <= u <= hi and lo_v <= v <= hi_v
// (for z > 0), in the order left, right, top, bottom; inside >= 0.
void side_planes(const Pinhole& K, double lo_u, double hi_u, double lo_v, double hi_v,
                 ClipPlane* out) {
  out[0] = {K.fx, 0, K.cx - lo_u, 0};
  out[1] = {-K.fx, 0, hi_u - K.cx, 0};
  out[2] = {0, K.fy, K.cy - lo_v, 0};
  out[3] = {0, -K.fy, hi_v - K.cy, 0};
}

// Near plane, then the guard band: the clip planes in outcode bit order.
void clip_planes(const Pinhole& K, double near_mm, ClipPlane* out) {
  out[0] = {0, 0, 1, -near_mm};
  const double g = raster::kGuardBandPx;
  side_planes(K, -g, K.width - 1 + g, -g, K.height - 1 + g, out + 1);
}

// 1/z of the triangle's plane is affine in the pixel coordinates: with
// n = (p1 - p0) x (p2 - p0), d = n . p0 and the ray r(u, v) of a pixel,
// z n . r = d, so 1/z = n . r(u, v) / d. Exact for clipped pieces as well.
bool depth_plane(const ClipPoint& p0, const ClipPoint& p1, const ClipPoint& p2, const Pinhole& K,
                 double z_min, double z_max, raster::DepthPlane* plane, double* d_out) {
  const double ax = p1.x - p0.x, ay = p1.y - p0.y, az = p1.z - p0.z;
  const double bx = p2.x - p0.x, by = p2.y - p0.y, bz = p2.z - p0.z;
  const double nx = ay * bz - az * by, ny = az * bx - ax * bz, nz = ax * by - ay * bx;
  const double d = nx * p0.x + ny * p0.y + nz * p0.z;
  *d_out = d;
  if (!(std::abs(d) > 0.0) || !std::isfinite(d)) return false;  // plane through the eye
  // One division per triangle: 1/fx and 1/fy are folded in through d fx fy.
  const double inv_dff = 1.0 / (d * K.fx * K.fy);
  const double ax_ = nx * K.fy * inv_dff, ay_ = ny * K.fx * inv_dff;  // nx/(fx d), ny/(fy d)
  plane->gx = ax_;
  plane->gy = ay_;
  plane->c = nz * K.fx * K.fy * inv_dff - ax_ * K.cx - ay_ * K.cy;
  plane->iz_min = static_cast<float>(1.0 / z_max);
  plane->iz_max = static_cast<float>(1.0 / z_min);
  return true;
}

}  // namespace

Status MeshRasterizer::configure(const Mesh& mesh, const RasterConfig& config) {
  configured_ = rendered_ = false;
  if (config.width <= 0 || config.height <= 0 || config.width > kMaxImageWidth ||
      config.height > kMaxImageHeight)
    return make_error("rasteriser: image size " + std::to_string(config.width) + "x" +
                      std::to_string(config.height) + " outside 1x1.." +
                      std::to_string(kMaxImageWidth) + "x" + std::to_string(kMaxImageHeight));
  if (config.downscale != 1 && config.downscale != 2 && config.downscale != 4)
    return make_error("rasteriser: downscale must be 1, 2 or 4, got " +
                      std::to_string(config.downscale));
  if (config.width < config.downscale || config.height < config.downscale)
    return make_error("rasteriser: image smaller than one raster pixel at this downscale");
  if (!(config.near_mm > 0.0) || !std::isfinite(config.near_mm))
    return make_error("rasteriser: near_mm must be positive and finite");
  const std::size_t nv = mesh.x.size();
  if (mesh.y.size() != nv || mesh.z.size() != nv)
    return make_error("rasteriser: mesh x/y/z arrays differ in length");
  if (mesh.tri.size() % 3 != 0)
    return make_error("rasteriser: mesh index array is not a multiple of 3");
  if (nv == 0 || mesh.tri.empty()) return make_error("rasteriser: mesh has no triangles");
  if (static_cast<std::int64_t>(nv) > kMaxMeshVertices || mesh.triangle_count() > kMaxMeshTriangles)
    return make_error("rasteriser: mesh larger than the compile-time capacity");
  for (std::int32_t i : mesh.tri)
    if (i < 0 || static_cast<std::size_t>(i) >= nv)
      return make_error("rasteriser: triangle index " + std::to_string(i) + " outside 0.." +
                        std::to_string(nv - 1));
  for (std::size_t i = 0; i < nv; ++i)
    if (!std::isfinite(mesh.x[i]) || !std::isfinite(mesh.y[i]) || !std::isfinite(mesh.z[i]))
      return make_error("rasteriser: vertex " + std::to_string(i) + " is not finite");

  config_ = config;
  use_avx512_ = config.use_simd && config.allow_avx512 && raster::avx512_available();
  raster_width_ = config.width / config.downscale;
  raster_height_ = config.height / config.downscale;
  model_x_ = mesh.x;
  model_y_ = mesh.y;
  model_z_ = mesh.z;
  order_for_locality(mesh);
  cam_x_.assign(nv, 0.0);
  cam_y_.assign(nv, 0.0);
  cam_z_.assign(nv, 0.0);
  outcode_.assign(nv, 0);
  snap_x_.assign(nv, 0);
  snap_y_.assign(nv, 0);
  const std::size_t pixels = static_cast<std::size_t>(raster_width_) * raster_height_;
  depth_buf_.assign(pixels + kBufferPad, 0.0f);
  id_buf_.assign(pixels + kBufferPad, -1);
  mask_buf_.assign(pixels + kBufferPad, 0);
  dirty_x0_.assign(raster_height_, raster_width_);
  dirty_x1_.assign(raster_height_, -1);
  visible_bits_.assign((tri_id_.size() + 63) / 64, 0);
  morph_.configure(raster_width_, raster_height_);
  covered_pixels_ = 0;
  stats_ = {};
  configured_ = true;
  return Status::Ok();
}

// Spreads the bits of a 10-bit value three apart (Morton code helper).
static std::uint32_t spread3(std::uint32_t v) {
  v &= 0x3FF;
  v = (v | (v << 16)) & 0x030000FF;
  v = (v | (v << 8)) & 0x0300F00F;
  v = (v | (v << 4)) & 0x030C30C3;
  v = (v | (v << 2)) & 0x09249249;
  return v;
}

// Draw order: triangles sorted along a Morton curve of their model-frame
// centroids, so consecutive triangles land near each other in the image and
// the depth/id rows they touch are still in cache (the CT liver's own order
// jumps ~40 mm between consecutive faces). Ids stay the mesh's.
void MeshRasterizer::order_for_locality(const Mesh& mesh) {
  const int n = mesh.triangle_count();
  const auto [x0, x1] = std::minmax_element(mesh.x.begin(), mesh.x.end());
  const auto [y0, y1] = std::minmax_element(mesh.y.begin(), mesh.y.end());
  const auto [z0, z1] = std::minmax_element(mesh.z.begin(), mesh.z.end());
  const float lo[3] = {*x0, *y0, *z0};
  const float ext = std::max({*x1 - *x0, *y1 - *y0, *z1 - *z0, 1e-6f});
  std::vector<std::uint64_t> keys(static_cast<std::size_t>(n));
  for (int t = 0; t < n; ++t) {
    std::uint32_t code = 0;
    for (int a = 0; a < 3; ++a) {
      const std::vector<float>& c = a == 0 ? mesh.x : a == 1 ? mesh.y : mesh.z;
      const float centroid =
          (c[mesh.tri[3 * t]] + c[mesh.tri[3 * t + 1]] + c[mesh.tri[3 * t + 2]]) / 3.0f;
      const float q = (centroid - lo[a]) / ext * 1023.0f;
      code |= spread3(static_cast<std::uint32_t>(std::clamp(q, 0.0f, 1023.0f))) << a;
    }
    keys[t] = (std::uint64_t{code} << 32) | static_cast<std::uint32_t>(t);
  }
  std::sort(keys.begin(), keys.end());
  // Vertices renumbered in order of first use by the sorted triangles, so
  // that the per-vertex arrays are read almost in sequence as well.
  const std::size_t nv = mesh.x.size();
  std::vector<std::int32_t> renumber(nv, -1);
  std::int32_t next = 0;
  for (std::vector<std::int32_t>& c : corner_) c.resize(static_cast<std::size_t>(n));
  tri_id_.resize(static_cast<std::size_t>(n));
  for (int k = 0; k < n; ++k) {
    const auto t = static_cast<std::int32_t>(keys[k] & 0xFFFFFFFFu);
    tri_id_[k] = t;
    for (int j = 0; j < 3; ++j) {
      std::int32_t& v = renumber[static_cast<std::size_t>(mesh.tri[3 * t + j])];
      if (v < 0) v = next++;
      corner_[j][k] = v;
    }
  }
  for (std::int32_t& v : renumber)
    if (v < 0) v = next++;  // vertices no triangle uses
  for (std::size_t i = 0; i < nv; ++i) {
    const auto v = static_cast<std::size_t>(renumber[i]);
    model_x_[v] = mesh.x[i];
    model_y_[v] = mesh.y[i];
    model_z_[v] = mesh.z[i];
  }
}

bool MeshRasterizer::simd_available() { return raster::simd_enabled(); }
bool MeshRasterizer::avx512_available() { return raster::avx512_available(); }

// Only what the last render wrote (and resets that record): with the organ
// in view this is about the covered area rather than the whole image.
void MeshRasterizer::clear_rows(int y_first, int y_last) {
  for (int y = y_first; y <= y_last; ++y) {
    const int x0 = dirty_x0_[y], x1 = dirty_x1_[y];
    if (x0 > x1) continue;
    const std::size_t a = static_cast<std::size_t>(y) * raster_width_ + x0;
    const std::size_t n = static_cast<std::size_t>(x1 - x0 + 1);
    std::fill_n(depth_buf_.begin() + a, n, 0.0f);
    std::fill_n(id_buf_.begin() + a, n, -1);
    std::fill_n(mask_buf_.begin() + a, n, std::uint8_t{0});
    dirty_x0_[y] = raster_width_;
    dirty_x1_[y] = -1;
  }
}

// Depth from 1/z, the mask and the covered count over what this render wrote.
void MeshRasterizer::resolve_rows(int y_first, int y_last) {
  for (int y = y_first; y <= y_last; ++y) {
    const int x0 = dirty_x0_[y], x1 = dirty_x1_[y];
    if (x0 > x1) continue;
    const std::size_t row = static_cast<std::size_t>(y) * raster_width_;
    covered_pixels_ += raster::resolve_row(depth_buf_.data() + row, mask_buf_.data() + row, x0,
                                           x1, config_.use_simd, use_avx512_);
  }
}

raster::Target MeshRasterizer::target() {
  raster::Target t;
  t.depth = depth_buf_.data();
  t.triangle_id = id_buf_.data();
  t.mask = mask_buf_.data();
  t.width = raster_width_;
  t.height = raster_height_;
  t.stride = raster_width_;
  t.use_simd = config_.use_simd;
  t.use_avx512 = use_avx512_;
  t.dirty_x0 = dirty_x0_.data();
  t.dirty_x1 = dirty_x1_.data();
  return t;
}

void MeshRasterizer::render(const SE3& T_camera_model, const Pinhole& K_full) {
  T_camera_model_ = T_camera_model;
  const double s = 1.0 / config_.downscale;
  camera_ = K_full.scaled(s, raster_width_, raster_height_);
  covered_pixels_ = 0;
  stats_ = {};
  rendered_ = configured_;
  if (!configured_) return;
  const bool intrinsics_ok = K_full.fx > 0 && K_full.fy > 0 && std::isfinite(K_full.fx) &&
                             std::isfinite(K_full.fy) && std::isfinite(K_full.cx) &&
                             std::isfinite(K_full.cy);
  if (!intrinsics_ok || !T_camera_model.all_finite()) {
    clear_rows(0, raster_height_ - 1);
    return;
  }
  transform_vertices();
  const raster::Target tgt = target();
  raster::Counters counters;
  const int n = triangle_count();
  clear_rows(0, raster_height_ - 1);
  raster::CullInput cull;
  cull.v0 = corner_[0].data();
  cull.v1 = corner_[1].data();
  cull.v2 = corner_[2].data();
  cull.outcode = outcode_.data();
  cull.snap_x = snap_x_.data();
  cull.snap_y = snap_y_.data();
  cull.width = tgt.width;
  cull.height = tgt.height;
  cull.cull_backfaces = config_.cull_backfaces;
  // The trivial tests a batch at a time, then the survivors in draw order.
  for (int t0 = 0; t0 < n; t0 += raster::kCullBatch) {
    raster::CullBatch batch;
    raster::classify(cull, t0, std::min(raster::kCullBatch, n - t0), use_avx512_, &batch);
    stats_.triangles_outside += batch.outside;
    stats_.triangles_culled += batch.culled;
    for (std::uint32_t bits = batch.draw | batch.clip; bits != 0; bits &= bits - 1) {
      const int k = __builtin_ctz(bits);
      if (batch.clip >> k & 1u)
        draw_clipped(t0 + k, tgt, &counters);
      else
        draw_snapped(t0 + k, (batch.front >> k & 1u) != 0, tgt, &counters);
    }
  }
  resolve_rows(0, raster_height_ - 1);
  stats_.fragments = counters.fragments;
}

// One screen-space triangle: small ones (most of a dense organ mesh) by
// the bounding-box kernel, the rest by the scanline walk.
void MeshRasterizer::emit(const raster::FixedTriangle& ft, const raster::DepthPlane& plane,
                          std::int32_t id, const raster::Target& tgt, raster::Counters* counters) {
  if (raster::draw_small(ft, plane, id, tgt, counters)) return;
  raster::PreparedTriangle p;
  if (raster::prepare(ft, plane, id, tgt, &p)) raster::draw_rows(&p, tgt.height - 1, tgt, counters);
}

// Camera-frame coordinates, outcodes and snapped positions of every vertex,
// once per render.
void MeshRasterizer::transform_vertices() {
  const Mat3& R = T_camera_model_.rotation();
  const Vec3& t = T_camera_model_.translation();
  const Pinhole& K = camera_;
  raster::VertexPass pass;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 3; ++c) pass.R[3 * r + c] = R(r, c);
    pass.t[r] = t[r];
  }
  pass.fx = K.fx;
  pass.fy = K.fy;
  pass.cx = K.cx;
  pass.cy = K.cy;
  pass.near_mm = config_.near_mm;
  const double g = raster::kGuardBandPx;
  pass.guard_lo = -g;
  pass.guard_hi_u = K.width - 1 + g;
  pass.guard_hi_v = K.height - 1 + g;
  pass.in_lo = -1.0;
  pass.in_hi_u = K.width;
  pass.in_hi_v = K.height;
  ClipPlane reject[4];
  side_planes(K, pass.in_lo, pass.in_hi_u, pass.in_lo, pass.in_hi_v, reject);
  for (int k = 0; k < 4; ++k) {
    pass.reject_plane[k][0] = reject[k].a;
    pass.reject_plane[k][1] = reject[k].b;
    pass.reject_plane[k][2] = reject[k].c;
    pass.reject_plane[k][3] = reject[k].d;
  }
  raster::VertexArrays v;
  v.model_x = model_x_.data();
  v.model_y = model_y_.data();
  v.model_z = model_z_.data();
  v.x = cam_x_.data();
  v.y = cam_y_.data();
  v.z = cam_z_.data();
  v.outcode = outcode_.data();
  v.snap_x = snap_x_.data();
  v.snap_y = snap_y_.data();
  v.count = static_cast<int>(model_x_.size());
  raster::transform_vertices(pass, v, use_avx512_);
}

// A triangle that passed the trivial tests (raster::classify): snapped,
// inside the guard band, facing as required, covering a pixel centre.
void MeshRasterizer::draw_snapped(int t, bool front, const raster::Target& tgt,
                                  raster::Counters* counters) {
  const std::int32_t i0 = corner_[0][t], i1 = corner_[1][t], i2 = corner_[2][t];
  const std::int64_t x0 = snap_x_[i0], y0 = snap_y_[i0], x1 = snap_x_[i1], y1 = snap_y_[i1],
                     x2 = snap_x_[i2], y2 = snap_y_[i2];
  const ClipPoint p0{cam_x_[i0], cam_y_[i0], cam_z_[i0]}, p1{cam_x_[i1], cam_y_[i1], cam_z_[i1]},
      p2{cam_x_[i2], cam_y_[i2], cam_z_[i2]};
  raster::DepthPlane plane;
  double d;
  if (!depth_plane(p0, p1, p2, camera_, std::min({p0.z, p1.z, p2.z}), std::max({p0.z, p1.z, p2.z}),
                   &plane, &d)) {
    ++stats_.triangles_culled;
    return;
  }
  // Positive area for the edge walker: swap two vertices of front faces.
  const raster::FixedTriangle ft = front ? raster::FixedTriangle{{x0, x2, x1}, {y0, y2, y1}}
                                         : raster::FixedTriangle{{x0, x1, x2}, {y0, y1, y2}};
  ++stats_.triangles_drawn;
  emit(ft, plane, tri_id_[t], tgt, counters);
}

// Near-plane / guard-band crossing: clip in the camera frame, then draw the
// convex remainder as a fan (its inner edges are shared exactly, so the fill
// rule covers every pixel once). All pieces use the original triangle's plane.
void MeshRasterizer::draw_clipped(int t, const raster::Target& tgt, raster::Counters* counters) {
  const std::int32_t i0 = corner_[0][t], i1 = corner_[1][t], i2 = corner_[2][t];
  ClipPoint poly[raster::kMaxClipVertices] = {{cam_x_[i0], cam_y_[i0], cam_z_[i0]},
                                              {cam_x_[i1], cam_y_[i1], cam_z_[i1]},
                                              {cam_x_[i2], cam_y_[i2], cam_z_[i2]}};
  raster::DepthPlane plane;
  double d = 0;
  // Orientation from 3D (the eye sees the front side where d = n . p0 < 0).
  depth_plane(poly[0], poly[1], poly[2], camera_, 1.0, 1.0, &plane, &d);
  const bool front = d < 0;
  if (!(d != 0.0) || (!front && config_.cull_backfaces)) {
    ++stats_.triangles_culled;
    return;
  }
  ClipPlane planes[raster::kMaxClipPlanes];
  clip_planes(camera_, config_.near_mm, planes);
  const int n = raster::clip_polygon(poly, 3, planes, raster::kOutClipMask);
  if (n == 0) {
    ++stats_.triangles_outside;
    return;
  }
  std::int64_t sx[raster::kMaxClipVertices], sy[raster::kMaxClipVertices];
  double z_min = poly[0].z, z_max = poly[0].z;
  for (int k = 0; k < n; ++k) {
    sx[k] = raster::snap(camera_.fx * poly[k].x / poly[k].z + camera_.cx);
    sy[k] = raster::snap(camera_.fy * poly[k].y / poly[k].z + camera_.cy);
    z_min = std::min(z_min, poly[k].z);
    z_max = std::max(z_max, poly[k].z);
  }
  const ClipPoint p0{cam_x_[i0], cam_y_[i0], cam_z_[i0]}, p1{cam_x_[i1], cam_y_[i1], cam_z_[i1]},
      p2{cam_x_[i2], cam_y_[i2], cam_z_[i2]};
  if (!depth_plane(p0, p1, p2, camera_, z_min, z_max, &plane, &d)) return;
  ++stats_.triangles_clipped;
  ++stats_.triangles_drawn;
  for (int k = 1; k + 1 < n; ++k) {
    const std::int64_t area =
        (sx[k] - sx[0]) * (sy[k + 1] - sy[0]) - (sy[k] - sy[0]) * (sx[k + 1] - sx[0]);
    if (area == 0 || (area < 0) != front) continue;  // collapsed by snapping
    const raster::FixedTriangle ft =
        front ? raster::FixedTriangle{{sx[0], sx[k + 1], sx[k]}, {sy[0], sy[k + 1], sy[k]}}
              : raster::FixedTriangle{{sx[0], sx[k], sx[k + 1]}, {sy[0], sy[k], sy[k + 1]}};
    emit(ft, plane, tri_id_[t], tgt, counters);
  }
}

ImageView<const float> MeshRasterizer::depth() const {
  if (!configured_) return {};
  return ImageView<const float>(depth_buf_.data(), raster_width_, raster_height_);
}
ImageView<const std::int32_t> MeshRasterizer::triangle_id() const {
  if (!configured_) return {};
  return ImageView<const std::int32_t>(id_buf_.data(), raster_width_, raster_height_);
}
ImageView<const std::uint8_t> MeshRasterizer::mask() const {
  if (!configured_) return {};
  return ImageView<const std::uint8_t>(mask_buf_.data(), raster_width_, raster_height_);
}

Vec2 MeshRasterizer::full_to_raster(const Vec2& px_full) const {
  const double s = 1.0 / config_.downscale;
  return {(px_full.x() + 0.5) * s - 0.5, (px_full.y() + 0.5) * s - 0.5};
}

bool MeshRasterizer::depth_at(const Vec2& px_raster, float* depth_mm) const {
  if (!rendered_ || !px_raster.allFinite()) return false;
  const ImageView<const float> D = depth();
  const double x = px_raster.x(), y = px_raster.y();
  if (x < -0.5 || y < -0.5 || x >= D.width - 0.5 || y >= D.height - 0.5) return false;
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 >= 0 && y0 >= 0 && x0 + 1 < D.width && y0 + 1 < D.height) {
    const double d00 = D(x0, y0), d10 = D(x0 + 1, y0), d01 = D(x0, y0 + 1), d11 = D(x0 + 1, y0 + 1);
    const double lo = std::min({d00, d10, d01, d11}), hi = std::max({d00, d10, d01, d11});
    if (lo > 0.0 && hi - lo <= kSameSurfaceRelDepth * lo) {
      const double ax = x - x0, ay = y - y0;
      *depth_mm = static_cast<float>((1 - ay) * ((1 - ax) * d00 + ax * d10) +
                                     ay * ((1 - ax) * d01 + ax * d11));
      return true;
    }
  }
  const int xn = static_cast<int>(std::floor(x + 0.5)), yn = static_cast<int>(std::floor(y + 0.5));
  if (!D.contains(xn, yn) || D(xn, yn) <= 0.0f) return false;
  *depth_mm = D(xn, yn);
  return true;
}

Vec3 MeshRasterizer::model_point(const Vec2& px_raster, double depth_mm) const {
  const Vec3 p_camera = camera_.unproject(px_raster, depth_mm);
  const Mat3& R = T_camera_model_.rotation();
  return R.transpose() * (p_camera - T_camera_model_.translation());
}

void MeshRasterizer::morph_mask(int k, ImageView<std::uint8_t> out) const {
  if (!configured_ || out.empty() || out.width != raster_width_ || out.height != raster_height_)
    return;
  morph_square(mask(), k, out, morph_.scratch(raster_width_, raster_height_));
}

int MeshRasterizer::visible_triangles(std::int32_t* out, int capacity) const {
  if (!rendered_) return 0;
  std::fill(visible_bits_.begin(), visible_bits_.end(), 0);
  // Only the columns the render wrote (the rest holds -1).
  std::int32_t last = -1;
  for (int y = 0; y < raster_height_; ++y) {
    const std::int32_t* row = id_buf_.data() + static_cast<std::size_t>(y) * raster_width_;
    for (int x = dirty_x0_[y]; x <= dirty_x1_[y]; ++x) {
      const std::int32_t id = row[x];
      if (id == last || id < 0) continue;
      last = id;
      visible_bits_[static_cast<std::size_t>(id) >> 6] |= std::uint64_t{1} << (id & 63);
    }
  }
  int count = 0;
  for (std::size_t w = 0; w < visible_bits_.size(); ++w) {
    for (std::uint64_t bits = visible_bits_[w]; bits; bits &= bits - 1) {
      if (count < capacity && out)
        out[count] = static_cast<std::int32_t>(w * 64 + __builtin_ctzll(bits));
      ++count;
    }
  }
  return count;
}

}  // namespace st
