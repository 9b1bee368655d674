#include "tools/sim/scene.h"

#include <algorithm>
#include <cmath>

#include "tools/sim/liver_mesh.h"
#include "tools/sim/noise.h"

namespace st::sim {

Mesh make_instrument_mesh(double radius_mm, double length_mm, int segments) {
  // Rings along z: jaw tip (narrow), jaw base, shaft start, shaft end.
  const double z[4] = {-12.0, -1.0, 0.0, length_mm};
  const double r[4] = {0.35 * radius_mm, 0.9 * radius_mm, radius_mm, radius_mm};
  Mesh m;
  for (int k = 0; k < 4; ++k)
    for (int s = 0; s < segments; ++s) {
      const double a = 2.0 * M_PI * s / segments;
      m.add_vertex(static_cast<float>(r[k] * std::cos(a)), static_cast<float>(r[k] * std::sin(a)),
                   static_cast<float>(z[k]));
    }
  for (int k = 0; k < 3; ++k)
    for (int s = 0; s < segments; ++s) {
      const int s1 = (s + 1) % segments;
      const int a = k * segments + s, b = k * segments + s1, c = (k + 1) * segments + s1,
                d = (k + 1) * segments + s;
      m.add_triangle(a, b, c);  // outward: counter-clockwise seen from outside
      m.add_triangle(a, c, d);
    }
  // Caps: centre vertices at both ends.
  m.add_vertex(0, 0, static_cast<float>(z[0]));
  m.add_vertex(0, 0, static_cast<float>(z[3]));
  const int tip = m.vertex_count() - 2, end = m.vertex_count() - 1;
  for (int s = 0; s < segments; ++s) {
    const int s1 = (s + 1) % segments;
    m.add_triangle(tip, s1, s);
    m.add_triangle(end, 3 * segments + s, 3 * segments + s1);
  }
  return m;
}

Mesh make_blob(const Vec3& c, const Vec3& r, double yaw_rad, std::uint64_t seed) {
  Mesh m = make_icosphere(3);
  const Noise3 noise(seed);
  const Mat3 R = Eigen::AngleAxisd(yaw_rad, Vec3::UnitZ()).toRotationMatrix();
  for (int i = 0; i < m.vertex_count(); ++i) {
    const Vec3 d = m.vertex(i);
    const double bump = 1.0 + 0.08 * static_cast<double>(noise.fbm(
                                         static_cast<float>(2 * d.x()), static_cast<float>(2 * d.y()),
                                         static_cast<float>(2 * d.z()), 2));
    const Vec3 p = c + R * Vec3(d.x() * r.x(), d.y() * r.y(), d.z() * r.z()) * bump;
    m.x[i] = static_cast<float>(p.x());
    m.y[i] = static_cast<float>(p.y());
    m.z[i] = static_cast<float>(p.z());
  }
  return m;
}

Mesh make_floor(const Box& box, double floor_z, std::uint64_t seed, std::vector<MaterialId>* material) {
  const Noise3 noise(seed);
  const int n = 110;
  const double half = 320.0;
  const double r0 = 0.65 * std::max(box.size().x(), box.size().y()) + 20.0;
  const double k = 230.0 / ((half - r0) * (half - r0));
  Mesh m;
  auto height = [&](double x, double y) {
    const double r = std::hypot(x, y);
    const auto fx = static_cast<float>(x), fy = static_cast<float>(y);
    // Fat lobules (~15 mm) on a gently rolling floor, then the bowl wall.
    const double lobes = 2.5 * static_cast<double>(noise.gradient(fx / 15.0f, fy / 15.0f, 0.5f));
    const double roll = 6.0 * static_cast<double>(noise.fbm(fx / 90.0f, fy / 90.0f, 3.3f, 2));
    const double wall = r > r0 ? k * (r - r0) * (r - r0) : 0.0;
    return floor_z + lobes + roll + wall;
  };
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      const double x = -half + 2.0 * half * i / n, y = -half + 2.0 * half * j / n;
      m.add_vertex(static_cast<float>(x), static_cast<float>(y), static_cast<float>(height(x, y)));
    }
  material->clear();
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const int a = j * (n + 1) + i, b = a + 1, c = a + n + 2, d = a + n + 1;
      m.add_triangle(a, b, c);  // counter-clockwise seen from above (+z)
      m.add_triangle(a, c, d);
      const double cx = -half + 2.0 * half * (i + 0.5) / n, cy = -half + 2.0 * half * (j + 0.5) / n;
      const double rise = height(cx, cy) - floor_z;
      const double edge = 30.0 + 25.0 * static_cast<double>(noise.gradient(
                                            static_cast<float>(cx / 60.0), static_cast<float>(cy / 60.0), 7.1f));
      const MaterialId id = rise < edge ? MaterialId::Fat : MaterialId::Wall;
      material->push_back(id);
      material->push_back(id);
    }
  return m;
}

Scene make_scene(Mesh organ, std::uint64_t seed) {
  Scene s;
  const Box box = bounding_box(organ);
  s.T_world_model_rest = SE3(Mat3::Identity(), -box.centre());
  s.organ_box_world = {box.min - box.centre(), box.max - box.centre()};
  s.organ = std::move(organ);
  // The organ floats a few mm above the floor bumps so the floor never cuts
  // into its visible surface (the ground-truth mask is then the whole organ).
  s.floor_z_mm = s.organ_box_world.min.z() - 12.0;
  s.background = make_floor(s.organ_box_world, s.floor_z_mm, seed + 11, &s.background_material);
  const Box& b = s.organ_box_world;
  const Mesh gall = make_blob(Vec3(-0.15 * b.size().x(), b.max.y() + 24.0, s.floor_z_mm + 14.0),
                              Vec3(36, 19, 15), 0.35, seed + 12);
  const Mesh stomach = make_blob(Vec3(b.max.x() + 45.0, 0.15 * b.size().y(), s.floor_z_mm + 16.0),
                                 Vec3(48, 42, 22), -0.5, seed + 13);
  append_mesh(s.background, gall);
  s.background_material.insert(s.background_material.end(), static_cast<std::size_t>(gall.triangle_count()),
                               MaterialId::Neighbour);
  append_mesh(s.background, stomach);
  s.background_material.insert(s.background_material.end(),
                               static_cast<std::size_t>(stomach.triangle_count()), MaterialId::Wall);
  s.instrument = make_instrument_mesh(s.instrument_radius_mm, 350.0, 24);
  return s;
}

}  // namespace st::sim
