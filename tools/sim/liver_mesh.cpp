#include "tools/sim/liver_mesh.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include "tools/sim/mesh_ops.h"
#include "tools/sim/noise.h"

namespace st::sim {
namespace {

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

// Midpoint of edge (a, b) on the unit sphere, shared between the two faces.
std::int32_t midpoint(Mesh& m, std::unordered_map<std::uint64_t, std::int32_t>& cache,
                      std::int32_t a, std::int32_t b) {
  const std::uint64_t key = (static_cast<std::uint64_t>(std::min(a, b)) << 32) |
                            static_cast<std::uint32_t>(std::max(a, b));
  const auto it = cache.find(key);
  if (it != cache.end()) return it->second;
  const Vec3 p = (m.vertex(a) + m.vertex(b)).normalized();
  m.add_vertex(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
  const auto idx = static_cast<std::int32_t>(m.vertex_count() - 1);
  cache.emplace(key, idx);
  return idx;
}

// Radius of the liver surface along unit direction d (model frame).
double liver_radius(const Vec3& d, const LiverShape& s, const Noise3& noise) {
  const double a = d.x() < 0 ? s.right_lobe_x_mm : s.left_lobe_x_mm;
  const double b = s.half_depth_mm * (d.y() > 0 ? 1.0 : 0.9);
  // The left lobe thins out: thickness falls from the right lobe to the tip.
  // It also thins towards the sharp anterior (+y) border.
  const double taper = (1.0 - 0.6 * smoothstep(-0.3, 0.95, d.x())) * (1.0 - 0.45 * smoothstep(0.0, 0.95, d.y()));
  const double c = (d.z() > 0 ? s.dome_mm : s.visceral_mm) * taper;
  const double q = (d.x() / a) * (d.x() / a) + (d.y() / b) * (d.y() / b) + (d.z() / c) * (d.z() / c);
  double r = 1.0 / std::sqrt(q);
  // Lobes: the right lobe bulges backwards, a caudate-like bump underneath,
  // the falciform notch as a shallow groove across the top.
  r *= 1.0 + 0.10 * std::exp(-(d - Vec3(-0.6, -0.5, 0.3)).squaredNorm() / 0.15);
  r *= 1.0 + 0.08 * std::exp(-(d - Vec3(-0.1, -0.4, -0.7)).squaredNorm() / 0.08);
  r *= 1.0 + 0.06 * std::exp(-(d - Vec3(0.5, 0.6, 0.1)).squaredNorm() / 0.10);
  const double groove = d.x() - 0.15 - 0.2 * d.y();
  r *= 1.0 - 0.035 * std::exp(-groove * groove / 0.012) * smoothstep(-0.2, 0.4, d.z());
  // Anterior inferior edge notch (gallbladder fossa).
  r *= 1.0 - 0.08 * std::exp(-(d - Vec3(-0.2, 0.85, -0.3)).squaredNorm() / 0.03);
  r *= 1.0 + s.lobe_noise * static_cast<double>(noise.fbm(static_cast<float>(1.5 * d.x()), static_cast<float>(1.5 * d.y()),
                                      static_cast<float>(1.5 * d.z()), 2));
  return r;
}

}  // namespace

Mesh make_icosphere(int level) {
  const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
  Mesh m;
  const float v[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                          {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  for (const auto& p : v) {
    const Vec3 u = Vec3(p[0], p[1], p[2]).normalized();
    m.add_vertex(static_cast<float>(u.x()), static_cast<float>(u.y()), static_cast<float>(u.z()));
  }
  const int f[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                        {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                        {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                        {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
  for (const auto& tri : f) m.add_triangle(tri[0], tri[1], tri[2]);
  for (int l = 0; l < level; ++l) {
    std::unordered_map<std::uint64_t, std::int32_t> cache;
    std::vector<std::int32_t> old = m.tri;
    m.tri.clear();
    for (std::size_t i = 0; i < old.size(); i += 3) {
      const std::int32_t a = old[i], b = old[i + 1], c = old[i + 2];
      const std::int32_t ab = midpoint(m, cache, a, b), bc = midpoint(m, cache, b, c),
                         ca = midpoint(m, cache, c, a);
      m.add_triangle(a, ab, ca);
      m.add_triangle(b, bc, ab);
      m.add_triangle(c, ca, bc);
      m.add_triangle(ab, bc, ca);
    }
  }
  return m;
}

Mesh map_icosphere(int level, const std::function<Vec3(const Vec3&)>& surface) {
  Mesh m = make_icosphere(level);
  for (int i = 0; i < m.vertex_count(); ++i) {
    const Vec3 p = surface(m.vertex(i));
    m.x[i] = static_cast<float>(p.x());
    m.y[i] = static_cast<float>(p.y());
    m.z[i] = static_cast<float>(p.z());
  }
  centre_on_box(m);
  return m;
}

Mesh make_liver_mesh(const LiverShape& shape) {
  const Noise3 noise(shape.seed);
  return map_icosphere(shape.subdivisions, [&](const Vec3& d) { return Vec3(d * liver_radius(d, shape, noise)); });
}

}  // namespace st::sim
