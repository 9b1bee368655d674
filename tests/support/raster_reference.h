// Brute-force reference for the rasteriser tests: for every pixel centre,
// intersect its ray with every candidate triangle (nearest hit, inclusive
// edges, in double), plus the comparison the tests assert on, and
// adversarial meshes. Test-only; slow on purpose.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/geometry/camera.h"
#include "core/mesh/mesh.h"
#include "core/raster/rasterizer.h"
#include "core/geometry/se3.h"

namespace st::test {

struct ReferenceRender {
  int width = 0, height = 0;
  std::vector<double> depth;     // mm, 0 where nothing is hit
  std::vector<std::int32_t> id;  // -1 where nothing is hit
};

// K is the raster's pinhole (already scaled). Hits nearer than near_mm do
// not count (near-plane clipping); with cull_backfaces, faces whose outward
// side is away from the eye are ignored.
ReferenceRender reference_render(const Mesh& mesh, const SE3& T_camera_model, const Pinhole& K,
                                 double near_mm, bool cull_backfaces);

struct RasterComparison {
  long pixels = 0;
  long covered_reference = 0;
  long agree = 0;                  // same triangle id (or both empty)
  long depth_ties = 0;             // different ids, both surfaces within 1e-4 relative depth
  long on_boundary = 0;            // different ids, pixel centre within 1e-3 px of an edge involved
  long unexplained = 0;            // any other disagreement
  long cracks = 0;                 // reference covers the pixel and its 8 neighbours, we do not
  double max_rel_depth_error = 0;  // over pixels where both hit (not on a boundary)
  std::string summary() const;
  double agreement() const { return pixels ? double(agree) / double(pixels) : 1.0; }
};

RasterComparison compare_with_reference(const MeshRasterizer& r, const Mesh& mesh,
                                        const ReferenceRender& ref);

// Adversarial meshes, given directly in the camera frame (render them with
// T_camera_model = identity); every face is oriented towards the eye.
Mesh fan_mesh(const Pinhole& K, bool pixel_aligned);  // fans sharing edges
Mesh sliver_mesh(const Pinhole& K);                   // long thin triangles
Mesh near_plane_mesh();   // a floor and walls through z = near and z = 0
Mesh far_outside_mesh();  // huge and far-off triangles
// A closed UV sphere (outward faces).
Mesh sphere_mesh(const Vec3& centre, double radius, int rings, int segments);
// Triangles of m flipped so that each faces the eye at the origin.
void orient_towards_origin(Mesh* m);

}  // namespace st::test
