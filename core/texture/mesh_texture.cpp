#include "core/texture/mesh_texture.h"

#include <algorithm>
#include <cmath>

#include "core/base/capacity.h"

namespace st {

void yuv_to_rgb(float y, float u, float v, bool full_range, float rgb[3]) {
  const float cb = u - 128.f, cr = v - 128.f;
  float l = y;
  if (full_range) {  // JPEG / JFIF: Y' 0..255, Cb Cr 0..255 around 128
    rgb[0] = l + 1.402f * cr;
    rgb[1] = l - 0.344136f * cb - 0.714136f * cr;
    rgb[2] = l + 1.772f * cb;
  } else {  // studio swing: Y' 16..235, Cb Cr 16..240
    l = 1.164383f * (y - 16.f);
    rgb[0] = l + 1.596027f * cr;
    rgb[1] = l - 0.391762f * cb - 0.812968f * cr;
    rgb[2] = l + 2.017232f * cb;
  }
  for (int c = 0; c < 3; ++c) rgb[c] = std::clamp(rgb[c], 0.f, 255.f);
}

void yuv_to_rgb(int y, int u, int v, bool full_range, std::uint8_t rgb[3]) {
  float f[3];
  yuv_to_rgb(static_cast<float>(y), static_cast<float>(u), static_cast<float>(v), full_range, f);
  for (int c = 0; c < 3; ++c) rgb[c] = static_cast<std::uint8_t>(std::lround(f[c]));
}

Status MeshTexture::configure(const Mesh& mesh, const CameraModel& camera,
                              const TextureConfig& config) {
  if (config.width <= 0 || config.height <= 0 || config.width > kMaxImageWidth ||
      config.height > kMaxImageHeight)
    return make_error("texture: frame size out of range");
  if (config.max_weight < 1 || config.max_weight > 255)
    return make_error("texture: max_weight must be 1..255");
  if (config.min_pixels < 1) return make_error("texture: min_pixels must be >= 1");
  if (Status s = CameraModel::validate(camera.pinhole(), camera.distortion()); !s) return s;
  RasterConfig rc;
  rc.width = config.width;
  rc.height = config.height;
  rc.downscale = config.downscale;
  rc.cull_backfaces = true;  // front-facing only
  if (Status s = raster_.configure(mesh, rc); !s) return s;
  config_ = config;
  camera_ = camera;

  // Raster pixel centre -> ideal full-resolution pixel -> distorted pixel of the frame.
  const int rw = config.width / config.downscale, rh = config.height / config.downscale;
  sample_of_pixel_.assign(static_cast<std::size_t>(rw) * static_cast<std::size_t>(rh), -1);
  const double ds = config.downscale;
  for (int ry = 0; ry < rh; ++ry)
    for (int rx = 0; rx < rw; ++rx) {
      const Vec2 ideal((rx + 0.5) * ds - 0.5, (ry + 0.5) * ds - 0.5);
      const Vec2 d = camera.distort_pixel(ideal);
      const long x = std::lround(d.x()), y = std::lround(d.y());
      if (!d.allFinite() || x < 0 || y < 0 || x >= config.width || y >= config.height) continue;
      sample_of_pixel_[static_cast<std::size_t>(ry * rw + rx)] =
          static_cast<std::int32_t>(x | (y << 16));
    }

  const auto n = static_cast<std::size_t>(mesh.triangle_count());
  sum_.assign(4 * n, 0);
  touched_.assign(n, 0);
  colour_.assign(3 * n, 0.f);
  rgb8_.assign(3 * n, 0);
  weight_.assign(n, 0);
  seen_.assign(n, 0);
  changed_.assign(n, TriangleRgb{});
  touched_count_ = changed_count_ = 0;
  return Status::Ok();
}

TriangleRgb MeshTexture::colour(int t) const {
  const auto i = static_cast<std::size_t>(t);
  return {static_cast<std::uint32_t>(t), rgb8_[3 * i], rgb8_[3 * i + 1], rgb8_[3 * i + 2]};
}

int MeshTexture::add_frame(const YuvFrameView& frame, const SE3& T_camera_model) {
  changed_count_ = 0;
  if (frame.y.width != config_.width || frame.y.height != config_.height || sum_.empty()) return 0;
  const bool mono = frame.u.empty() || frame.v.empty();
  if (!mono &&
      (frame.u.width < (config_.width + 1) / 2 || frame.u.height < (config_.height + 1) / 2 ||
       frame.v.width < frame.u.width || frame.v.height < frame.u.height))
    return 0;
  raster_.render(T_camera_model, camera_.pinhole());
  accumulate(frame);
  update_touched();
  return static_cast<int>(changed_count_);
}

// Sums every covered raster pixel's Y', Cb, Cr into its triangle. The
// conversion to RGB is linear (up to clamping), so the mean is converted
// once per triangle instead of once per pixel.
void MeshTexture::accumulate(const YuvFrameView& f) {
  const ImageView<const std::int32_t> ids = raster_.triangle_id();
  const bool mono = f.u.empty() || f.v.empty();
  touched_count_ = 0;
  std::uint32_t* sums = sum_.data();
  for (int ry = 0; ry < ids.height; ++ry) {
    const std::int32_t* id_row = ids.row(ry);
    const std::int32_t* sample_row =
        sample_of_pixel_.data() + static_cast<std::ptrdiff_t>(ry) * ids.width;
    for (int rx = 0; rx < ids.width; ++rx) {
      const std::int32_t t = id_row[rx], s = sample_row[rx];
      if (t < 0 || s < 0) continue;
      const int x = s & 0xffff, y = s >> 16;
      std::uint32_t* acc = sums + 4 * static_cast<std::ptrdiff_t>(t);
      if (acc[3]++ == 0) touched_[touched_count_++] = t;
      acc[0] += f.y(x, y);
      acc[1] += mono ? 128u : f.u(x >> 1, y >> 1);
      acc[2] += mono ? 128u : f.v(x >> 1, y >> 1);
    }
  }
}

// Algorithm 1's update for every triangle seen this frame; clears the sums.
void MeshTexture::update_touched() {
  for (std::size_t k = 0; k < touched_count_; ++k) {
    const auto t = static_cast<std::size_t>(touched_[k]);
    std::uint32_t* acc = &sum_[4 * t];
    const std::uint32_t n = acc[3];
    if (n >= static_cast<std::uint32_t>(config_.min_pixels)) {
      const float inv_n = 1.f / static_cast<float>(n);
      float mean_rgb[3];
      yuv_to_rgb(static_cast<float>(acc[0]) * inv_n, static_cast<float>(acc[1]) * inv_n,
                 static_cast<float>(acc[2]) * inv_n, config_.full_range, mean_rgb);
      const float w = weight_[t];
      float* c = &colour_[3 * t];
      std::uint8_t* c8 = &rgb8_[3 * t];
      bool changed = weight_[t] == 0;
      for (int ch = 0; ch < 3; ++ch) {
        c[ch] = (w * c[ch] + mean_rgb[ch]) / (w + 1.f);
        const auto v = static_cast<std::uint8_t>(std::clamp(std::lround(c[ch]), 0l, 255l));
        changed = changed || v != c8[ch];
        c8[ch] = v;
      }
      weight_[t] = static_cast<std::uint8_t>(std::min(weight_[t] + 1, config_.max_weight));
      ++seen_[t];
      if (changed)
        changed_[changed_count_++] = {static_cast<std::uint32_t>(t), c8[0], c8[1], c8[2]};
    }
    acc[0] = acc[1] = acc[2] = acc[3] = 0;
  }
}

}  // namespace st
