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
      m.vessel_strength = 1.0f;
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

Material smooth_liver() {
  Material m = material(MaterialId::Liver);
  // Per-vertex mottling would be sampled at the CT mesh's ~4 mm vertex
  // spacing (creases at every vertex): the texel grid carries it instead.
  m.mottle = 0.0f;
  m.variation_mm = 30.0f;  // broad lobe-scale colour drift (per vertex: smooth)
  m.smooth_mottle_mm = 7.0f;
  m.smooth_fine = 0.25f;
  m.speckle_strength = 0.6f;
  // Small dark marks of random strength (the vessel channel), most too
  // faint for FAST: the few surface-fixed corners a tracker can hold on
  // to, as on the real frame once its noise is gone.
  m.vessel_strength = 1.0f;
  m.spots = 1.0f;
  m.spot_mm = 2.5f;  // calibrated: ~1 FAST>20 corner per 10k organ px without noise
  m.spot_radius_mm = 0.6f;  // a dark core of ~2 px inside FAST's 3 px ring
  m.specular = 0.9f;
  m.shininess_log2 = 8;
  m.film = 3.0f;
  m.film_shininess_log2 = 11;
  m.film_tilt = 0.14f;
  m.film_mm = 3.0f;
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

Texture::Detail Texture::smooth_sample(const Material& m, const Vec3f& p) const {
  const float f = 1.0f / m.smooth_mottle_mm;
  // Two smooth octaves (9 and 4 mm by default) and a faint third: patches
  // of brighter and darker tissue with soft edges, no point-like features.
  const float a = noise_.gradient(p.x() * f + 5.3f, p.y() * f, p.z() * f + 1.9f);
  const float b = noise_.gradient(p.x() * 2.2f * f, p.y() * 2.2f * f + 3.7f, p.z() * 2.2f * f);
  const float c = detail_.gradient(p.x() * 4.1f * f + 0.7f, p.y() * 4.1f * f, p.z() * 4.1f * f + 6.2f);
  Detail d;
  d.speckle = std::clamp(0.5f + 0.5f * (a + 0.5f * b + m.smooth_fine * c), 0.0f, 1.0f);
  if (m.spots > 0.0f) {  // soft-edged, of random strength (most faint)
    const float t = 1.0f / m.spot_mm;
    const Noise3::Cell cell = noise_.cellular(p.x() * t + 3.3f, p.y() * t + 0.4f, p.z() * t + 7.9f);
    const float r = cell.distance * m.spot_mm / m.spot_radius_mm;
    d.vessel = std::min(1.0f, std::clamp(2.5f * (1.0f - r), 0.0f, 1.0f) * m.spots * cell.value);
  }
  return d;
}

Vec3f Texture::film_tilt(const Material& m, const Vec3f& p) const {
  // Central differences of two octaves of ripples; the height is in units
  // of the wavelength, so the gradient is dimensionless (a slope).
  auto height = [&](const Vec3f& q) {
    const float f = 1.0f / m.film_mm, g = f / 0.45f;
    return detail_.gradient(q.x() * f + 11.3f, q.y() * f, q.z() * f + 2.1f) +
           0.45f * detail_.gradient(q.x() * g, q.y() * g + 4.4f, q.z() * g + 13.7f);
  };
  const float h = 0.05f * m.film_mm;
  Vec3f grad;
  for (int k = 0; k < 3; ++k) {
    Vec3f e = Vec3f::Zero();
    e[k] = h;
    grad[k] = (height(p + e) - height(p - e)) / (2.0f * h);
  }
  return grad * (m.film_mm / (2.0f * static_cast<float>(M_PI)));
}

}  // namespace st::sim
