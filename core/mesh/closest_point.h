// D(f): the closest point on the organ mesh to a model-frame point, for the
// shape residual of bundle adjustment (paper Eq. 4). Exact: a bounding
// volume hierarchy over the triangles (median split, <= 4 triangles per
// leaf, collapsed to 4 children per node) searched nearest-box-first with
// the exact point-triangle distance (Voronoi regions of vertices, edges and
// face), so there is no sampling error as with the paper's k-d tree over a
// dense point cloud.
//
// Search cost: the 4 child boxes of a node are tested at once in float
// (OpenCV's 4-lane universal intrinsics; a plain loop where there is none);
// a box is skipped only when its float distance exceeds the best triangle
// distance by more than a slack that bounds the float rounding, so the
// float test never drops a box that could hold a closer triangle (the
// triangles themselves are compared in double). Half the node visits of
// the binary tree, ~30% fewer instructions and branch misses per query:
// ~20% less time per near-surface query (tools/bench `ba`, last row).
//
// The closest point also says which feature of the triangle it lies on
// (face, edge, vertex): the derivative of f - D(f) with respect to f is the
// projector onto that feature's normal space (n n^T on a face, I - e e^T on
// an edge, I at a vertex), which the shape residual uses as its Jacobian.
//
// Memory: the 4-wide nodes (128 bytes each, ~1 per 3 leaves) and a copy of
// the triangles' vertices in leaf order (float, as the mesh holds them: half
// the bytes of double, the same results), ~90 bytes per triangle;
// built once in configure() (allocates). closest() allocates nothing (a
// fixed traversal stack) and is const: any thread.
#pragma once

#include <cstdint>
#include <vector>

#include "core/mesh/mesh.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"

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
  // a non-finite p_model (or one beyond 1e15 mm). Allocates nothing.
  bool closest(const Vec3& p_model, SurfacePoint* out) const;

  int triangle_count() const { return static_cast<int>(tri_index_.size()); }
  int node_count() const { return static_cast<int>(nodes_.size()); }
  int depth() const { return depth_; }
  std::size_t memory_bytes() const;

 private:
  // Binary build tree (configure() only).
  struct BuildNode {
    float lo[3], hi[3];
    std::int32_t first;  // leaf: first triangle slot; inner: right child (left is this + 1)
    std::int32_t count;  // leaf: triangles (> 0); inner: 0
  };
  // Search node: the boxes of up to 4 children (lane-major: lo[axis][child])
  // and what they are. Child c: count[c] > 0 a leaf of count[c] triangle
  // slots from ref[c]; count[c] == 0 and ref[c] >= 0 an inner node; ref[c] < 0
  // an empty lane (its box is +inf: never entered).
  struct Node {
    float lo[3][4], hi[3][4];
    std::int32_t ref[4];
    std::int32_t count[4];
  };
  int build(int first, int count, int level, std::vector<float>* centroid);
  void build_boxes();
  void set_lane(Node* n, int c, int build_node) const;
  int collapse(int build_node, int level);
  void leaf_search(int first, int count, const Vec3& p, double* best2, int* best_slot) const;
  Vec3 corner(int slot, int k) const;

  std::vector<BuildNode> build_nodes_;    // configure() only (released after)
  std::vector<Node> nodes_;
  std::vector<float> tri_xyz_;            // 9 per triangle slot (leaf order): a, b, c; the mesh's
                                          // own floats (exact), widened to double where used
  std::vector<std::uint8_t> degenerate_;  // per slot: no usable normal (the search takes its edges)
  std::vector<std::int32_t> tri_index_;   // mesh triangle of each slot
  double extent_ = 0;                     // max |coordinate| of the mesh (float slack)
  int depth_ = 0;
};

}  // namespace st
