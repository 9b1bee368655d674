// SceneRenderer: per-frame work (renderer.h). Allocation-free.
#include <algorithm>
#include <cmath>

#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>

#include "tools/sim/renderer.h"
#include "tools/sim/rng.h"

namespace st::sim {
namespace {

constexpr float kAmbient = 0.05f;  // inter-reflections: shadowed tissue is not black

}  // namespace

void SceneRenderer::render_subframe(const WorldState& state, float weight, bool first, bool keep_labels) {
  const SE3 T_camera_world = state.T_world_camera.inverse();
  organ_raster_.render(T_camera_world * state.T_world_model, K_ideal_);
  background_raster_.render(T_camera_world, K_ideal_);
  instrument_raster_.render(T_camera_world * state.T_world_instrument, K_ideal_);
  auto to_xf = [](const SE3& T) {
    return Xf{T.rotation().cast<float>(), T.translation().cast<float>()};
  };
  const Xf T_mesh_camera[3] = {to_xf(state.T_model_camera()), to_xf(state.T_world_camera),
                               to_xf(state.T_world_instrument.inverse() * state.T_world_camera)};
  // Auto exposure, as a scope's camera control unit does: the gain follows
  // the distance to the organ (most of the way), so a close organ is not
  // blown out and a far one not black. Irradiance = scale / depth^2.
  // The metered distance: mean depth of the organ pixels (every 8th pixel
  // of every 8th row), or the organ centre's distance when none is seen.
  double d_organ = (T_camera_world * (state.T_world_model * organ_centre_model_)).norm();
  const ImageView<const float> od = organ_raster_.depth();
  double sum = 0;
  int n = 0;
  for (int y = 0; y < od.height; y += 8)
    for (int x = 0; x < od.width; x += 8)
      if (od(x, y) > 0.0f) {
        sum += static_cast<double>(od(x, y));
        ++n;
      }
  if (n > 20) d_organ = sum / n;
  const double d_ref = 90.0 * std::pow(std::max(d_organ, 20.0) / 90.0, 0.85);
  const auto irradiance = static_cast<float>(settings_.exposure * d_ref * d_ref);
  composite(keep_labels);
  shade_background_half(T_mesh_camera[1], irradiance);
  shade_rows(T_mesh_camera, irradiance, weight, first);
}

// The nearest surface per ideal pixel (the background raster is half
// size), and which half-resolution background pixels its bilinear taps
// read: only those are shaded (most of the background is behind the organ).
void SceneRenderer::composite(bool keep_labels) {
  const ImageView<const float> depth[3] = {organ_raster_.depth(), background_raster_.depth(),
                                           instrument_raster_.depth()};
  const ImageView<const std::int32_t> ids[3] = {organ_raster_.triangle_id(), background_raster_.triangle_id(),
                                                instrument_raster_.triangle_id()};
  const std::uint8_t label_of[3] = {kLabelOrgan, kLabelBackground, kLabelInstrument};
  const int half_w = depth[1].width;
  background_need_.setTo(cv::Scalar::all(0));
  for (int y = 0; y < K_ideal_.height; ++y) {
    std::uint8_t* win = winner_.ptr<std::uint8_t>(y);
    std::uint8_t* lab = labels_ideal_.ptr<std::uint8_t>(y);
    const int hy = std::min(y >> 1, depth[1].height - 1);
    const float* d_row[3] = {depth[0].row(y), depth[1].row(hy), depth[2].row(y)};
    const std::int32_t* id_row[3] = {ids[0].row(y), ids[1].row(hy), ids[2].row(y)};
    const BackgroundRow bg = background_row(y);
    std::uint8_t* need0 = background_need_.ptr<std::uint8_t>(bg.y0);
    std::uint8_t* need1 = background_need_.ptr<std::uint8_t>(bg.y1);
    for (int x = 0; x < K_ideal_.width; ++x) {
      const int rx[3] = {x, std::min(x >> 1, half_w - 1), x};
      int best = -1;
      float z = 0.0f;
      for (int m = 0; m < 3; ++m) {
        const float d = d_row[m][rx[m]];
        if (d > 0.0f && id_row[m][rx[m]] >= 0 && (best < 0 || d < z)) {
          best = m;
          z = d;
        }
      }
      win[x] = best < 0 ? kNoSurface : static_cast<std::uint8_t>(best);
      if (keep_labels) lab[x] = best < 0 ? kLabelNone : label_of[best];
      if (best == 1) {
        const BackgroundTap& t = background_taps_[static_cast<std::size_t>(x)];
        need0[t.x0] = need0[t.x1] = need1[t.x0] = need1[t.x1] = 1;
      }
    }
  }
}

void SceneRenderer::shade_background_half(const Xf& T_world_camera, float irradiance) {
  const ImageView<const float> depth = background_raster_.depth();
  const ImageView<const std::int32_t> ids = background_raster_.triangle_id();
  const Pinhole& K = background_raster_.camera();
  const auto inv_fx = static_cast<float>(1.0 / K.fx), inv_fy = static_cast<float>(1.0 / K.fy);
  for (int y = 0; y < depth.height; ++y) {
    auto* out = background_half_.ptr<cv::Vec3f>(y);
    const std::uint8_t* need = background_need_.ptr<std::uint8_t>(y);
    const float ray_y = static_cast<float>(y - K.cy) * inv_fy;
    for (int x = 0; x < depth.width; ++x) {
      if (!need[x]) continue;  // no output pixel reads it (composite())
      const float d = depth(x, y);
      const std::int32_t tri = ids(x, y);
      if (d <= 0.0f || tri < 0) {
        out[x] = cv::Vec3f(0, 0, 0);
        continue;
      }
      const Vec3f ray(static_cast<float>(x - K.cx) * inv_fx, ray_y, 1.0f);
      const Vec3f c = shade_pixel(background_, T_world_camera, ray, tri, d, irradiance);
      out[x] = cv::Vec3f(c.x(), c.y(), c.z());
    }
  }
}

SceneRenderer::BackgroundRow SceneRenderer::background_row(int y) const {
  // Half-resolution pixel centres: y_half = (y + 0.5) / 2 - 0.5.
  const float hy = std::max(0.0f, 0.5f * static_cast<float>(y) - 0.25f);
  const int y0 = std::min(static_cast<int>(hy), background_half_.rows - 1);
  const int y1 = std::min(y0 + 1, background_half_.rows - 1);
  return {background_half_.ptr<cv::Vec3f>(y0), background_half_.ptr<cv::Vec3f>(y1), hy - static_cast<float>(y0), y0, y1};
}

cv::Vec3f SceneRenderer::background_at(const BackgroundRow& r, int x) const {
  const BackgroundTap& t = background_taps_[static_cast<std::size_t>(x)];
  const float fx = t.fx, fy = r.fy;
  return (r.r0[t.x0] * (1 - fx) + r.r0[t.x1] * fx) * (1 - fy) + (r.r1[t.x0] * (1 - fx) + r.r1[t.x1] * fx) * fy;
}

// Per row: the radiance of each pixel's nearest surface (composite()).
// The first sub-frame writes the accumulator (no clearing pass), later
// ones add.
void SceneRenderer::shade_rows(const Xf T_mesh_camera[3], float irradiance, float weight, bool first) {
  const ImageView<const float> depth[3] = {organ_raster_.depth(), background_raster_.depth(),
                                           instrument_raster_.depth()};
  const ImageView<const std::int32_t> ids[3] = {organ_raster_.triangle_id(), background_raster_.triangle_id(),
                                                instrument_raster_.triangle_id()};
  const auto inv_fx = static_cast<float>(1.0 / K_ideal_.fx), inv_fy = static_cast<float>(1.0 / K_ideal_.fy);
  for (int y = 0; y < K_ideal_.height; ++y) {
    const float ray_y = static_cast<float>(y - K_ideal_.cy) * inv_fy;
    auto* acc = accum_.ptr<cv::Vec3f>(y);
    const std::uint8_t* win = winner_.ptr<std::uint8_t>(y);
    const BackgroundRow bg = background_row(y);
    for (int x = 0; x < K_ideal_.width; ++x) {
      const int best = win[x];
      cv::Vec3f c(0.0f, 0.0f, 0.0f);
      if (best == 1) {
        c = background_at(bg, x) * weight;
      } else if (best != kNoSurface) {
        const Vec3f ray(static_cast<float>(x - K_ideal_.cx) * inv_fx, ray_y, 1.0f);
        const ShadeMesh& sm = best == 0 ? organ_ : instrument_;
        const Vec3f r =
            shade_pixel(sm, T_mesh_camera[best], ray, ids[best](x, y), depth[best](x, y), irradiance);
        c = cv::Vec3f(r.x(), r.y(), r.z()) * weight;
      }
      if (first) acc[x] = c;
      else acc[x] += c;
    }
  }
}

// Inlined into the row loops: the mesh's arrays stay in registers.
[[gnu::always_inline]] inline Vec3f SceneRenderer::shade_pixel(const ShadeMesh& sm, const Xf& T, const Vec3f& ray, std::int32_t tri,
                                 float depth, float irradiance) const {
  const Vec3f p_c = ray * depth;
  const Vec3f Rp = T.R * p_c;
  const Vec3f p_m = Rp + T.t;
  // Barycentrics in the mesh frame (precomputed per triangle solve).
  const float* s = &sm.solve[9 * static_cast<std::size_t>(tri)];
  const Vec3f w(p_m.x() - s[0], p_m.y() - s[1], p_m.z() - s[2]);
  const float b1 = std::clamp(s[3] * w.x() + s[4] * w.y() + s[5] * w.z(), 0.0f, 1.0f);
  const float b2 = std::clamp(s[6] * w.x() + s[7] * w.y() + s[8] * w.z(), 0.0f, 1.0f - b1);
  const float b0 = 1.0f - b1 - b2;
  const std::int32_t* v = &sm.mesh->tri[3 * static_cast<std::size_t>(tri)];
  const ShadeMesh::VertexShade &s0 = sm.vertex[v[0]], &s1 = sm.vertex[v[1]], &s2 = sm.vertex[v[2]];
  const Vec3f n_raw = b0 * s0.normal + b1 * s1.normal + b2 * s2.normal;
  const Vec3f albedo0 = b0 * s0.albedo + b1 * s1.albedo + b2 * s2.albedo;
  const int mat_id = static_cast<int>(sm.material[tri]);
  const Material& mat = materials_[mat_id];
  // Baked detail, bilinear over the triangle's texel grid.
  const int g = sm.texels;
  const float gx = b1 * static_cast<float>(g - 1), gy = b2 * static_cast<float>(g - 1);
  const int ix = std::min(static_cast<int>(gx), g - 2), iy = std::min(static_cast<int>(gy), g - 2);
  const float fx = gx - static_cast<float>(ix), fy = gy - static_cast<float>(iy);
  const std::uint8_t* d = &sm.detail[((static_cast<std::size_t>(tri) * g + iy) * g + ix) * 2];
  const std::uint8_t* d2 = d + 2 * g;
  const float w00 = (1 - fx) * (1 - fy), w10 = fx * (1 - fy), w01 = (1 - fx) * fy, w11 = fx * fy;
  const float vessel = (w00 * d[0] + w10 * d[2] + w01 * d2[0] + w11 * d2[2]) * (1.0f / 255.0f);
  const float speckle = (w00 * d[1] + w10 * d[3] + w01 * d2[1] + w11 * d2[3]) * (1.0f / 255.0f);
  const Vec3f albedo = Texture::apply_detail(mat, albedo0, vessel, speckle);
  // Light and eye at the camera centre: l = v = h (Blinn-Phong's half vector).
  // One sqrt per pixel (for n.l), the inverse square needs none; the
  // specular power by repeated squaring in registers (no table on the stack).
  const float dist2 = p_c.squaredNorm();
  const float ndl = std::max(0.0f, -n_raw.dot(Rp) / std::sqrt(n_raw.squaredNorm() * dist2));
  float spec = 0.0f;
  if (ndl > specular_cutoff_[mat_id]) {  // most pixels are far from a highlight
    spec = ndl;
    for (int k = 0; k < mat.shininess_log2; ++k) spec *= spec;
  }
  // The wet film (smooth tissue): its own sharp lobe on the smooth normal
  // tilted by the baked ripples; only where the smooth normal faces the
  // scope closely enough for any tilt to reach the lobe.
  float film = 0.0f;
  if (!sm.film.empty() && ndl > film_cutoff_[mat_id]) {
    const std::int8_t* f = &sm.film[((static_cast<std::size_t>(tri) * g + iy) * g + ix) * 4];
    const std::int8_t* f2 = f + 4 * g;
    const Vec3f tilt(w00 * f[0] + w10 * f[4] + w01 * f2[0] + w11 * f2[4],
                     w00 * f[1] + w10 * f[5] + w01 * f2[1] + w11 * f2[5],
                     w00 * f[2] + w10 * f[6] + w01 * f2[2] + w11 * f2[6]);
    const Vec3f n_film = n_raw / std::sqrt(n_raw.squaredNorm()) + tilt * (mat.film_tilt * (1.0f / 63.5f));
    film = std::max(0.0f, -n_film.dot(Rp) / std::sqrt(n_film.squaredNorm() * dist2));
    for (int k = 0; k < mat.film_shininess_log2; ++k) film *= film;
  }
  const float e = irradiance / dist2;
  return albedo * (e * ndl + kAmbient) + Vec3f::Constant(e * mat.specular * spec + e * mat.film * film);
}

void SceneRenderer::finish(int frame, cv::Mat& rgb, cv::Mat& labels) {
  const int W = settings_.K.width, H = settings_.K.height;
  const bool distorted = !settings_.distortion.is_zero();
  if (distorted) cv::remap(accum_, linear_out_, map1_, map2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  if (smoke_.enabled()) smoke_.apply(frame, distorted ? linear_out_ : accum_);
  const cv::Mat& lin = distorted ? linear_out_ : accum_;
  rgb.create(H, W, CV_8UC3);
  labels.create(H, W, CV_8U);
  const std::uint64_t noise_seed = settings_.noise_seed != 0 ? settings_.noise_seed : settings_.seed;
  Rng rng(mix_seed(noise_seed, static_cast<std::uint64_t>(frame) + 1));
  for (int y = 0; y < H; ++y) {
    const auto* in = lin.ptr<cv::Vec3f>(y);
    auto* out = rgb.ptr<cv::Vec3b>(y);
    std::uint8_t* lab = labels.ptr<std::uint8_t>(y);
    // Each row reads the noise table from a random place.
    const std::size_t g = rng.next_u64() % (gaussian_.size() - 3 * static_cast<std::size_t>(W));
    const std::size_t row = static_cast<std::size_t>(y) * W;
    if (distorted) {
      const std::uint8_t* ideal = labels_ideal_.ptr<std::uint8_t>();
      for (int x = 0; x < W; ++x) lab[x] = nearest_[row + x] >= 0 ? ideal[nearest_[row + x]] : kLabelNone;
    } else {
      std::copy_n(labels_ideal_.ptr<std::uint8_t>(y), W, lab);
    }
    noise_gamma_row(in, &gain_[row], &gaussian_[g], W, out);
  }
}

// Pixel x of a row: c = in * gain, plus noise sigma(mean of c) * N(0, 1)
// per channel (noise[3x + k]), clamped, through the gamma table. Four
// pixels at a time with OpenCV's universal intrinsics (SSE2 / NEON), the
// same float operations in the same order as the scalar tail, so both give
// the same bytes.
void SceneRenderer::noise_gamma_row(const cv::Vec3f* in, const float* gain, const float* noise, int W,
                                    cv::Vec3b* out) const {
  const float lut_scale = static_cast<float>(gamma_lut_.size()) - 1.0f;
  int x = 0;
#if CV_SIMD128
  const cv::v_float32x4 zero = cv::v_setzero_f32(), one = cv::v_setall_f32(1.0f);
  const cv::v_float32x4 third = cv::v_setall_f32(1.0f / 3.0f), s255 = cv::v_setall_f32(255.0f);
  const cv::v_float32x4 scale = cv::v_setall_f32(lut_scale), half = cv::v_setall_f32(0.5f);
  alignas(16) int sigma_index[4], gamma_index[3][4];
  alignas(16) float sigma[4];
  for (; x + 4 <= W; x += 4) {
    cv::v_float32x4 c[3], n[3];
    cv::v_load_deinterleave(&in[x][0], c[0], c[1], c[2]);
    cv::v_load_deinterleave(noise + 3 * x, n[0], n[1], n[2]);
    const cv::v_float32x4 g = cv::v_load(gain + x);
    for (auto& ck : c) ck = ck * g;
    const cv::v_float32x4 mean = cv::v_min(one, (c[0] + c[1] + c[2]) * third);
    cv::v_store_aligned(sigma_index, cv::v_trunc(mean * s255));
    for (int j = 0; j < 4; ++j) sigma[j] = sigma_lut_[static_cast<std::size_t>(sigma_index[j])];
    const cv::v_float32x4 sg = cv::v_load_aligned(sigma);
    for (int k = 0; k < 3; ++k) {
      const cv::v_float32x4 v = cv::v_min(cv::v_max(c[k] + sg * n[k], zero), one);
      cv::v_store_aligned(gamma_index[k], cv::v_trunc(v * scale + half));
    }
    for (int j = 0; j < 4; ++j)
      for (int k = 0; k < 3; ++k) out[x + j][k] = gamma_lut_[static_cast<std::size_t>(gamma_index[k][j])];
  }
#endif
  for (; x < W; ++x) {
    const cv::Vec3f c = in[x] * gain[x];
    const float mean = std::min(1.0f, (c[0] + c[1] + c[2]) * (1.0f / 3.0f));
    const float sigma_x = sigma_lut_[static_cast<std::size_t>(mean * 255.0f)];
    for (int k = 0; k < 3; ++k) {
      const float v = std::clamp(c[k] + sigma_x * noise[3 * x + k], 0.0f, 1.0f);
      out[x][k] = gamma_lut_[static_cast<std::size_t>(v * lut_scale + 0.5f)];
    }
  }
}

}  // namespace st::sim
