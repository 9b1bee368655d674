// The simulated abdomen: the organ (model frame), the background (world
// frame: fat-covered floor rising into the abdominal wall, a gallbladder-like
// and a stomach-like neighbour) and the instrument (its own frame: tip at the
// origin, shaft along +z). Built once; offline code, allocates.
#pragma once

#include <cstdint>
#include <vector>

#include "core/mesh/mesh.h"
#include "core/geometry/se3.h"
#include "tools/sim/materials.h"
#include "tools/sim/mesh_ops.h"

namespace st::sim {

struct Scene {
  Mesh organ;             // the rendered (exact) organ, model frame, mm
  SE3 T_world_model_rest; // organ placement at rest: box centre at the origin
  Box organ_box_world;    // organ bounding box at rest, world frame
  Mesh background;        // world frame
  std::vector<MaterialId> background_material;  // per background triangle
  Mesh instrument;        // instrument frame
  double instrument_radius_mm = 2.75;
  double floor_z_mm = 0;  // floor height under the organ (world z is up)
};

// organ: any closed mesh in its own frame (mm). The world frame has z up
// (towards the scope) and the organ's box centre at the origin.
Scene make_scene(Mesh organ, std::uint64_t seed);

Mesh make_instrument_mesh(double radius_mm, double length_mm, int segments);
// Heightfield floor + bowl wall around the organ, with per-triangle materials.
Mesh make_floor(const Box& organ_box_world, double floor_z_mm, std::uint64_t seed,
                std::vector<MaterialId>* material);
// An ellipsoid (icosphere level 3) with radii r, centred at c, rotated by yaw.
Mesh make_blob(const Vec3& c, const Vec3& r, double yaw_rad, std::uint64_t seed);

}  // namespace st::sim
