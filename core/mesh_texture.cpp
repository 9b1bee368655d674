#include "core/mesh_texture.h"

#include <algorithm>
#include <cmath>

#include "core/capacity.h"

namespace st {

void yuv_to_rgb(int y, int u, int v, bool full_range, std::uint8_t rgb[3]) {
  const float cb = static_cast<float>(u - 128), cr = static_cast<float>(v - 128);
  float r, g, b;
  if (full_range) {  // JPEG / JFIF: Y' 0..255, Cb Cr 0..255 around 128
    const float l = static_cast<float>(y);
    r = l + 1.402f * cr;
    g = l - 0.344136f * cb - 0.714136f * cr;
    b = l + 1.772f * cb;
  } else {  // studio swing: Y' 16..235, Cb Cr 16..240
    const float l = 1.164383f * static_cast<float>(y - 16);
    r = l + 1.596027f * cr;
    g = l - 0.391762f * cb - 0.812968f * cr;
    b = l + 2.017232f * cb;
  }
  const auto to8 = [](float x) { return static_cast<std::uint8_t>(std::clamp(std::lround(x), 0l, 255l)); };
  rgb[0] = to8(r);
  rgb[1] = to8(g);
  rgb[2] = to8(b);
}

Status MeshTexture::configure(const Mesh& mesh, const CameraModel& camera, const TextureConfig& config) {
  if (config.width <= 0 || config.height <= 0 || config.width > kMaxImageWidth || config.height > kMaxImageHeight)
    return make_error("texture: frame size out of range");
  if (config.max_weight < 1 || config.max_weight > 255) return make_error("texture: max_weight must be 1..255");
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
      sample_of_pixel_[static_cast<std::size_t>(ry * rw + rx)] = static_cast<std::int32_t>(y * config.width + x);
    }

  const auto n = static_cast<std::size_t>(mesh.triangle_count());
  sum_.assign(3 * n, 0.f);
  count_.assign(n, 0);
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
  if (!mono && (frame.u.width < (config_.width + 1) / 2 || frame.u.height < (config_.height + 1) / 2 ||
                frame.v.width < frame.u.width || frame.v.height < frame.u.height))
    return 0;
  raster_.render(T_camera_model, camera_.pinhole());
  accumulate(frame);
  update_touched();
  return static_cast<int>(changed_count_);
}

// Sums every covered raster pixel's colour into its triangle.
void MeshTexture::accumulate(const YuvFrameView& f) {
  const ImageView<const std::int32_t> ids = raster_.triangle_id();
  const bool mono = f.u.empty() || f.v.empty();
  const int w = config_.width;
  touched_count_ = 0;
  for (int ry = 0; ry < ids.height; ++ry) {
    const std::int32_t* id_row = ids.row(ry);
    const std::int32_t* sample_row = sample_of_pixel_.data() + static_cast<std::ptrdiff_t>(ry) * ids.width;
    for (int rx = 0; rx < ids.width; ++rx) {
      const std::int32_t t = id_row[rx], s = sample_row[rx];
      if (t < 0 || s < 0) continue;
      const int x = s % w, y = s / w;
      std::uint8_t rgb[3];
      const int luma = f.y(x, y);
      if (mono)
        rgb[0] = rgb[1] = rgb[2] = static_cast<std::uint8_t>(luma);
      else
        yuv_to_rgb(luma, f.u(x / 2, y / 2), f.v(x / 2, y / 2), config_.full_range, rgb);
      const auto ti = static_cast<std::size_t>(t);
      if (count_[ti]++ == 0) touched_[touched_count_++] = t;
      sum_[3 * ti] += rgb[0];
      sum_[3 * ti + 1] += rgb[1];
      sum_[3 * ti + 2] += rgb[2];
    }
  }
}

// Algorithm 1's update for every triangle seen this frame; clears the sums.
void MeshTexture::update_touched() {
  for (std::size_t k = 0; k < touched_count_; ++k) {
    const auto t = static_cast<std::size_t>(touched_[k]);
    const std::uint32_t n = count_[t];
    float* sum = &sum_[3 * t];
    if (n >= static_cast<std::uint32_t>(config_.min_pixels)) {
      const float w = weight_[t];
      float* c = &colour_[3 * t];
      std::uint8_t* c8 = &rgb8_[3 * t];
      bool changed = weight_[t] == 0;
      for (int ch = 0; ch < 3; ++ch) {
        c[ch] = (w * c[ch] + sum[ch] / static_cast<float>(n)) / (w + 1.f);
        const auto v = static_cast<std::uint8_t>(std::clamp(std::lround(c[ch]), 0l, 255l));
        changed = changed || v != c8[ch];
        c8[ch] = v;
      }
      weight_[t] = static_cast<std::uint8_t>(std::min(weight_[t] + 1, config_.max_weight));
      ++seen_[t];
      if (changed) changed_[changed_count_++] = {static_cast<std::uint32_t>(t), c8[0], c8[1], c8[2]};
    }
    count_[t] = 0;
    sum[0] = sum[1] = sum[2] = 0.f;
  }
}

}  // namespace st
