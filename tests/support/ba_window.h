// A simulated bundle-adjustment window on a mesh, shared by the BA tests and
// the `ba` bench stage (header-only: the bench includes it without a build
// change). Keyframes on an arc around the organ, map points sampled on the
// mesh surface (front-facing, inside the image), observations with octave
// noise; then the window's poses and points are perturbed as the issue
// asks (poses 1 deg / 2 mm, points 1 mm), the older keyframes stay exact.
#pragma once

#include <cmath>
#include <random>
#include <vector>

#include "core/mapping/ba_job.h"
#include "core/geometry/camera.h"
#include "core/pose/correspondences.h"
#include "core/mesh/mesh.h"
#include "tests/support/draws.h"
#include "tests/support/raster_scene.h"

namespace st::test {

struct BaWindowSpec {
  int window_keyframes = 8;
  int fixed_keyframes = 2;     // older keyframes observing the same points, held constant
  int points = 1000;
  double step_deg = 2.5;       // azimuth between consecutive keyframes
  double distance_mm = 170.0;  // camera to the mesh's box centre
  double pixel_sigma = 0.5;    // level-0 noise, scaled by 1.2^octave
  double pose_rot_deg = 1.0, pose_trans_mm = 2.0, point_mm = 1.0;  // perturbation
  std::uint32_t seed = 1;
};

struct BaWindow {
  std::vector<SE3> T_true;       // per job keyframe (fixed ones first)
  std::vector<Vec3> p_true;      // per job point
  BaJob job;                     // perturbed start values
};

inline BaWindow make_ba_window(const Mesh& mesh, const Pinhole& K, const BaWindowSpec& spec) {
  std::mt19937 rng(spec.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  BaWindow w;
  const int nk = spec.fixed_keyframes + spec.window_keyframes;
  const Vec3 target = bbox_centre(mesh);
  for (int k = 0; k < nk; ++k) {
    const double az = (k - nk / 2) * spec.step_deg * M_PI / 180.0, el = 0.1 * std::sin(k * 0.7);
    const Vec3 dir(std::sin(az) * std::cos(el), std::sin(el), std::cos(az) * std::cos(el));
    w.T_true.push_back(look_at(target, dir, spec.distance_mm, 0.05 * k));
  }
  struct Obs { int k; Vec2 px; int octave; };
  std::vector<std::vector<Obs>> obs;
  for (int tries = 0; static_cast<int>(w.p_true.size()) < spec.points && tries < 200 * spec.points; ++tries) {
    const int t = static_cast<int>(u(rng) * mesh.triangle_count()) % mesh.triangle_count();
    const Vec3 a = mesh.vertex(mesh.tri[3 * t]), b = mesh.vertex(mesh.tri[3 * t + 1]), c = mesh.vertex(mesh.tri[3 * t + 2]);
    double s1 = u(rng), s2 = u(rng);
    if (s1 + s2 > 1) s1 = 1 - s1, s2 = 1 - s2;
    const Vec3 p = a + s1 * (b - a) + s2 * (c - a), n = (b - a).cross(c - a).normalized();
    std::vector<Obs> seen;
    for (int k = 0; k < nk; ++k) {
      const Vec3 pc = w.T_true[static_cast<std::size_t>(k)] * p;
      const Vec3 centre = w.T_true[static_cast<std::size_t>(k)].inverse().translation();
      const Vec2 px = K.project(pc);
      if (pc.z() < 10 || !K.in_image(px, 10.0) || n.dot(centre - p) <= 0) continue;
      const int octave = static_cast<int>(u(rng) * 4) % 4;
      seen.push_back({k, px + spec.pixel_sigma * std::pow(1.2, octave) * draw_vec2(g, rng), octave});
    }
    int in_window = 0;
    for (const Obs& o : seen) in_window += o.k >= spec.fixed_keyframes ? 1 : 0;
    if (in_window < 2) continue;
    w.p_true.push_back(p);
    obs.push_back(seen);
  }
  int total = 0;
  for (const auto& o : obs) total += static_cast<int>(o.size());
  if (!w.job.configure(nk, static_cast<int>(w.p_true.size()) + 1, total + 1).ok()) return w;
  for (int k = 0; k < nk; ++k) {
    SE3 T = w.T_true[static_cast<std::size_t>(k)];
    const bool fixed = k < spec.fixed_keyframes;
    if (!fixed) {
      const Vec3 rot = spec.pose_rot_deg * M_PI / 180.0 * random_unit(rng);
      T = SE3(so3_exp(rot), spec.pose_trans_mm * random_unit(rng)) * T;
    }
    w.job.add_keyframe(k, 100 + k, T, fixed);
  }
  for (std::size_t i = 0; i < w.p_true.size(); ++i) {
    const int j = w.job.add_point(static_cast<int>(i), 0, w.p_true[i] + spec.point_mm * random_unit(rng));
    for (const Obs& o : obs[i]) w.job.add_observation(o.k, j, o.px, octave_information(o.octave));
  }
  return w;
}

}  // namespace st::test
