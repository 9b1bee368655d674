#include "tools/sim/sim_run.h"

#include <algorithm>

#include "core/base/capacity.h"
#include "hal/storage/mesh_file.h"
#include "tools/sim/mesh_ops.h"

namespace st::sim {
namespace {

RenderSettings default_render(const SimOptions& o, int W, int H) {
  RenderSettings r;
  // ~70 deg horizontal field of view, principal point a little off centre.
  r.K = Pinhole{0.72 * W, 0.72 * W, 0.5 * W - 0.5 + 3.25, 0.5 * H - 0.5 - 2.5, W, H};
  r.seed = o.seed;
  r.organ_detail = o.organ_detail;
  r.shutter = o.shutter;
  r.smoke = o.smoke;
  r.tissue = o.tissue;
  r.breathing_mm = o.breathing_mm;
  r.exposure *= o.light;
  const bool invivo = o.scenario == ScenarioKind::InVivo;
  r.field_stop = o.field_stop < 0 ? invivo : o.field_stop == 1;
  if (invivo) {
    r.distortion.count = 5;
    r.distortion.k = {-0.28, 0.10, 0.0005, -0.0004, -0.015, 0, 0, 0};
    r.noise_read = 0.012;
    r.noise_shot = 0.004;
    r.vignetting = 0.45;
  }
  return r;
}

}  // namespace

Result<SimSetup> make_setup(const SimOptions& o) {
  const bool invivo = o.scenario == ScenarioKind::InVivo;
  const int W = o.width > 0 ? o.width : (invivo ? 960 : 1280);
  const int H = o.height > 0 ? o.height : (invivo ? 540 : 720);
  if (W < 16 || H < 16 || W > kMaxImageWidth || H > kMaxImageHeight || W % 2 || H % 2)
    return make_error("frame size " + std::to_string(W) + "x" + std::to_string(H) +
                      " must be even and within 16x16.." + std::to_string(kMaxImageWidth) + "x" +
                      std::to_string(kMaxImageHeight));
  if (o.frames < 1 || o.frames > 1'000'000) return make_error("--frames must be in 1..1000000");
  if (o.tissue == Tissue::Smooth && o.mesh_file.empty())
    return make_error("smooth tissue is rendered on the CT liver: give --mesh shared/data/liver/liver.ply");
  SimSetup s;
  Mesh organ;
  if (o.mesh_file.empty()) {
    organ = make_organ_mesh(o.organ, o.seed);
  } else {
    auto loaded = load_mesh_file(o.mesh_file, nullptr);
    if (!loaded) return loaded.error();
    organ = std::move(loaded.value());
  }
  s.scene = make_scene(std::move(organ), o.seed);
  s.prior = s.scene.organ;
  if (invivo) {  // a CT segmentation: coarser and about 1 mm off
    s.prior = decimate(s.scene.organ, s.scene.organ.triangle_count() / 2);
    perturb_along_normals(s.prior, 1.0, o.seed + 31);
  }
  if (o.prior_subdivide > 0) s.prior = subdivide(s.prior, o.prior_subdivide);
  s.render = default_render(o, W, H);
  if (!o.texture_file.empty()) {
    auto photo = PhotoTexture::load(o.texture_file, o.texture_px_per_mm);
    if (!photo) return photo.error();
    s.render.organ_photo = photo.value();
  }
  s.frames = o.frames;
  return s;
}

std::vector<Marker> pick_markers(const std::vector<std::pair<Vec2, Vec3>>& c) {
  std::vector<Marker> out;
  if (c.empty()) return out;
  Vec2 centroid = Vec2::Zero();
  for (const auto& p : c) centroid += p.first / static_cast<double>(c.size());
  std::vector<double> dist(c.size());
  for (std::size_t i = 0; i < c.size(); ++i) dist[i] = (c[i].first - centroid).norm();
  for (int k = 0; k < 3; ++k) {
    const auto best = static_cast<std::size_t>(std::max_element(dist.begin(), dist.end()) - dist.begin());
    if (k > 0 && dist[best] <= 0.0) break;
    out.push_back(Marker{k + 1, c[best].second});
    for (std::size_t i = 0; i < c.size(); ++i)
      dist[i] = k == 0 ? (c[i].first - c[best].first).norm() : std::min(dist[i], (c[i].first - c[best].first).norm());
  }
  return out;
}

}  // namespace st::sim
