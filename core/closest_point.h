// D(f): the closest point on the organ mesh to a model-frame point, for the
// shape residual of bundle adjustment (paper Eq. 4). Exact: a bounding
// volume hierarchy over the triangles (median split, <= 4 triangles per
// leaf) searched nearest-box-first with the exact point-triangle distance
// (Voronoi regions of vertices, edges and face), so there is no sampling
// error as with the paper's k-d tree over a dense point cloud.
//
// The closest point also says which feature of the triangle it lies on
// (face, edge, vertex): the derivative of f - D(f) with respect to f is the
// projector onto that feature's normal space (n n^T on a face, I - e e^T on
// an edge, I at a vertex), which the shape residual uses as its Jacobian.
//
// Memory: the nodes and a copy of the triangles' vertices (float), ~110
// bytes per triangle; built once in configure() (allocates). closest()
// allocates nothing (a fixed traversal stack) and is const: any thread.
#pragma once

#include <cstdint>
#include <vector>

#include "core/mesh.h"
#include "core/result.h"
#include "core/se3.h"

namespace st {

enum class SurfaceFeature : std::uint8_t { kFace, kEdge, kVertex };

struct SurfacePoint {
  Vec3 p_model = Vec3::Zero();  // closest point on the mesh, mm
  double distance_mm = 0;
  int triangle = -1;            // mesh triangle index
  SurfaceFeature feature = SurfaceFeature::kFace;
  Vec3 axis = Vec3::UnitZ();    // face: unit normal (winding order); edge: unit edge direction
  Vec3 face_normal = Vec3::UnitZ();  // the triangle's unit normal (winding order), any feature
  // d(f - D(f)) / df: the projector onto the normal space of the feature.
  Mat3 residual_jacobian() const;
};

// Exact closest point of p on triangle (a, b, c), with the feature it lies on.
SurfacePoint closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);
// Its squared distance alone (the search kernel: no normals, no roots).
double triangle_distance2(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c);

class ClosestPointIndex {
 public:
  // Builds the hierarchy (allocates). The mesh needs >= 1 triangle with
  // finite vertices and valid indices.
  Status configure(const Mesh& mesh);
  // The closest surface point to p_model. False before configure() or for
  // a non-finite p_model. Allocates nothing.
  bool closest(const Vec3& p_model, SurfacePoint* out) const;

  int triangle_count() const { return static_cast<int>(tri_index_.size()); }
  int node_count() const { return static_cast<int>(nodes_.size()); }
  int depth() const { return depth_; }
  std::size_t memory_bytes() const;

 private:
  struct Node {
    float lo[3], hi[3];
    std::int32_t first;  // leaf: first triangle slot; inner: right child (left is this + 1)
    std::int32_t count;  // leaf: triangles (> 0); inner: 0
  };
  int build(int first, int count, int level, std::vector<float>* centroid);
  double box_distance2(const Node& n, const Vec3& p) const;
  Vec3 corner(int slot, int k) const;

  std::vector<Node> nodes_;
  std::vector<float> tri_xyz_;            // 9 floats per triangle slot (leaf order)
  std::vector<std::int32_t> tri_index_;   // mesh triangle of each slot
  int depth_ = 0;
};

}  // namespace st
