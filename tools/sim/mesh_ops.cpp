#include "tools/sim/mesh_ops.h"

#include <algorithm>
#include <limits>
#include <unordered_map>

#include "tools/sim/noise.h"

namespace st::sim {

double signed_volume(const Mesh& m) {
  double v6 = 0.0;
  for (int t = 0; t < m.triangle_count(); ++t) {
    const Vec3 a = m.vertex(m.tri[3 * t]), b = m.vertex(m.tri[3 * t + 1]),
               c = m.vertex(m.tri[3 * t + 2]);
    v6 += a.dot(b.cross(c));
  }
  return v6 / 6.0;
}

bool is_closed_oriented(const Mesh& m) {
  std::unordered_map<std::uint64_t, int> directed;
  directed.reserve(m.tri.size() * 2);
  auto key = [](std::int32_t a, std::int32_t b) {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(a)) << 32) |
           static_cast<std::uint32_t>(b);
  };
  for (int t = 0; t < m.triangle_count(); ++t)
    for (int k = 0; k < 3; ++k)
      if (++directed[key(m.tri[3 * t + k], m.tri[3 * t + (k + 1) % 3])] != 1) return false;
  for (const auto& [k, n] : directed) {
    const auto a = static_cast<std::int32_t>(k >> 32), b = static_cast<std::int32_t>(k & 0xffffffffu);
    if (directed.find(key(b, a)) == directed.end()) return false;
  }
  return !directed.empty();
}

std::vector<Vec3f> vertex_normals(const Mesh& m) {
  std::vector<Vec3f> n(static_cast<std::size_t>(m.vertex_count()), Vec3f::Zero());
  for (int t = 0; t < m.triangle_count(); ++t) {
    const std::int32_t i = m.tri[3 * t], j = m.tri[3 * t + 1], k = m.tri[3 * t + 2];
    const Vec3f a(m.x[i], m.y[i], m.z[i]), b(m.x[j], m.y[j], m.z[j]), c(m.x[k], m.y[k], m.z[k]);
    const Vec3f fn = (b - a).cross(c - a);  // length = 2 * area: area weighting
    n[i] += fn;
    n[j] += fn;
    n[k] += fn;
  }
  for (auto& v : n) {
    const float len = v.norm();
    v = len > 0 ? Vec3f(v / len) : Vec3f(0, 0, 1);
  }
  return n;
}

Box bounding_box(const Mesh& m) {
  Box b{Vec3::Constant(std::numeric_limits<double>::max()),
        Vec3::Constant(std::numeric_limits<double>::lowest())};
  for (int i = 0; i < m.vertex_count(); ++i) {
    b.min = b.min.cwiseMin(m.vertex(i));
    b.max = b.max.cwiseMax(m.vertex(i));
  }
  return b;
}

void centre_on_box(Mesh& m) {
  const Vec3 c = bounding_box(m).centre();
  for (int i = 0; i < m.vertex_count(); ++i) {
    m.x[i] = static_cast<float>(static_cast<double>(m.x[i]) - c.x());
    m.y[i] = static_cast<float>(static_cast<double>(m.y[i]) - c.y());
    m.z[i] = static_cast<float>(static_cast<double>(m.z[i]) - c.z());
  }
}

void append_mesh(Mesh& a, const Mesh& b) {
  const auto base = static_cast<std::int32_t>(a.vertex_count());
  a.x.insert(a.x.end(), b.x.begin(), b.x.end());
  a.y.insert(a.y.end(), b.y.begin(), b.y.end());
  a.z.insert(a.z.end(), b.z.begin(), b.z.end());
  for (const std::int32_t v : b.tri) a.tri.push_back(v + base);
}

Mesh subdivide(const Mesh& mesh, int levels) {
  Mesh m = mesh;
  for (int level = 0; level < levels; ++level) {
    std::unordered_map<std::uint64_t, std::int32_t> midpoint;
    midpoint.reserve(m.tri.size());
    const auto mid = [&](std::int32_t a, std::int32_t b) {
      const auto key = (static_cast<std::uint64_t>(std::min(a, b)) << 32) | static_cast<std::uint32_t>(std::max(a, b));
      const auto [it, inserted] = midpoint.emplace(key, m.vertex_count());
      if (inserted) {
        const Vec3 p = 0.5 * (m.vertex(a) + m.vertex(b));
        m.add_vertex(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
      }
      return it->second;
    };
    std::vector<std::int32_t> tri;
    tri.reserve(m.tri.size() * 4);
    for (std::size_t t = 0; t + 2 < m.tri.size(); t += 3) {
      const std::int32_t a = m.tri[t], b = m.tri[t + 1], c = m.tri[t + 2];
      const std::int32_t ab = mid(a, b), bc = mid(b, c), ca = mid(c, a);
      for (const std::int32_t v : {a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca}) tri.push_back(v);
    }
    m.tri = std::move(tri);
  }
  return m;
}

void perturb_along_normals(Mesh& m, double amplitude_mm, std::uint64_t seed) {
  const std::vector<Vec3f> n = vertex_normals(m);
  const Noise3 noise(seed);
  const float f = 1.0f / 20.0f;  // wavelength ~20 mm
  for (int i = 0; i < m.vertex_count(); ++i) {
    // fbm of 2 octaves mostly stays within [-0.45, 0.45]: scale, clamp to the amplitude.
    const float s = std::clamp(noise.fbm(m.x[i] * f, m.y[i] * f, m.z[i] * f, 2) / 0.45f, -1.0f, 1.0f);
    const auto d = static_cast<float>(amplitude_mm) * s;
    m.x[i] += d * n[i].x();
    m.y[i] += d * n[i].y();
    m.z[i] += d * n[i].z();
  }
}

}  // namespace st::sim
