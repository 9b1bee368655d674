// Breathing: the organ's vertices displaced by a smooth, periodic field
// (the diaphragm pushes the liver along its long axis and bends it), in the
// organ's model frame; the prior (organ.ply) is the rest shape. Built once
// (allocates); displace() allocates nothing.
//
// The organ's rigid frame while it breathes: most of the push moves the
// whole organ (3 mm of breathing carry it about 2.4 mm along model z), and
// a frame fixed to the rest shape would call that motion an error of every
// pose that follows the organ. The frame is the least-squares rigid fit of
// the displaced vertices to the rest ones (rigid_motion(): the field's mean
// and its best small rotation about the vertices' centroid, scaled by the
// phase); the ground truth is the camera in that frame, and what the field
// leaves beside it (bend()) is the deformation no rigid pose can follow.
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
  // The organ's rigid motion at a phase: the rest shape's frame moved by
  // the field's best rigid fit (identity without breathing or at phase 0).
  // A rest point p lies near rigid_motion(phase) * p on the breathing organ.
  SE3 rigid_motion(double phase) const;
  // What rigid_motion() leaves of the displacement at phase 1: the bend.
  Vec3 bend(const Vec3& p_rest) const;
  // rest's vertices displaced by phase * offset into out (same topology;
  // out must have rest's vertex count).
  void displace(const Mesh& rest, double phase, Mesh* out) const;

 private:
  Vec3 shape(const Vec3& p_rest) const;  // unscaled field
  void fit_rigid(const Mesh& rest);
  double amplitude_mm_ = 0.0;
  double scale_ = 0.0;  // amplitude / the largest |shape| over the rest vertices
  Vec3 centre_ = Vec3::Zero(), inv_half_ = Vec3::Ones();
  // The rigid fit at phase 1: translation of the centroid and rotation
  // vector (small: the field is a few mm over a ~150 mm organ).
  Vec3 centroid_ = Vec3::Zero(), fit_translation_ = Vec3::Zero(), fit_rotation_ = Vec3::Zero();
};

}  // namespace st::sim
