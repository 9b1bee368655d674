#include "tools/sim/materials.h"

#include <algorithm>
#include <cmath>

namespace st::sim {

Material material(MaterialId id) {
  Material m;
  switch (id) {
    case MaterialId::Liver:  // dark red-brown, smooth, glossy, faint vessels
      m.base = {0.26f, 0.030f, 0.026f};
      m.alt = {0.19f, 0.034f, 0.040f};
      m.vessel = {0.12f, 0.016f, 0.026f};
      m.vessel_width = 0.05f;
      m.vessel_strength = 0.35f;
      m.speckle_strength = 0.07f;
      m.specular = 0.7f;
      m.shininess_log2 = 7;
      break;
    case MaterialId::Fat:  // yellow lobulated omentum with red vessels
      m.base = {0.80f, 0.46f, 0.08f};
      m.alt = {0.70f, 0.34f, 0.06f};
      m.variation_mm = 40.0f;
      m.vessel = {0.40f, 0.02f, 0.02f};
      m.vessel_mm = 30.0f;
      m.vessel_width = 0.035f;
      m.vessel_strength = 0.8f;
      m.speckle_strength = 0.06f;
      m.specular = 0.30f;
      m.shininess_log2 = 5;
      m.lobules = 0.35f;
      break;
    case MaterialId::Wall:  // diaphragm / abdominal wall: purple-grey, pink
      m.base = {0.30f, 0.15f, 0.20f};
      m.alt = {0.36f, 0.20f, 0.22f};
      m.variation_mm = 60.0f;
      m.vessel = {0.25f, 0.03f, 0.06f};
      m.vessel_mm = 35.0f;
      m.vessel_width = 0.04f;
      m.vessel_strength = 0.6f;
      m.speckle_strength = 0.05f;
      m.specular = 0.25f;
      m.shininess_log2 = 4;
      break;
    case MaterialId::Neighbour:  // gallbladder-like: pale blue-white, red vessels
      m.base = {0.40f, 0.42f, 0.48f};
      m.alt = {0.36f, 0.40f, 0.36f};
      m.vessel = {0.45f, 0.05f, 0.05f};
      m.vessel_mm = 14.0f;
      m.vessel_width = 0.04f;
      m.vessel_strength = 0.7f;
      m.speckle_strength = 0.05f;
      m.specular = 0.6f;
      m.shininess_log2 = 6;
      break;
    case MaterialId::Instrument:  // dark anodised steel shaft
    case MaterialId::Count:
      m.base = {0.045f, 0.045f, 0.05f};
      m.alt = {0.06f, 0.06f, 0.065f};
      m.vessel_width = 0.0f;
      m.speckle_strength = 0.02f;
      m.specular = 1.2f;
      m.shininess_log2 = 6;
      break;
  }
  return m;
}

Vec3f Texture::albedo_at_vertex(const Material& m, const Vec3f& p) const {
  const float f = 1.0f / m.variation_mm;
  const float blend = std::clamp(0.5f + 0.9f * noise_.fbm(p.x() * f, p.y() * f, p.z() * f, 3), 0.0f, 1.0f);
  Vec3f a = m.base + blend * (m.alt - m.base);
  // Brightness variation at ~8 mm: mottled, not flat.
  const float g = 0.125f;
  a *= 1.0f + 0.12f * noise_.gradient(p.x() * g + 3.1f, p.y() * g, p.z() * g);
  if (m.lobules > 0.0f) {
    const float l = 1.0f / m.lobule_mm;
    const float cell = noise_.value(p.x() * l, p.y() * l, p.z() * l);
    a *= 1.0f - m.lobules * std::max(0.0f, 0.45f - cell);
  }
  return a;
}

Texture::Detail Texture::detail_sample(const Material& m, const Vec3f& p) const {
  Detail d;
  if (m.vessel_width > 0.0f) {
    const float f = 1.0f / m.vessel_mm;
    // Two scales of zero-crossing lines: trunks and thinner branches.
    const float v1 = detail_.ridge(p.x() * f, p.y() * f, p.z() * f, m.vessel_width);
    const float v2 = detail_.ridge(p.x() * f * 2.3f + 7.7f, p.y() * f * 2.3f, p.z() * f * 2.3f,
                                   m.vessel_width * 0.8f);
    d.vessel = std::min(1.0f, v1 + 0.6f * v2);
  }
  const float s = 1.0f / m.speckle_mm;
  d.speckle = std::clamp(detail_.value(p.x() * s, p.y() * s, p.z() * s), 0.0f, 1.0f);
  return d;
}

Vec3f Texture::apply_detail(const Material& m, const Vec3f& albedo, float vessel, float speckle) {
  const Vec3f a = albedo + (vessel * m.vessel_strength) * (m.vessel - albedo);
  return a * (1.0f + 2.0f * m.speckle_strength * (speckle - 0.5f));
}

}  // namespace st::sim
