#include "tools/sim/organ_shapes.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "tools/sim/liver_mesh.h"
#include "tools/sim/noise.h"

namespace st::sim {
namespace {

constexpr int kSubdivisions = 5;  // 20,480 triangles, as the liver

// A proportion in [1 - 0.08, 1 + 0.08] drawn from the seed's noise at a
// fixed probe point (deterministic, different per probe).
double proportion(const Noise3& noise, float probe) {
  return 1.0 + 0.08 * std::clamp(static_cast<double>(noise.fbm(probe, 0.37f * probe, 1.7f, 1)) / 0.45, -1.0, 1.0);
}

// Kidney: an ellipsoid with half-axes a (long, x), b (y), c (z), the hilum
// a dent on its +y (medial) border halfway along, a slightly thicker upper
// pole and a gentle bow in z.
Vec3 kidney_point(const Vec3& d, double a, double b, double c, double irregular) {
  const double y_medial = std::max(0.0, d.y());
  const double dent = 0.35 * std::exp(-((d.x() / 0.45) * (d.x() / 0.45) + (d.z() / 0.5) * (d.z() / 0.5))) *
                      y_medial * std::sqrt(y_medial);
  const double r = (1.0 - dent) * irregular;
  return Vec3(a * r * d.x() * (1.0 + 0.08 * d.y()), b * r * d.y(), c * r * d.z() + 3.0 * d.x() * d.x());
}

// Stomach: a flattened ellipsoid bent into a J along y (the greater
// curvature), thinner towards the pylorus (+x).
Vec3 stomach_point(const Vec3& d, double a, double b, double c, double irregular) {
  const double r = irregular;
  return Vec3(a * r * d.x(), b * r * d.y() + 20.0 * d.x() * d.x(), c * r * d.z() * (1.0 - 0.3 * d.x()));
}

}  // namespace

Result<OrganKind> parse_organ(std::string_view name) {
  if (name == "liver") return OrganKind::Liver;
  if (name == "kidney") return OrganKind::Kidney;
  if (name == "stomach") return OrganKind::Stomach;
  return make_error("unknown organ '" + std::string(name) + "': use liver, kidney or stomach");
}

const char* organ_name(OrganKind kind) {
  switch (kind) {
    case OrganKind::Liver: return "liver";
    case OrganKind::Kidney: return "kidney";
    case OrganKind::Stomach: return "stomach";
  }
  return "?";
}

Mesh make_organ_mesh(OrganKind kind, std::uint64_t seed) {
  if (kind == OrganKind::Liver) {
    LiverShape shape;
    shape.seed = seed;
    return make_liver_mesh(shape);
  }
  const Noise3 noise(seed);
  const bool kidney = kind == OrganKind::Kidney;
  const double a = (kidney ? 58.0 : 95.0) * proportion(noise, 3.1f);
  const double b = (kidney ? 32.0 : 55.0) * proportion(noise, 7.3f);
  const double c = (kidney ? 24.0 : 35.0) * proportion(noise, 11.9f);
  return map_icosphere(kSubdivisions, [&](const Vec3& d) {
    const double irregular =
        1.0 + 0.04 * static_cast<double>(noise.fbm(static_cast<float>(1.5 * d.x()), static_cast<float>(1.5 * d.y()),
                                                    static_cast<float>(1.5 * d.z()), 2));
    return kidney ? kidney_point(d, a, b, c, irregular) : stomach_point(d, a, b, c, irregular);
  });
}

}  // namespace st::sim
