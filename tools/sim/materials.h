// Tissue appearance, defined in each mesh's own frame (mm) so the texture
// sticks to the surface. Colours are linear RGB albedo in [0, 1]; the
// renderer applies the light, then a display gamma.
//
// Split for speed: low-frequency colour variation is evaluated once per
// vertex (albedo_at_vertex, configure time); vessels and fine speckle are
// evaluated per pixel (detail_at, allocation-free, a few noise lookups).
#pragma once

#include <cstdint>

#include "core/geometry/se3.h"
#include "tools/sim/noise.h"

namespace st::sim {

enum class MaterialId : std::uint8_t { Liver = 0, Fat, Wall, Neighbour, Instrument, Count };

// The organ's tissue: Textured is the liver calibrated on the real frame's
// raw corner count (speckle, lobule spots, vessels); Smooth is what a real
// liver looks like once its sensor noise is gone (about 1 surface-fixed
// FAST>20 corner per 10k organ pixels): smooth mottling only, and a wet
// film that puts many small saturated highlights on it.
enum class Tissue : std::uint8_t { Textured = 0, Smooth };

struct Material {
  Vec3f base{0.3f, 0.05f, 0.04f};    // linear albedo
  Vec3f alt{0.2f, 0.05f, 0.05f};     // blended with base by low-frequency fbm
  float variation_mm = 25.0f;        // wavelength of the base/alt blend
  Vec3f vessel{0.1f, 0.02f, 0.03f};  // albedo inside a vessel
  float vessel_mm = 18.0f;           // spacing of the vessel network
  float vessel_width = 0.06f;        // half-width in noise units (0 = none)
  float vessel_strength = 0.5f;      // 0..1 blend towards the vessel colour
  float vessel_scale = 1.0f;         // vessel lines' weight in the vessel channel (spots share it)
  float speckle_mm = 0.6f;           // grain size of the fine speckle
  float speckle_strength = 0.08f;    // relative albedo modulation
  float specular = 0.35f;            // Blinn-Phong weight (wet tissue is glossy)
  int shininess_log2 = 5;            // exponent 2^k: 32
  float lobules = 0.0f;              // darker creases between round lobules (fat)
  float lobule_mm = 9.0f;
  float mottle = 0.12f;              // relative brightness variation of patches (~4-8 mm)
  float fine_mm = 0.0f;              // second, coarser speckle scale (liver lobules); 0 = none
  float spots = 0.0f;                // strength of small dark spots (0..1), in the vessel channel
  float spot_mm = 2.2f;              // spacing of the spots (lobule centres)
  float spot_radius_mm = 0.3f;
  // Smooth tissue: > 0 puts a smooth relative-brightness mottle of this
  // wavelength (and half of it, weaker) in the speckle channel instead of
  // the speckle, spots and vessels.
  float smooth_mottle_mm = 0.0f;
  float smooth_fine = 0.0f;  // weight of the finest octave (smooth_mottle_mm / 4.1): the few corners
  // Wet film: a second, sharper specular lobe on a normal tilted by small
  // ripples of the film (wavelength film_mm and 0.45 of it), so a surface
  // turned towards the scope breaks into many small glints that slide as
  // the scope moves. film = 0: none.
  float film = 0.0f;
  int film_shininess_log2 = 11;
  float film_tilt = 0.0f;  // the ripples' largest normal tilt, radians (about)
  float film_mm = 3.0f;
};

Material material(MaterialId id);
// The liver of Tissue::Smooth: glossier (a sharper, brighter lobe), the wet
// film, no fine texture; colour mottling at >= 3 mm only.
Material smooth_liver();

class Texture {
 public:
  explicit Texture(std::uint64_t seed) : noise_(seed), detail_(seed ^ 0x5A5A5A5Aull) {}
  // Per-vertex albedo: base/alt blend, lobule creases, brightness variation.
  Vec3f albedo_at_vertex(const Material& m, const Vec3f& p_mm) const;
  // Fine detail at a point: vessel weight and speckle, both in [0, 1]
  // (the renderer bakes these into per-triangle texel grids).
  struct Detail {
    float vessel = 0, speckle = 0.5f;
  };
  Detail detail_sample(const Material& m, const Vec3f& p_mm) const;
  // Smooth tissue (m.smooth_mottle_mm > 0): no vessel, the speckle channel
  // a smooth mottle in [0, 1] around 0.5.
  Detail smooth_sample(const Material& m, const Vec3f& p_mm) const;
  // The wet film's normal tilt at a point: the gradient of its ripple
  // height field, in units of m.film_tilt (length mostly < 1), model frame
  // (the caller removes the component along the surface normal).
  Vec3f film_tilt(const Material& m, const Vec3f& p_mm) const;
  // Albedo after vessels and speckle, from the interpolated vertex albedo.
  static Vec3f apply_detail(const Material& m, const Vec3f& albedo, float vessel, float speckle) {
    const Vec3f a = albedo + (vessel * m.vessel_strength) * (m.vessel - albedo);
    return a * (1.0f + 2.0f * m.speckle_strength * (speckle - 0.5f));
  }
  Vec3f detail_at(const Material& m, const Vec3f& p_mm, const Vec3f& albedo) const {
    const Detail d = detail_sample(m, p_mm);
    return apply_detail(m, albedo, d.vessel, d.speckle);
  }

 private:
  Noise3 noise_;
  Noise3 detail_;
};

}  // namespace st::sim
