// Breathing: the organ's vertices displaced by a smooth, periodic field
// (the diaphragm pushes the liver along its long axis and bends it), in the
// organ's model frame, so the ground truth stays the organ's rigid frame
// and the prior (organ.ply) is the rest shape. Built once (allocates);
// displace() allocates nothing.
#pragma once

#include <vector>

#include "core/mesh/mesh.h"
#include "core/geometry/se3.h"

namespace st::sim {

// Largest accepted breathing amplitude, mm.
inline constexpr double kMaxBreathingMm = 20.0;
// One breath every 4 s: 120 frames at 30 frames/s.
inline constexpr double kBreathingPeriodS = 4.0;

class BreathingField {
 public:
  BreathingField() = default;
  // amplitude_mm: the largest displacement of any vertex, reached at the
  // middle of every breath (0: no breathing).
  BreathingField(const Mesh& rest, double amplitude_mm);

  bool enabled() const { return amplitude_mm_ > 0.0; }
  // Share of the full displacement at time t_s: 0 at rest (t = 0, so the
  // first frame shows the prior's shape), 1 half a period later; smooth
  // (raised cosine).
  static double phase(double t_s);
  // The displacement of a rest-shape point at phase 1, mm (model frame).
  Vec3 offset(const Vec3& p_rest) const;
  // rest's vertices displaced by phase * offset into out (same topology;
  // out must have rest's vertex count).
  void displace(const Mesh& rest, double phase, Mesh* out) const;

 private:
  Vec3 shape(const Vec3& p_rest) const;  // unscaled field
  double amplitude_mm_ = 0.0;
  double scale_ = 0.0;  // amplitude / the largest |shape| over the rest vertices
  Vec3 centre_ = Vec3::Zero(), inv_half_ = Vec3::Ones();
};

}  // namespace st::sim
