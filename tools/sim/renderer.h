// Renders a simulated laparoscope frame: organ, background and instrument
// rasterised by the project's MeshRasterizer (one instance each), composited
// by depth and shaded with the scope light at the camera (inverse square,
// Lambert + Blinn-Phong), then the camera: lens distortion (OpenCV model,
// exact: every output pixel samples the ideal image at its undistorted
// position), vignetting, field stop, sensor noise, display gamma.
//
// configure() allocates every buffer; render() reuses them (cv::Mat outputs
// keep their size). Single-threaded.
#pragma once

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include <opencv2/core.hpp>

#include "core/geometry/camera.h"
#include "core/raster/rasterizer.h"
#include "core/base/result.h"
#include "tools/sim/breathing.h"
#include "tools/sim/materials.h"
#include "tools/sim/photo_texture.h"
#include "tools/sim/scenario.h"
#include "tools/sim/smoke.h"
#include "tools/sim/scene.h"

namespace st::sim {

// Per-pixel labels of the rendered (output) image.
inline constexpr std::uint8_t kLabelNone = 0, kLabelOrgan = 1, kLabelBackground = 2, kLabelInstrument = 3;

// Largest RenderSettings::organ_detail accepted: twice the calibrated texture.
inline constexpr double kMaxOrganDetail = 2.0;

struct RenderSettings {
  Pinhole K;                 // output (distorted) image camera
  Distortion distortion;     // OpenCV radial-tangential
  bool field_stop = false;   // black outside a circle centred on (cx, cy)
  double field_stop_radius_px = 0;  // 0: 0.66 * height
  double vignetting = 0.35;  // relative brightness loss at the image corners
  double exposure = 1.1;     // linear gain at the reference distance
  double noise_read = 0.0022; // sensor noise sigma, linear units
  double noise_shot = 0.0007; // signal-dependent variance per unit signal
  std::uint64_t seed = 1;
  std::uint64_t noise_seed = 0;  // sensor noise only; 0: use seed (texture stays that of seed)
  // The organ's fine texture (speckle and lobule spots) relative to the
  // calibrated one: 1 matches the real liver's corner density, lower is
  // smoother tissue (0: no fine texture; vessels and mottling stay).
  double organ_detail = 1.0;
  // Fraction of the frame interval the shutter is open (0..1), centred on
  // the frame time: the length of the motion blur; 0 renders every frame
  // sharp.
  double shutter = kDefaultShutter;
  // The organ's fine texture from a photograph instead of the procedural
  // speckle, spots and vessels (photo_texture.h); organ_detail scales its
  // contrast as it scales the speckle's. Null: procedural.
  std::shared_ptr<const PhotoTexture> organ_photo;
  // Surgical smoke (smoke.h): the veil's share at the thickest point of
  // an episode, 0..kMaxSmoke; 0 renders no smoke.
  double smoke = 0.0;
  // The organ's tissue (materials.h): Smooth replaces the liver's fine
  // texture by smooth mottling and adds the wet film's glints; organ_detail
  // then scales the mottling's contrast. Not with organ_photo.
  Tissue tissue = Tissue::Textured;
  // Breathing (breathing.h): the organ's largest displacement, mm, at the
  // phase the trajectory gives (WorldState::breath); 0: a rigid organ.
  double breathing_mm = 0.0;
};

class SceneRenderer {
 public:
  Status configure(const Scene& scene, const RenderSettings& settings);
  // Frame `frame` of the trajectory: 8-bit RGB and labels, output size.
  // Averages the trajectory's sub-frames (motion blur); the labels are the
  // centre sub-frame, i.e. exactly the frame's pose. With breathing the
  // organ takes the frame's shape once for all its sub-frames (a breath is
  // slow beside the shutter); reshaping re-configures the organ's
  // rasteriser, so render() then allocates.
  void render(const Trajectory& trajectory, int frame, cv::Mat& rgb, cv::Mat& labels);
  // Organ surface points seen at output pixels of a rendered frame (every
  // step_px), at least margin_px inside the organ's label region: pairs of
  // (output pixel, model point). Re-renders the organ at `state`. With
  // breathing the model point is the seen point's place on the rest shape
  // (the same barycentric position on the rest triangle).
  std::vector<std::pair<Vec2, Vec3>> visible_organ_points(const WorldState& state, const cv::Mat& labels,
                                                          int margin_px, int step_px);
  // The ideal pinhole the meshes are rasterised with (output K plus a
  // margin that covers the distorted image).
  const Pinhole& ideal_camera() const { return K_ideal_; }
  // The organ's breathing (its rigid part gives the ground truth's frame).
  const BreathingField& breathing() const { return breathing_; }

 private:
  struct ShadeMesh {  // per-vertex normals/albedo, per-triangle barycentric solve
    struct VertexShade {  // interleaved: one cache line serves both
      Vec3f normal, albedo;
    };
    std::vector<VertexShade> vertex;
    std::vector<float> solve;  // per triangle: v0 (3), M (2x3): (b1, b2) = M (p - v0)
    std::vector<MaterialId> material;
    // Fine detail baked per triangle: an n x n grid over (b1, b2) of
    // (vessel, speckle) bytes, sampled bilinearly. Grid points beyond the
    // b1 + b2 = 1 edge hold the texture continued over the triangle's
    // plane, so interpolation never reads undefined texels.
    int texels = 8;
    std::vector<std::uint8_t> detail;
    // The wet film's normal tilt per texel (x, y, z, unused), int8 in units
    // of the material's film_tilt / 63.5; empty when no material has a film.
    std::vector<std::int8_t> film;
    const Mesh* mesh = nullptr;
  };
  void prepare_mesh(const Mesh& mesh, const std::vector<MaterialId>& material, int texels, ShadeMesh* out);
  // Normals and barycentric solves from the mesh's current vertices.
  static void update_geometry(ShadeMesh* sm);
  void bake_detail(ShadeMesh* sm) const;
  void bake_film(ShadeMesh* sm) const;
  // The organ at breathing phase `phase` (0 rest, 1 the full displacement):
  // vertices, rasteriser and shading geometry; nothing when unchanged.
  void set_organ_shape(double phase);
  // A point on the current organ shape's triangle tri -> the same
  // barycentric position on the rest shape.
  Vec3 rest_point(const Vec3& p_model, std::int32_t tri) const;
  void build_camera_maps();
  struct Xf {  // a rigid transform in float for the per-pixel loop
    Eigen::Matrix3f R;
    Vec3f t;
  };
  // first: the sub-frame writes the accumulator instead of adding to it.
  void render_subframe(const WorldState& state, float weight, bool first, bool keep_labels);
  void composite(bool keep_labels);
  void shade_rows(const Xf T_mesh_camera[3], float irradiance, float weight, bool first);
  // Radiance (linear) of one ideal pixel on a mesh: light at the camera.
  // ray = ((x - cx) / fx, (y - cy) / fy, 1): the pixel's point is ray * depth.
  Vec3f shade_pixel(const ShadeMesh& sm, const Xf& T_mesh_camera, const Vec3f& ray, std::int32_t tri,
                    float depth, float irradiance) const;
  // The background at half resolution (it is rasterised at half size and
  // mostly far or out of focus); full-resolution pixels sample it bilinearly.
  void shade_background_half(const Xf& T_world_camera, float irradiance);
  // Bilinear taps into background_half_ for full-resolution pixels: the
  // columns' once (configure), a row's per row.
  struct BackgroundTap {
    int x0, x1;
    float fx;
  };
  struct BackgroundRow {
    const cv::Vec3f *r0, *r1;
    float fy;
    int y0, y1;
  };
  BackgroundRow background_row(int y) const;
  cv::Vec3f background_at(const BackgroundRow& row, int x) const;
  void finish(int frame, cv::Mat& rgb, cv::Mat& labels);
  void noise_gamma_row(const cv::Vec3f* in, const float* gain, const float* noise, int W, cv::Vec3b* out) const;

  RenderSettings settings_;
  Pinhole K_ideal_;
  const Scene* scene_ = nullptr;
  Texture texture_{1};
  Vec3 organ_centre_model_;
  Material materials_[static_cast<int>(MaterialId::Count)];
  float specular_cutoff_[static_cast<int>(MaterialId::Count)] = {};
  float film_cutoff_[static_cast<int>(MaterialId::Count)] = {};  // smooth n.l below which no film glint can reach
  BreathingField breathing_;
  Mesh organ_shape_;         // the organ at organ_phase_ (breathing only)
  double organ_phase_ = 0.0;
  RasterConfig organ_raster_config_;
  ShadeMesh organ_, background_, instrument_;
  MeshRasterizer organ_raster_, background_raster_, instrument_raster_;
  SmokeVeil smoke_;
  cv::Mat accum_;         // ideal image, linear RGB, CV_32FC3
  cv::Mat background_half_;  // half-resolution background radiance, CV_32FC3
  std::vector<BackgroundTap> background_taps_;  // per ideal column
  cv::Mat background_need_;  // CV_8U, half size: 1 where a bilinear tap of a background pixel reads it
  static constexpr std::uint8_t kNoSurface = 255;
  cv::Mat winner_;           // CV_8U, ideal size: nearest mesh per pixel (0 organ, 1 background, 2 instrument)
  cv::Mat labels_ideal_;  // CV_8U
  cv::Mat map1_, map2_;   // output -> ideal (fixed point maps for cv::remap)
  std::vector<std::int32_t> nearest_;  // output pixel -> ideal pixel index, -1 outside
  cv::Mat linear_out_;    // output size, CV_32FC3
  std::vector<float> gain_;            // vignetting x field stop, per output pixel
  std::vector<float> sigma_lut_;       // noise sigma by brightness (256 steps)
  std::vector<float> gaussian_;        // table of N(0, 1) samples for sensor noise
  std::vector<std::uint8_t> gamma_lut_;
};

}  // namespace st::sim
