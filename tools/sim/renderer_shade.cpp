// SceneRenderer: per-frame work (renderer.h). Allocation-free.
#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "tools/sim/renderer.h"
#include "tools/sim/rng.h"

namespace st::sim {
namespace {

constexpr float kAmbient = 0.05f;  // inter-reflections: shadowed tissue is not black

}  // namespace

void SceneRenderer::render_subframe(const WorldState& state, float weight, bool keep_labels) {
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
  const double d_organ = (T_camera_world * (state.T_world_model * organ_centre_model_)).norm();
  const double d_ref = 100.0 * std::pow(std::max(d_organ, 20.0) / 100.0, 0.85);
  shade_rows(T_mesh_camera, static_cast<float>(settings_.exposure * d_ref * d_ref), weight, keep_labels);
}

void SceneRenderer::shade_rows(const Xf T_mesh_camera[3], float irradiance, float weight,
                               bool keep_labels) {
  const MeshRasterizer* rasters[3] = {&organ_raster_, &background_raster_, &instrument_raster_};
  const ShadeMesh* meshes[3] = {&organ_, &background_, &instrument_};
  const std::uint8_t label_of[3] = {kLabelOrgan, kLabelBackground, kLabelInstrument};
  ImageView<const float> depth[3];
  ImageView<const std::int32_t> ids[3];
  for (int m = 0; m < 3; ++m) {
    depth[m] = rasters[m]->depth();
    ids[m] = rasters[m]->triangle_id();
  }
  for (int y = 0; y < K_ideal_.height; ++y) {
    auto* acc = accum_.ptr<cv::Vec3f>(y);
    std::uint8_t* lab = labels_ideal_.ptr<std::uint8_t>(y);
    for (int x = 0; x < K_ideal_.width; ++x) {
      int best = -1;
      float z = 0.0f;
      for (int m = 0; m < 3; ++m) {
        const float d = depth[m](x, y);
        if (d > 0.0f && ids[m](x, y) >= 0 && (best < 0 || d < z)) {
          best = m;
          z = d;
        }
      }
      if (keep_labels) lab[x] = best < 0 ? kLabelNone : label_of[best];
      if (best < 0) continue;
      const Vec3f c = shade_pixel(*meshes[best], T_mesh_camera[best], ids[best](x, y),
                                  static_cast<float>(x), static_cast<float>(y), z, irradiance);
      acc[x] += cv::Vec3f(c.x(), c.y(), c.z()) * weight;
    }
  }
}

Vec3f SceneRenderer::shade_pixel(const ShadeMesh& sm, const Xf& T, std::int32_t tri, float x, float y,
                                 float depth, float irradiance) const {
  const Vec3f p_c((x - static_cast<float>(K_ideal_.cx)) / static_cast<float>(K_ideal_.fx) * depth,
                  (y - static_cast<float>(K_ideal_.cy)) / static_cast<float>(K_ideal_.fy) * depth, depth);
  const Vec3f Rp = T.R * p_c;
  const Vec3f p_m = Rp + T.t;
  // Barycentrics in the mesh frame (precomputed per triangle solve).
  const float* s = &sm.solve[9 * static_cast<std::size_t>(tri)];
  const Vec3f w(p_m.x() - s[0], p_m.y() - s[1], p_m.z() - s[2]);
  const float b1 = std::clamp(s[3] * w.x() + s[4] * w.y() + s[5] * w.z(), 0.0f, 1.0f);
  const float b2 = std::clamp(s[6] * w.x() + s[7] * w.y() + s[8] * w.z(), 0.0f, 1.0f - b1);
  const float b0 = 1.0f - b1 - b2;
  const std::int32_t* v = &sm.mesh->tri[3 * static_cast<std::size_t>(tri)];
  const Vec3f n = (b0 * sm.normal[v[0]] + b1 * sm.normal[v[1]] + b2 * sm.normal[v[2]]).normalized();
  const Vec3f albedo0 = b0 * sm.albedo[v[0]] + b1 * sm.albedo[v[1]] + b2 * sm.albedo[v[2]];
  const Material& mat = materials_[static_cast<int>(sm.material[tri])];
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
  const float dist2 = p_c.squaredNorm();
  const float ndl = std::max(0.0f, -n.dot(Rp) / std::sqrt(dist2));
  float spec = ndl;
  for (int k = 0; k < mat.shininess_log2; ++k) spec *= spec;
  const float e = irradiance / dist2;
  return albedo * (e * ndl + kAmbient) + Vec3f::Constant(e * mat.specular * spec);
}

void SceneRenderer::finish(int frame, cv::Mat& rgb, cv::Mat& labels) {
  const int W = settings_.K.width, H = settings_.K.height;
  const bool distorted = !settings_.distortion.is_zero();
  if (distorted) cv::remap(accum_, linear_out_, map1_, map2_, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  const cv::Mat& lin = distorted ? linear_out_ : accum_;
  rgb.create(H, W, CV_8UC3);
  labels.create(H, W, CV_8U);
  Rng rng(mix_seed(settings_.seed, static_cast<std::uint64_t>(frame) + 1));
  const float read2 = static_cast<float>(settings_.noise_read * settings_.noise_read);
  const auto shot = static_cast<float>(settings_.noise_shot);
  const float lut_scale = static_cast<float>(gamma_lut_.size()) - 1.0f;
  for (int y = 0; y < H; ++y) {
    const auto* in = lin.ptr<cv::Vec3f>(y);
    auto* out = rgb.ptr<cv::Vec3b>(y);
    std::uint8_t* lab = labels.ptr<std::uint8_t>(y);
    // Each row reads the noise table from a random place.
    std::size_t g = rng.next_u64() % (gaussian_.size() - 3 * static_cast<std::size_t>(W));
    for (int x = 0; x < W; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * W + x;
      const std::int32_t src = nearest_[i];
      lab[x] = distorted ? (src >= 0 ? labels_ideal_.ptr<std::uint8_t>()[src] : kLabelNone)
                         : labels_ideal_.ptr<std::uint8_t>(y)[x];
      const cv::Vec3f c = in[x] * gain_[i];
      const float sigma = std::sqrt(read2 + shot * (c[0] + c[1] + c[2]) * (1.0f / 3.0f));
      for (int k = 0; k < 3; ++k) {
        const float v = std::clamp(c[k] + sigma * gaussian_[g++], 0.0f, 1.0f);
        out[x][k] = gamma_lut_[static_cast<std::size_t>(v * lut_scale + 0.5f)];
      }
    }
  }
}

}  // namespace st::sim
