#include "tools/sim/materials.h"

#include <algorithm>
#include <cmath>

namespace st::sim {

Material material(MaterialId id) {
  Material m;
  switch (id) {
    case MaterialId::Liver:  // red-brown, glossy; mottled lobules, faint vessels and spots
      m.base = {0.25f, 0.046f, 0.040f};
      m.alt = {0.19f, 0.042f, 0.046f};
      m.variation_mm = 18.0f;
      m.mottle = 0.20f;
      m.vessel = {0.035f, 0.010f, 0.014f};
      m.vessel_mm = 14.0f;
      m.vessel_width = 0.05f;
      m.vessel_strength = 1.0f;
      m.speckle_mm = 0.55f;
      m.fine_mm = 1.4f;
      m.speckle_strength = 0.40f;
      m.spots = 1.0f;
      m.spot_mm = 1.1f;  // 3D cells: a surface cuts ~1 spot per 2 mm^2
      m.spot_radius_mm = 0.35f;
      m.vessel_scale = 0.4f;  // vessels 0.4 of the way to the vessel colour, spots up to all the way
      m.specular = 0.5f;
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
  // Brightness variation at ~8 and ~4 mm: mottled patches, not flat.
  const float g = 0.125f;
  a *= 1.0f + m.mottle * (noise_.gradient(p.x() * g + 3.1f, p.y() * g, p.z() * g) +
                          0.6f * noise_.gradient(p.x() * 2.1f * g, p.y() * 2.1f * g + 9.3f, p.z() * 2.1f * g));
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
    // Vessels run in patches, not as an even net of loops everywhere.
    const float patch = noise_.gradient(p.x() * f * 0.35f + 2.7f, p.y() * f * 0.35f, p.z() * f * 0.35f);
    d.vessel = std::min(1.0f, v1 + 0.6f * v2) * std::clamp(0.5f + 2.0f * patch, 0.0f, 1.0f) * m.vessel_scale;
  }
  const float s = 1.0f / m.speckle_mm;
  float speckle = detail_.value(p.x() * s, p.y() * s, p.z() * s);
  if (m.fine_mm > 0.0f) {  // lobular pattern: a coarser grain under the fine one
    const float l = 1.0f / m.fine_mm;
    speckle = 0.45f * speckle + 0.55f * detail_.value(p.x() * l + 4.1f, p.y() * l, p.z() * l + 8.3f);
    // Value noise of two scales clusters near 0.5: stretch it back to [0, 1].
    speckle = 0.5f + 1.6f * (speckle - 0.5f);
  }
  d.speckle = std::clamp(speckle, 0.0f, 1.0f);
  if (m.spots > 0.0f) {
    // Lobule centres: a small dark spot at every cellular feature point,
    // of random strength (many faint, some distinct), soft-edged.
    const float t = 1.0f / m.spot_mm;
    const Noise3::Cell c = noise_.cellular(p.x() * t + 1.7f, p.y() * t + 6.1f, p.z() * t);
    const float r = c.distance * m.spot_mm / m.spot_radius_mm;  // 1 at the spot's edge
    const float spot = std::clamp(3.0f * (1.0f - r), 0.0f, 1.0f) * m.spots * (0.5f + 0.5f * c.value);
    d.vessel = std::max(d.vessel, spot);
  }
  return d;
}


}  // namespace st::sim
