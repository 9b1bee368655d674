#include "tools/sim/renderer.h"

#include <algorithm>
#include <cmath>

#include <opencv2/imgproc.hpp>

#include "core/base/capacity.h"
#include "tools/sim/rng.h"

namespace st::sim {
namespace {

constexpr int kGaussianTable = 1 << 16;
constexpr int kGammaLut = 4096;

}  // namespace

void SceneRenderer::prepare_mesh(const Mesh& mesh, const std::vector<MaterialId>& material, int texels,
                                 ShadeMesh* out) {
  out->mesh = &mesh;
  out->texels = texels;
  out->material = material;
  out->vertex.resize(static_cast<std::size_t>(mesh.vertex_count()));
  update_geometry(out);
  // Vertex albedo uses the material of any triangle touching the vertex;
  // materials change only along whole-triangle boundaries, a soft seam.
  std::vector<MaterialId> vmat(static_cast<std::size_t>(mesh.vertex_count()), material.front());
  for (int t = 0; t < mesh.triangle_count(); ++t)
    for (int k = 0; k < 3; ++k) vmat[mesh.tri[3 * t + k]] = material[t];
  for (int i = 0; i < mesh.vertex_count(); ++i)
    out->vertex[i].albedo =
        texture_.albedo_at_vertex(materials_[static_cast<int>(vmat[i])], mesh.vertex(i).cast<float>());
  bake_detail(out);
  bake_film(out);
}

void SceneRenderer::update_geometry(ShadeMesh* sm) {
  const Mesh& mesh = *sm->mesh;
  const std::vector<Vec3f> normal = vertex_normals(mesh);
  for (int i = 0; i < mesh.vertex_count(); ++i) sm->vertex[i].normal = normal[i];
  sm->solve.resize(static_cast<std::size_t>(mesh.triangle_count()) * 9);
  for (int t = 0; t < mesh.triangle_count(); ++t) {
    const Vec3 v0 = mesh.vertex(mesh.tri[3 * t]);
    const Vec3 e1 = mesh.vertex(mesh.tri[3 * t + 1]) - v0, e2 = mesh.vertex(mesh.tri[3 * t + 2]) - v0;
    const double d00 = e1.dot(e1), d01 = e1.dot(e2), d11 = e2.dot(e2);
    const double det = d00 * d11 - d01 * d01;
    const double inv = std::abs(det) > 1e-18 ? 1.0 / det : 0.0;  // degenerate: all weight on v0
    const Vec3 m1 = (d11 * e1 - d01 * e2) * inv, m2 = (d00 * e2 - d01 * e1) * inv;
    float* s = &sm->solve[9 * static_cast<std::size_t>(t)];
    for (int k = 0; k < 3; ++k) {
      s[k] = static_cast<float>(v0[k]);
      s[3 + k] = static_cast<float>(m1[k]);
      s[6 + k] = static_cast<float>(m2[k]);
    }
  }
}

void SceneRenderer::bake_film(ShadeMesh* sm) const {
  sm->film.clear();
  const bool any = std::any_of(sm->material.begin(), sm->material.end(),
                               [&](MaterialId id) { return materials_[static_cast<int>(id)].film > 0.0f; });
  if (!any) return;
  const Mesh& mesh = *sm->mesh;
  const int n = sm->texels;
  sm->film.assign(static_cast<std::size_t>(mesh.triangle_count()) * n * n * 4, 0);
  std::int8_t* out = sm->film.data();
  for (int t = 0; t < mesh.triangle_count(); ++t, out += 4 * n * n) {
    const Material& m = materials_[static_cast<int>(sm->material[t])];
    if (!(m.film > 0.0f)) continue;
    const std::int32_t* v = &mesh.tri[3 * static_cast<std::size_t>(t)];
    const Vec3f v0 = mesh.vertex(v[0]).cast<float>();
    const Vec3f e1 = mesh.vertex(v[1]).cast<float>() - v0, e2 = mesh.vertex(v[2]).cast<float>() - v0;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const float b1 = static_cast<float>(i) / static_cast<float>(n - 1);
        const float b2 = static_cast<float>(j) / static_cast<float>(n - 1);
        const Vec3f normal = ((1.0f - b1 - b2) * sm->vertex[v[0]].normal + b1 * sm->vertex[v[1]].normal +
                              b2 * sm->vertex[v[2]].normal)
                                 .normalized();
        Vec3f tilt = texture_.film_tilt(m, v0 + b1 * e1 + b2 * e2);
        tilt -= tilt.dot(normal) * normal;  // a tilt within the tangent plane
        std::int8_t* o = out + 4 * (j * n + i);
        for (int k = 0; k < 3; ++k)
          o[k] = static_cast<std::int8_t>(std::lround(63.5f * std::clamp(tilt[k], -2.0f, 2.0f)));
      }
  }
}

void SceneRenderer::set_organ_shape(double phase) {
  if (!breathing_.enabled() || phase == organ_phase_) return;
  organ_phase_ = phase;
  breathing_.displace(scene_->organ, phase, &organ_shape_);
  (void)organ_raster_.configure(organ_shape_, organ_raster_config_);  // the same mesh that configured before
  update_geometry(&organ_);
}

void SceneRenderer::bake_detail(ShadeMesh* sm) const {
  const Mesh& mesh = *sm->mesh;
  const int n = sm->texels;
  sm->detail.resize(static_cast<std::size_t>(mesh.triangle_count()) * n * n * 2);
  std::uint8_t* out = sm->detail.data();
  for (int t = 0; t < mesh.triangle_count(); ++t) {
    const Vec3f v0 = mesh.vertex(mesh.tri[3 * t]).cast<float>();
    const Vec3f e1 = mesh.vertex(mesh.tri[3 * t + 1]).cast<float>() - v0;
    const Vec3f e2 = mesh.vertex(mesh.tri[3 * t + 2]).cast<float>() - v0;
    const Material& m = materials_[static_cast<int>(sm->material[t])];
    // The photo replaces the organ's procedural detail: no vessel, and the
    // speckle channel carries the photo's relative albedo (see configure).
    const PhotoTexture* photo = sm->material[t] == MaterialId::Liver ? settings_.organ_photo.get() : nullptr;
    // The photo's triplanar blend follows the shading normal, interpolated
    // from the vertices: with the face's own normal the blend jumped at
    // every edge, and the organ showed its triangles as a net of seams,
    // surface-fixed edges that real tissue does not have.
    const Vec3f& n0 = sm->vertex[mesh.tri[3 * t]].normal;
    const Vec3f& n1 = sm->vertex[mesh.tri[3 * t + 1]].normal;
    const Vec3f& n2 = sm->vertex[mesh.tri[3 * t + 2]].normal;
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const float b1 = static_cast<float>(i) / static_cast<float>(n - 1);
        const float b2 = static_cast<float>(j) / static_cast<float>(n - 1);
        const Vec3f p = v0 + b1 * e1 + b2 * e2;
        Texture::Detail d;
        if (photo) {
          const Vec3f normal = (1.0f - b1 - b2) * n0 + b1 * n1 + b2 * n2;
          d.vessel = 0.0f;
          d.speckle = (photo->ratio_at(p, normal) - PhotoTexture::kMinRatio) /
                      (PhotoTexture::kMaxRatio - PhotoTexture::kMinRatio);
        } else if (m.smooth_mottle_mm > 0.0f) {
          d = texture_.smooth_sample(m, p);
        } else {
          d = texture_.detail_sample(m, p);
        }
        *out++ = static_cast<std::uint8_t>(std::lround(255.0f * d.vessel));
        *out++ = static_cast<std::uint8_t>(std::lround(255.0f * d.speckle));
      }
  }
}

Status SceneRenderer::configure(const Scene& scene, const RenderSettings& settings) {
  if (Status s = CameraModel::validate(settings.K, settings.distortion); !s) return s;
  if (!(settings.organ_detail >= 0.0 && settings.organ_detail <= kMaxOrganDetail))
    return make_error("organ detail must be a number in 0..2 (1: the calibrated texture)");
  if (!(settings.shutter >= 0.0 && settings.shutter <= 1.0))
    return make_error("shutter must be a fraction of the frame interval in 0..1");
  if (!(settings.smoke >= 0.0 && settings.smoke <= kMaxSmoke))
    return make_error("smoke must be the veil's peak share of the view in 0..0.9");
  if (!(settings.breathing_mm >= 0.0 && settings.breathing_mm <= kMaxBreathingMm))
    return make_error("breathing must be the organ's largest displacement in 0..20 mm");
  if (settings.tissue == Tissue::Smooth && settings.organ_photo)
    return make_error("smooth tissue and a photo texture both define the organ's texture: choose one");
  settings_ = settings;
  scene_ = &scene;
  organ_centre_model_ = bounding_box(scene.organ).centre();
  texture_ = Texture(settings.seed);
  for (int m = 0; m < static_cast<int>(MaterialId::Count); ++m) {
    materials_[m] = material(static_cast<MaterialId>(m));
    if (static_cast<MaterialId>(m) == MaterialId::Liver && settings.tissue == Tissue::Smooth)
      materials_[m] = smooth_liver();
    if (static_cast<MaterialId>(m) == MaterialId::Liver && settings.organ_photo) {
      // apply_detail's speckle factor 1 + 2 s (speckle - 1/2) maps the
      // baked 0..1 back onto the photo's ratio kMinRatio..kMaxRatio.
      materials_[m].speckle_strength = 0.5f * (PhotoTexture::kMaxRatio - PhotoTexture::kMinRatio);
      materials_[m].vessel_strength = 0.0f;
      materials_[m].spots = 0.0f;
    }
    if (static_cast<MaterialId>(m) == MaterialId::Liver) {
      materials_[m].speckle_strength *= static_cast<float>(settings.organ_detail);
      materials_[m].spots *= static_cast<float>(settings.organ_detail);
    }
    // n.l below which the specular term ndl^(2^k) is < 1e-4 (under 1/255 of
    // the brightest highlight): shade_pixel skips the squaring chain there.
    specular_cutoff_[m] = std::pow(1e-4f, 1.0f / static_cast<float>(1 << materials_[m].shininess_log2));
    // The film's lobe, reached through a normal tilted by up to 2 film_tilt
    // (the stored clamp): no glint where the smooth normal is farther off.
    const Material& mm = materials_[m];
    const float film_lobe = std::acos(std::pow(1e-4f, 1.0f / static_cast<float>(1 << mm.film_shininess_log2)));
    film_cutoff_[m] = std::cos(std::min(1.5f, film_lobe + 2.0f * mm.film_tilt));
  }
  build_camera_maps();
  smoke_.configure(settings.smoke, settings.seed, settings.K.width, settings.K.height);
  if (K_ideal_.width > kMaxImageWidth || K_ideal_.height > kMaxImageHeight)
    return make_error("the distortion needs an ideal image of " + std::to_string(K_ideal_.width) + "x" +
                      std::to_string(K_ideal_.height) + " pixels, above the image capacity");
  // Texel grids: ~0.3 mm on the organ (2-3 mm triangles), ~0.5 mm on the
  // floor (6 mm cells), coarse on the plain instrument.
  const auto organ_tris = static_cast<std::size_t>(scene.organ.triangle_count());
  breathing_ = BreathingField(scene.organ, settings.breathing_mm);
  organ_phase_ = 0.0;
  organ_shape_ = breathing_.enabled() ? scene.organ : Mesh{};  // reshaped per frame when breathing
  prepare_mesh(breathing_.enabled() ? organ_shape_ : scene.organ,
               std::vector<MaterialId>(organ_tris, MaterialId::Liver), 12, &organ_);
  prepare_mesh(scene.background, scene.background_material, 12, &background_);
  const auto instrument_tris = static_cast<std::size_t>(scene.instrument.triangle_count());
  prepare_mesh(scene.instrument, std::vector<MaterialId>(instrument_tris, MaterialId::Instrument), 4, &instrument_);
  RasterConfig rc;
  rc.width = K_ideal_.width;
  rc.height = K_ideal_.height;
  rc.near_mm = 1.0;
  rc.cull_backfaces = true;
  organ_raster_config_ = rc;
  if (Status s = organ_raster_.configure(*organ_.mesh, rc); !s) return s;
  RasterConfig rc_half = rc;
  rc_half.downscale = 2;
  if (Status s = background_raster_.configure(scene.background, rc_half); !s) return s;
  if (Status s = instrument_raster_.configure(scene.instrument, rc); !s) return s;
  accum_.create(K_ideal_.height, K_ideal_.width, CV_32FC3);
  background_half_.create(background_raster_.depth().height, background_raster_.depth().width, CV_32FC3);
  background_need_.create(background_half_.rows, background_half_.cols, CV_8U);
  winner_.create(K_ideal_.height, K_ideal_.width, CV_8U);
  background_taps_.resize(static_cast<std::size_t>(K_ideal_.width));
  for (int x = 0; x < K_ideal_.width; ++x) {  // half-resolution centres: x_half = (x + 0.5) / 2 - 0.5
    const float hx = std::max(0.0f, 0.5f * static_cast<float>(x) - 0.25f);
    const int x0 = std::min(static_cast<int>(hx), background_half_.cols - 1);
    background_taps_[static_cast<std::size_t>(x)] = {x0, std::min(x0 + 1, background_half_.cols - 1),
                                                     hx - static_cast<float>(x0)};
  }
  labels_ideal_.create(K_ideal_.height, K_ideal_.width, CV_8U);
  linear_out_.create(settings.K.height, settings.K.width, CV_32FC3);
  Rng rng(mix_seed(settings.seed, 0xC0FFEE));
  gaussian_.resize(kGaussianTable);
  for (float& g : gaussian_) g = static_cast<float>(rng.gaussian());
  sigma_lut_.resize(256);
  for (int i = 0; i < 256; ++i)  // brightness i / 255 (linear, mean of R, G, B)
    sigma_lut_[i] = static_cast<float>(std::sqrt(settings.noise_read * settings.noise_read + settings.noise_shot * i / 255.0));
  gamma_lut_.resize(kGammaLut);
  for (int i = 0; i < kGammaLut; ++i)  // display gamma 1/2.2 (close to BT.709/sRGB)
    gamma_lut_[i] = static_cast<std::uint8_t>(std::lround(255.0 * std::pow(i / (kGammaLut - 1.0), 1.0 / 2.2)));
  return Status::Ok();
}

void SceneRenderer::build_camera_maps() {
  const Pinhole& K = settings_.K;
  const CameraModel cam(K, settings_.distortion);
  const int W = K.width, H = K.height;
  cv::Mat map_x(H, W, CV_32F), map_y(H, W, CV_32F);
  double min_x = 0, min_y = 0, max_x = W - 1, max_y = H - 1;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      Vec2 ideal(x, y);
      if (!settings_.distortion.is_zero()) (void)cam.undistort_pixel(Vec2(x, y), &ideal);
      map_x.at<float>(y, x) = static_cast<float>(ideal.x());
      map_y.at<float>(y, x) = static_cast<float>(ideal.y());
      min_x = std::min(min_x, ideal.x());
      max_x = std::max(max_x, ideal.x());
      min_y = std::min(min_y, ideal.y());
      max_y = std::max(max_y, ideal.y());
    }
  // The ideal image: same focal lengths, shifted so it covers every sample
  // (without distortion it is the output image itself).
  const bool distorted = !settings_.distortion.is_zero();
  const int ox = distorted ? static_cast<int>(std::ceil(-min_x)) + 2 : 0;
  const int oy = distorted ? static_cast<int>(std::ceil(-min_y)) + 2 : 0;
  K_ideal_ = K;
  K_ideal_.cx += ox;
  K_ideal_.cy += oy;
  K_ideal_.width = distorted ? static_cast<int>(std::ceil(max_x)) + ox + 3 : W;
  K_ideal_.height = distorted ? static_cast<int>(std::ceil(max_y)) + oy + 3 : H;
  map_x += static_cast<float>(ox);
  map_y += static_cast<float>(oy);
  nearest_.assign(static_cast<std::size_t>(W) * H, -1);
  gain_.resize(static_cast<std::size_t>(W) * H);
  const double r_corner2 = std::max(K.cx, W - 1 - K.cx) * std::max(K.cx, W - 1 - K.cx) +
                           std::max(K.cy, H - 1 - K.cy) * std::max(K.cy, H - 1 - K.cy);
  const double stop = settings_.field_stop_radius_px > 0 ? settings_.field_stop_radius_px : 0.66 * H;
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * W + x;
      const int ix = static_cast<int>(std::lround(map_x.at<float>(y, x)));
      const int iy = static_cast<int>(std::lround(map_y.at<float>(y, x)));
      if (ix >= 0 && iy >= 0 && ix < K_ideal_.width && iy < K_ideal_.height) nearest_[i] = iy * K_ideal_.width + ix;
      const double r2 = (x - K.cx) * (x - K.cx) + (y - K.cy) * (y - K.cy);
      double g = 1.0 - settings_.vignetting * r2 / r_corner2;
      if (settings_.field_stop) g *= std::clamp((stop - std::sqrt(r2)) / 1.5 + 0.5, 0.0, 1.0);
      gain_[i] = static_cast<float>(g);
    }
  if (!settings_.distortion.is_zero()) cv::convertMaps(map_x, map_y, map1_, map2_, CV_16SC2);
}

void SceneRenderer::render(const Trajectory& trajectory, int frame, cv::Mat& rgb, cv::Mat& labels) {
  const int n = trajectory.blur_subframes(frame, settings_.shutter);
  set_organ_shape(trajectory.at(frame).breath);
  for (int k = 0; k < n; ++k) {
    // Sub-frames spread over the open shutter, centred on the frame time.
    const double offset = n == 1 ? 0.0 : (k - (n - 1) / 2.0) / (n - 1) * settings_.shutter;
    render_subframe(trajectory.at(frame + offset), 1.0f / static_cast<float>(n), k == 0, 2 * k == n - 1);
  }
  finish(frame, rgb, labels);
}

std::vector<std::pair<Vec2, Vec3>> SceneRenderer::visible_organ_points(const WorldState& state,
                                                                     const cv::Mat& labels, int margin_px,
                                                                     int step_px) {
  const SE3 T_model_camera = state.T_model_camera();
  set_organ_shape(state.breath);
  organ_raster_.render(T_model_camera.inverse(), K_ideal_);
  const ImageView<const float> depth = organ_raster_.depth();
  std::vector<std::pair<Vec2, Vec3>> out;
  const int W = labels.cols, H = labels.rows, m = margin_px;
  auto organ = [&](int x, int y) { return labels.at<std::uint8_t>(y, x) == kLabelOrgan; };
  for (int y = m; y < H - m; y += step_px)
    for (int x = m; x < W - m; x += step_px) {
      if (!organ(x, y) || !organ(x - m, y) || !organ(x + m, y) || !organ(x, y - m) || !organ(x, y + m)) continue;
      const std::int32_t src = nearest_[static_cast<std::size_t>(y) * W + x];
      if (src < 0) continue;
      const int ix = src % K_ideal_.width, iy = src / K_ideal_.width;
      const float d = depth(ix, iy);
      if (d <= 0.0f) continue;
      const Vec3 p_model = T_model_camera * K_ideal_.unproject(Vec2(ix, iy), d);
      out.emplace_back(Vec2(x, y), breathing_.enabled() ? rest_point(p_model, organ_raster_.triangle_id()(ix, iy))
                                                        : p_model);
    }
  return out;
}

Vec3 SceneRenderer::rest_point(const Vec3& p_model, std::int32_t tri) const {
  if (tri < 0) return p_model;
  const float* s = &organ_.solve[9 * static_cast<std::size_t>(tri)];
  const Vec3 w = p_model - Vec3(s[0], s[1], s[2]);
  const Vec3 m1(s[3], s[4], s[5]), m2(s[6], s[7], s[8]);
  const double b1 = m1.dot(w), b2 = m2.dot(w);
  const std::int32_t* v = &scene_->organ.tri[3 * static_cast<std::size_t>(tri)];
  return (1.0 - b1 - b2) * scene_->organ.vertex(v[0]) + b1 * scene_->organ.vertex(v[1]) +
         b2 * scene_->organ.vertex(v[2]);
}

}  // namespace st::sim
