#include "support/track_scene.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>

#include "support/raster_scene.h"
#include "support/support.h"
#include "support/test_ply.h"

namespace st::test {

namespace {

double lattice(int x, int y, int z) {
  std::uint32_t h = static_cast<std::uint32_t>(x) * 73856093u ^ static_cast<std::uint32_t>(y) * 19349663u ^
                    static_cast<std::uint32_t>(z) * 83492791u;
  h ^= h >> 13;
  h *= 0x5bd1e995u;
  h ^= h >> 15;
  return static_cast<double>(h & 0xffffu) / 65535.0;
}

// Trilinear value noise with cells of cell_mm, in [0, 1].
double value_noise(const Vec3& p, double cell_mm) {
  const Vec3 q = p / cell_mm;
  const int x = static_cast<int>(std::floor(q.x())), y = static_cast<int>(std::floor(q.y())),
            z = static_cast<int>(std::floor(q.z()));
  const double fx = q.x() - x, fy = q.y() - y, fz = q.z() - z;
  double v = 0;
  for (int c = 0; c < 8; ++c) {
    const int dx = c & 1, dy = (c >> 1) & 1, dz = (c >> 2) & 1;
    const double w = (dx ? fx : 1 - fx) * (dy ? fy : 1 - fy) * (dz ? fz : 1 - fz);
    v += w * lattice(x + dx, y + dy, z + dz);
  }
  return v;
}

double texture(const Vec3& p_model) {
  return 0.45 * value_noise(p_model, 6.0) + 0.35 * value_noise(p_model, 2.5) + 0.2 * value_noise(p_model, 1.2);
}

}  // namespace

Mesh load_liver_for_tracking() {
  auto mesh = read_binary_ply_for_tests(read_file_bytes(shared_data("liver/liver.ply")));
  if (!mesh.ok()) FAIL(mesh.message());
  return std::move(mesh).value();
}

void TrackSceneRenderer::configure(const Mesh& mesh, const Pinhole& K) {
  K_ = K;
  RasterConfig rc;
  rc.width = K.width;
  rc.height = K.height;
  REQUIRE(raster_.configure(mesh, rc).ok());
  normal_model_.resize(static_cast<std::size_t>(mesh.triangle_count()));
  for (int t = 0; t < mesh.triangle_count(); ++t) {
    const auto i = static_cast<std::size_t>(3 * t);
    const Vec3 a = mesh.vertex(mesh.tri[i]), b = mesh.vertex(mesh.tri[i + 1]), c = mesh.vertex(mesh.tri[i + 2]);
    normal_model_[static_cast<std::size_t>(t)] = (b - a).cross(c - a).normalized();
  }
  tmp_.allocate(K.width, K.height);
}

void TrackSceneRenderer::render(const SE3& T_camera_model, Image<std::uint8_t>* luma) {
  raster_.render(T_camera_model, K_);
  luma->allocate(K_.width, K_.height);
  const Vec3 centre = -(T_camera_model.rotation().transpose() * T_camera_model.translation());
  const auto depth = raster_.depth();
  const auto id = raster_.triangle_id();
  for (int y = 0; y < K_.height; ++y)
    for (int x = 0; x < K_.width; ++x) {
      double v = 22.0;
      if (depth(x, y) > 0.f) {
        const Vec3 p = raster_.model_point(Vec2(x, y), static_cast<double>(depth(x, y)));
        const Vec3 n = normal_model_[static_cast<std::size_t>(id(x, y))];
        const double lambert = std::abs(n.dot((centre - p).normalized()));
        v = 30.0 + 200.0 * texture(p) * (0.35 + 0.65 * lambert);
      }
      tmp_(x, y) = static_cast<std::uint8_t>(std::clamp(v, 0.0, 255.0));
    }
  // [1 2 1]^2 / 16 smoothing: the optics' blur, and less aliasing.
  for (int y = 0; y < K_.height; ++y)
    for (int x = 0; x < K_.width; ++x) {
      int s = 0;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const int xx = std::clamp(x + dx, 0, K_.width - 1), yy = std::clamp(y + dy, 0, K_.height - 1);
          s += (2 - std::abs(dx)) * (2 - std::abs(dy)) * tmp_(xx, yy);
        }
      (*luma)(x, y) = static_cast<std::uint8_t>((s + 8) / 16);
    }
}

std::vector<SE3> liver_orbit(const Mesh& mesh, int frames) {
  const Vec3 target = bbox_centre(mesh);
  std::vector<SE3> poses;
  for (int i = 0; i < frames; ++i) {
    const double s = frames > 1 ? static_cast<double>(i) / (frames - 1) : 0.0;
    const double az = (-25.0 + 50.0 * s) * M_PI / 180.0;
    const double el = 10.0 * std::sin(2.0 * M_PI * s) * M_PI / 180.0;
    const Vec3 dir(std::sin(az) * std::cos(el), std::sin(el), std::cos(az) * std::cos(el));
    const double distance = 245.0 + 15.0 * std::cos(2.0 * M_PI * s);
    poses.push_back(look_at(target, dir, distance, 0.3 * std::sin(M_PI * s)));
  }
  return poses;
}

RenderedOrbit render_liver_orbit(int frames) {
  RenderedOrbit s;
  s.mesh = load_liver_for_tracking();
  s.K = track_test_pinhole();
  s.T_camera_model = liver_orbit(s.mesh, frames);
  TrackSceneRenderer renderer;
  renderer.configure(s.mesh, s.K);
  s.frames.resize(s.T_camera_model.size());
  for (std::size_t i = 0; i < s.frames.size(); ++i) renderer.render(s.T_camera_model[i], &s.frames[i]);
  return s;
}

double reprojection_gap_px(const RenderedOrbit& s, const SE3& T_camera_model, const SE3& truth) {
  double worst = 0;
  const int n = s.mesh.vertex_count();
  const int step = std::max(1, n / 40);
  for (int i = 0; i < n; i += step) {
    const Vec3 p = s.mesh.vertex(i);
    const Vec3 a = T_camera_model * p, b = truth * p;
    if (a.z() <= 0 || b.z() <= 0) return 1e9;
    worst = std::max(worst, (s.K.project(a) - s.K.project(b)).norm());
  }
  return worst;
}

const RenderedOrbit& liver_orbit40() {
  static const RenderedOrbit r = render_liver_orbit(40);
  return r;
}

TrackerConfig small_tracker_config(const Pinhole& K) {
  TrackerConfig c;
  c.width = K.width;
  c.height = K.height;
  c.features.n_features = 1000;
  c.max_map_points = 3000;
  c.max_keyframes = 12;
  c.keyframe_angle_deg = 3.0;
  c.ba_max_observations = 12000;
  return c;
}

}  // namespace st::test
