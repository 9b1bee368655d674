// Mesh utilities for the simulator: geometry checks, normals, and the
// "CT segmentation" prior for invivo (decimated + perturbed copy).
// Offline code (configure time): allocates freely.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/mesh/mesh.h"
#include "core/geometry/se3.h"

namespace st::sim {

// Volume enclosed by a closed mesh, mm^3; positive when faces are wound
// counter-clockwise seen from outside.
double signed_volume(const Mesh& mesh);
// Every directed edge appears once and its reverse once: closed, 2-manifold,
// consistently oriented.
bool is_closed_oriented(const Mesh& mesh);
// Area-weighted vertex normals (unit), model frame.
std::vector<Vec3f> vertex_normals(const Mesh& mesh);
struct Box {
  Vec3 min, max;
  Vec3 size() const { return max - min; }
  Vec3 centre() const { return 0.5 * (min + max); }
};
Box bounding_box(const Mesh& mesh);
// Moves all vertices by -centre of the bounding box.
void centre_on_box(Mesh& mesh);
// Appends b's vertices and triangles to a.
void append_mesh(Mesh& a, const Mesh& b);

// Shortest-edge collapse to at most target_triangles (or as near as the
// link condition and a no-fold check allow). Keeps a closed mesh closed and
// consistently oriented.
Mesh decimate(const Mesh& mesh, int target_triangles);
// Every triangle split into four at its edge midpoints, levels times: the
// same surface with 4^levels times the triangles (a segmentation exported
// at full density). Shared edges share their midpoint: a closed mesh stays
// closed, windings are kept.
Mesh subdivide(const Mesh& mesh, int levels);
// Displaces every vertex along its normal by a smooth random field in
// [-amplitude_mm, amplitude_mm] (wavelength ~20 mm): segmentation error.
void perturb_along_normals(Mesh& mesh, double amplitude_mm, std::uint64_t seed);

}  // namespace st::sim
