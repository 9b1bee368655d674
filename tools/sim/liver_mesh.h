// Procedural liver-like organ: a closed, lobed, asymmetric surface of about
// 150 x 100 x 70 mm with ~20k triangles, outward counter-clockwise faces.
// Built as a subdivided icosahedron pushed out along each direction by a
// positive radial function, so it is star-shaped about the origin and can
// never self-intersect or flip a face.
#pragma once

#include <cstdint>
#include <functional>

#include "core/mesh/mesh.h"

namespace st::sim {

struct LiverShape {
  int subdivisions = 5;       // icosphere level: 5 -> 20,480 triangles
  double right_lobe_x_mm = 68;  // half-length towards -x (thick right lobe)
  double left_lobe_x_mm = 82;   // half-length towards +x (thin left lobe)
  double half_depth_mm = 50;    // y half-extent
  double dome_mm = 40;          // z half-extent above (diaphragmatic dome)
  double visceral_mm = 27;      // z half-extent below (flatter visceral face)
  double lobe_noise = 0.04;     // low-frequency radial irregularity (fraction)
  std::uint64_t seed = 1;
};

// The organ in its model frame (mm), centred on its bounding box.
Mesh make_liver_mesh(const LiverShape& shape = {});

// A unit icosphere subdivided `level` times (20 * 4^level triangles,
// outward counter-clockwise). Exposed for the background's organ shapes.
Mesh make_icosphere(int level);

// make_icosphere(level) with every vertex (a unit direction d) moved to
// surface(d), then centred on its bounding box: the organ shapes' common
// construction. surface must turn no face over.
Mesh map_icosphere(int level, const std::function<Vec3(const Vec3&)>& surface);

}  // namespace st::sim
