#include "core/mesh/closest_point.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include <opencv2/core/hal/intrin.hpp>

namespace st {

namespace {

constexpr int kLeafTriangles = 4;
constexpr int kMaxDepth = 60;  // median splits: depth <= log2(triangles) + 1
constexpr double kMaxQueryMm = 1e15;  // float box distances stay finite below this

SurfacePoint at_vertex(const Vec3& p, const Vec3& v) {
  SurfacePoint s;
  s.p_model = v;
  s.distance_mm = (p - v).norm();
  s.feature = SurfaceFeature::kVertex;
  return s;
}

SurfacePoint on_edge(const Vec3& p, const Vec3& a, const Vec3& b, double t) {
  SurfacePoint s;
  s.p_model = a + t * (b - a);
  s.distance_mm = (p - s.p_model).norm();
  s.feature = SurfaceFeature::kEdge;
  s.axis = (b - a).normalized();
  return s;
}

// A triangle with edges ab, ac and normal n = ab x ac has no usable normal
// (collinear or coincident corners, relative to its edge lengths): its
// closest point is on one of its edges.
bool degenerate(const Vec3& ab, const Vec3& ac, const Vec3& n) {
  return !(n.squaredNorm() > 1e-24 * std::max(1.0, ab.squaredNorm() * ac.squaredNorm()));
}

bool degenerate_triangle(const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a;
  return degenerate(ab, ac, ab.cross(ac));
}

// Closest point on segment ab (degenerate triangles only).
SurfacePoint closest_on_segment(const Vec3& p, const Vec3& a, const Vec3& b) {
  const Vec3 ab = b - a;
  const double len2 = ab.squaredNorm();
  if (!(len2 > 0)) return at_vertex(p, a);
  const double t = (p - a).dot(ab) / len2;
  if (t <= 0) return at_vertex(p, a);
  if (t >= 1) return at_vertex(p, b);
  return on_edge(p, a, b, t);
}

}  // namespace

Mat3 SurfacePoint::residual_jacobian() const {
  switch (feature) {
    case SurfaceFeature::kFace: return axis * axis.transpose();
    case SurfaceFeature::kEdge: return Mat3::Identity() - axis * axis.transpose();
    case SurfaceFeature::kVertex: break;
  }
  return Mat3::Identity();
}

namespace {

// Where the closest point of a non-degenerate triangle lies: vertex v0,
// edge (v0, v1) at parameter t, or the face at a + u ab + w ac.
struct TriangleRegion {
  SurfaceFeature feature = SurfaceFeature::kFace;
  int v0 = 0, v1 = 0;
  double t = 0, u = 0, w = 0;
};

// Voronoi regions in the order vertex a, b, edge ab, vertex c, edge ac,
// edge bc, face (barycentric tests as in Ericson, Real-Time Collision
// Detection, 5.1.5, re-derived here). Vertices 0, 1, 2 = a, b, c.
TriangleRegion triangle_region(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  TriangleRegion r;
  const Vec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  const auto vertex = [&r](int v) {
    r.feature = SurfaceFeature::kVertex;
    r.v0 = v;
    return r;
  };
  const auto edge = [&r](int v0, int v1, double t) {
    r.feature = SurfaceFeature::kEdge;
    r.v0 = v0;
    r.v1 = v1;
    r.t = t;
    return r;
  };
  if (d1 <= 0 && d2 <= 0) return vertex(0);
  const Vec3 bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return vertex(1);
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return edge(0, 1, d1 / (d1 - d3));
  const Vec3 cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return vertex(2);
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return edge(0, 2, d2 / (d2 - d6));
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return edge(1, 2, (d4 - d3) / ((d4 - d3) + (d5 - d6)));
  const double denom = 1.0 / (va + vb + vc);
  r.u = vb * denom;
  r.w = vc * denom;
  return r;
}

Vec3 region_point(const TriangleRegion& r, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3* v[3] = {&a, &b, &c};
  switch (r.feature) {
    case SurfaceFeature::kVertex: return *v[r.v0];
    case SurfaceFeature::kEdge: return *v[r.v0] + r.t * (*v[r.v1] - *v[r.v0]);
    case SurfaceFeature::kFace: break;
  }
  return a + (b - a) * r.u + (c - a) * r.w;
}

SurfacePoint closest_by_region(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c, const Vec3& n) {
  const TriangleRegion r = triangle_region(p, a, b, c);
  const Vec3* v[3] = {&a, &b, &c};
  switch (r.feature) {
    case SurfaceFeature::kVertex: return at_vertex(p, *v[r.v0]);
    case SurfaceFeature::kEdge: return on_edge(p, *v[r.v0], *v[r.v1], r.t);
    case SurfaceFeature::kFace: break;
  }
  SurfacePoint s;
  s.p_model = region_point(r, a, b, c);
  s.distance_mm = (p - s.p_model).norm();
  s.feature = SurfaceFeature::kFace;
  s.axis = n;
  return s;
}

}  // namespace

// Squared distance of p to triangle (a, b, c): the search kernel, without the
// feature, normals and square roots of closest_point_on_triangle (which
// the search then calls once, for the winner). Same Voronoi regions.
double triangle_distance2(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a;
  const Vec3 n = ab.cross(ac);
  if (degenerate(ab, ac, n)) {
    const double d = std::min({closest_on_segment(p, a, b).distance_mm, closest_on_segment(p, a, c).distance_mm,
                               closest_on_segment(p, b, c).distance_mm});
    return d * d;
  }
  return (p - region_point(triangle_region(p, a, b, c), a, b, c)).squaredNorm();
}

SurfacePoint closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a;
  const Vec3 n = ab.cross(ac);
  if (degenerate(ab, ac, n)) {
    SurfacePoint best = closest_on_segment(p, a, b);
    for (const SurfacePoint& s : {closest_on_segment(p, a, c), closest_on_segment(p, b, c)})
      if (s.distance_mm < best.distance_mm) best = s;
    return best;  // face_normal stays +z: a degenerate triangle has none
  }
  SurfacePoint s = closest_by_region(p, a, b, c, n.normalized());
  s.face_normal = n.normalized();
  return s;
}

namespace {

// Squared distances of p to the 4 lane boxes, in float (see closest()).
// Empty lanes have +inf boxes: +inf.
inline void lane_distances2(const float (&lo)[3][4], const float (&hi)[3][4], const float (&p)[3], float (&d2)[4]) {
#if CV_SIMD128
  const cv::v_float32x4 zero = cv::v_setzero_f32();
  cv::v_float32x4 acc = zero;
  for (int k = 0; k < 3; ++k) {
    const cv::v_float32x4 pk = cv::v_setall_f32(p[k]);
    const cv::v_float32x4 d = cv::v_max(cv::v_max(cv::v_load(lo[k]) - pk, pk - cv::v_load(hi[k])), zero);
    acc = acc + d * d;
  }
  cv::v_store(d2, acc);
#else
  for (int c = 0; c < 4; ++c) {
    d2[c] = 0.f;
    for (int k = 0; k < 3; ++k) {
      const float d = std::max(std::max(lo[k][c] - p[k], p[k] - hi[k][c]), 0.f);
      d2[c] += d * d;
    }
  }
#endif
}

}  // namespace

Status ClosestPointIndex::configure(const Mesh& mesh) {
  build_nodes_.clear();
  nodes_.clear();
  tri_xyz_.clear();
  degenerate_.clear();
  tri_index_.clear();
  depth_ = 0;
  extent_ = 0;
  const int nt = mesh.triangle_count(), nv = mesh.vertex_count();
  if (nt <= 0) return make_error("closest point: the mesh has no triangles");
  for (const std::int32_t v : mesh.tri)
    if (v < 0 || v >= nv) return make_error("closest point: triangle index " + std::to_string(v) + " outside the vertices");
  for (int v = 0; v < nv; ++v)
    if (!mesh.vertex(v).allFinite()) return make_error("closest point: vertex " + std::to_string(v) + " is not finite");
  for (int v = 0; v < nv; ++v) extent_ = std::max(extent_, mesh.vertex(v).cwiseAbs().maxCoeff());
  std::vector<float> centroid(static_cast<std::size_t>(nt) * 3);
  tri_index_.resize(static_cast<std::size_t>(nt));
  for (int t = 0; t < nt; ++t) {
    tri_index_[static_cast<std::size_t>(t)] = t;
    for (int k = 0; k < 3; ++k) {
      const auto* coord = k == 0 ? &mesh.x : k == 1 ? &mesh.y : &mesh.z;
      float sum = 0.f;
      for (int j = 0; j < 3; ++j) sum += (*coord)[static_cast<std::size_t>(mesh.tri[static_cast<std::size_t>(3 * t + j)])];
      centroid[static_cast<std::size_t>(3 * t + k)] = sum / 3.f;
    }
  }
  build_nodes_.reserve(static_cast<std::size_t>(2 * (nt / kLeafTriangles + 1)));
  build(0, nt, 1, &centroid);
  if (depth_ > kMaxDepth) return make_error("closest point: hierarchy deeper than the traversal stack");
  tri_xyz_.resize(static_cast<std::size_t>(nt) * 9);
  degenerate_.resize(static_cast<std::size_t>(nt));
  for (int s = 0; s < nt; ++s) {
    const int t = tri_index_[static_cast<std::size_t>(s)];
    for (int j = 0; j < 3; ++j) {
      const Vec3 v = mesh.vertex(mesh.tri[static_cast<std::size_t>(3 * t + j)]);
      for (int k = 0; k < 3; ++k) tri_xyz_[static_cast<std::size_t>(9 * s + 3 * j + k)] = static_cast<float>(v[k]);
    }
    degenerate_[static_cast<std::size_t>(s)] = degenerate_triangle(corner(s, 0), corner(s, 1), corner(s, 2)) ? 1 : 0;
  }
  build_boxes();
  nodes_.reserve(build_nodes_.size() / 2 + 1);
  depth_ = 0;
  if (build_nodes_[0].count > 0) {  // a single leaf: one node holding it in lane 0
    nodes_.push_back(Node{});
    set_lane(&nodes_[0], 0, 0);
    for (int c = 1; c < 4; ++c) set_lane(&nodes_[0], c, -1);
    depth_ = 1;
  } else {
    collapse(0, 1);
  }
  std::vector<BuildNode>().swap(build_nodes_);
  return Status::Ok();
}

// Boxes of the build tree from the vertices (float: the mesh's precision;
// children before parents: nodes are in pre-order, so walk backwards).
void ClosestPointIndex::build_boxes() {
  for (int i = static_cast<int>(build_nodes_.size()) - 1; i >= 0; --i) {
    BuildNode& n = build_nodes_[static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k) {
      n.lo[k] = std::numeric_limits<float>::max();
      n.hi[k] = std::numeric_limits<float>::lowest();
    }
    if (n.count > 0) {
      for (int s = n.first; s < n.first + n.count; ++s)
        for (int j = 0; j < 9; ++j) {
          const float v = tri_xyz_[static_cast<std::size_t>(9 * s + j)];
          n.lo[j % 3] = std::min(n.lo[j % 3], v);
          n.hi[j % 3] = std::max(n.hi[j % 3], v);
        }
    } else {
      const BuildNode& l = build_nodes_[static_cast<std::size_t>(i + 1)];
      const BuildNode& r = build_nodes_[static_cast<std::size_t>(n.first)];
      for (int k = 0; k < 3; ++k) {
        n.lo[k] = std::min(l.lo[k], r.lo[k]);
        n.hi[k] = std::max(l.hi[k], r.hi[k]);
      }
    }
  }
}

// Pre-order build over slots [first, first + count): split at the median
// centroid of the widest centroid extent. Returns the node index.
int ClosestPointIndex::build(int first, int count, int level, std::vector<float>* centroid) {
  depth_ = std::max(depth_, level);
  const int id = static_cast<int>(build_nodes_.size());
  build_nodes_.push_back(BuildNode{});
  if (count <= kLeafTriangles) {
    build_nodes_[static_cast<std::size_t>(id)].first = first;
    build_nodes_[static_cast<std::size_t>(id)].count = count;
    return id;
  }
  float lo[3] = {std::numeric_limits<float>::max(), std::numeric_limits<float>::max(), std::numeric_limits<float>::max()};
  float hi[3] = {std::numeric_limits<float>::lowest(), std::numeric_limits<float>::lowest(),
                 std::numeric_limits<float>::lowest()};
  const std::vector<float>& c = *centroid;
  for (int s = first; s < first + count; ++s)
    for (int k = 0; k < 3; ++k) {
      const float v = c[static_cast<std::size_t>(3 * tri_index_[static_cast<std::size_t>(s)] + k)];
      lo[k] = std::min(lo[k], v);
      hi[k] = std::max(hi[k], v);
    }
  int axis = 0;
  for (int k = 1; k < 3; ++k)
    if (hi[k] - lo[k] > hi[axis] - lo[axis]) axis = k;
  const int half = count / 2;
  const auto begin = tri_index_.begin() + first;
  std::nth_element(begin, begin + half, begin + count, [&c, axis](std::int32_t a, std::int32_t b) {
    return c[static_cast<std::size_t>(3 * a + axis)] < c[static_cast<std::size_t>(3 * b + axis)];
  });
  build(first, half, level + 1, centroid);
  const int right = build(first + half, count - half, level + 1, centroid);
  build_nodes_[static_cast<std::size_t>(id)].first = right;
  build_nodes_[static_cast<std::size_t>(id)].count = 0;
  return id;
}

// Lane c of node n takes build node b (a leaf or an inner node's box; the
// inner node's search index is filled in by collapse()), or is empty (b < 0).
void ClosestPointIndex::set_lane(Node* n, int c, int b) const {
  if (b < 0) {
    for (int k = 0; k < 3; ++k) n->lo[k][c] = n->hi[k][c] = std::numeric_limits<float>::infinity();
    n->ref[c] = -1;
    n->count[c] = 0;
    return;
  }
  const BuildNode& bn = build_nodes_[static_cast<std::size_t>(b)];
  for (int k = 0; k < 3; ++k) {
    n->lo[k][c] = bn.lo[k];
    n->hi[k][c] = bn.hi[k];
  }
  n->ref[c] = bn.count > 0 ? bn.first : -1;
  n->count[c] = bn.count;
}

// The search node for inner build node b: its children and grandchildren
// (an inner child is opened while there is a free lane, largest box first);
// inner lanes become search nodes in turn. Returns the search node index.
int ClosestPointIndex::collapse(int b, int level) {
  depth_ = std::max(depth_, level);
  int lanes[4] = {b + 1, build_nodes_[static_cast<std::size_t>(b)].first, -1, -1};
  int used = 2;
  while (used < 4) {
    int open = -1;
    float open_size = -1.f;
    for (int c = 0; c < used; ++c) {
      const BuildNode& n = build_nodes_[static_cast<std::size_t>(lanes[c])];
      const float size = (n.hi[0] - n.lo[0]) + (n.hi[1] - n.lo[1]) + (n.hi[2] - n.lo[2]);
      if (n.count == 0 && size > open_size) {
        open = c;
        open_size = size;
      }
    }
    if (open < 0) break;
    const int inner = lanes[open];
    lanes[open] = inner + 1;
    lanes[used++] = build_nodes_[static_cast<std::size_t>(inner)].first;
  }
  const int id = static_cast<int>(nodes_.size());
  nodes_.push_back(Node{});
  for (int c = 0; c < 4; ++c) set_lane(&nodes_[static_cast<std::size_t>(id)], c, c < used ? lanes[c] : -1);
  for (int c = 0; c < used; ++c) {
    if (build_nodes_[static_cast<std::size_t>(lanes[c])].count > 0) continue;
    const int child = collapse(lanes[c], level + 1);  // may reallocate nodes_: index again below
    nodes_[static_cast<std::size_t>(id)].ref[c] = child;
  }
  return id;
}

Vec3 ClosestPointIndex::corner(int slot, int k) const {
  const float* v = &tri_xyz_[static_cast<std::size_t>(9 * slot + 3 * k)];
  return {v[0], v[1], v[2]};
}

void ClosestPointIndex::leaf_search(int first, int count, const Vec3& p, double* best2, int* best_slot) const {
  for (int s = first; s < first + count; ++s) {
    const float* v = &tri_xyz_[static_cast<std::size_t>(9 * s)];
    const Vec3 a(v[0], v[1], v[2]), b(v[3], v[4], v[5]), c(v[6], v[7], v[8]);
    // Degeneracy is known from configure(): the region kernel directly.
    const double d2 = degenerate_[static_cast<std::size_t>(s)]
                          ? triangle_distance2(p, a, b, c)
                          : (p - region_point(triangle_region(p, a, b, c), a, b, c)).squaredNorm();
    if (d2 < *best2) {
      *best2 = d2;
      *best_slot = s;
    }
  }
}

// Nearest-box-first depth-first search. The 4 lane distances are float;
// a lane (or a stacked entry) is skipped only when its float distance is
// at least (best + slack)^2. Rounding p to float, the subtractions, squares
// and the sum move a box distance by at most ~7 * 2^-24 (|p| + extent)
// = 4.2e-7 (|p| + extent) < slack: the true box distance then exceeds the
// best triangle distance, so no closer triangle is dropped. The result
// equals the exhaustive minimum over all triangles (tests/test_closest_point.cpp).
bool ClosestPointIndex::closest(const Vec3& p_model, SurfacePoint* out) const {
  // Beyond 1e15 mm the float box distances would overflow (refused, as a
  // non-finite point is).
  if (nodes_.empty() || !p_model.allFinite() || !(p_model.cwiseAbs().maxCoeff() <= kMaxQueryMm)) return false;
  const float p[3] = {static_cast<float>(p_model.x()), static_cast<float>(p_model.y()), static_cast<float>(p_model.z())};
  const double slack = 1e-6 * (1.0 + extent_ + p_model.cwiseAbs().maxCoeff());
  struct Entry {
    std::int32_t ref;    // search node, or leaf first slot when count > 0
    std::int32_t count;  // leaf triangles; 0: search node
    float d2;
  };
  std::array<Entry, 3 * kMaxDepth + 4> stack;  // a pop pushes <= 4: depth * 3 + 1 entries at most
  int top = 0;
  stack[static_cast<std::size_t>(top++)] = Entry{0, 0, 0.f};
  double best2 = std::numeric_limits<double>::infinity(), bound2 = best2;
  int best_slot = -1;
  while (top > 0) {
    const Entry e = stack[static_cast<std::size_t>(--top)];
    if (static_cast<double>(e.d2) >= bound2) continue;
    if (e.count > 0) {
      leaf_search(e.ref, e.count, p_model, &best2, &best_slot);
      const double b = std::sqrt(best2) + slack;
      bound2 = b * b;
      continue;
    }
    const Node& n = nodes_[static_cast<std::size_t>(e.ref)];
    float d2[4];
    lane_distances2(n.lo, n.hi, p, d2);
    // The lanes within the bound, nearest last on the stack (popped first).
    int order[4];
    int m = 0;
    for (int c = 0; c < 4; ++c) {
      if (!(static_cast<double>(d2[c]) < bound2)) continue;
      int j = m++;
      for (; j > 0 && d2[order[j - 1]] < d2[c]; --j) order[j] = order[j - 1];
      order[j] = c;
    }
    for (int j = 0; j < m; ++j) {
      const int c = order[j];
      stack[static_cast<std::size_t>(top++)] = Entry{n.ref[c], n.count[c], d2[c]};
    }
  }
  if (best_slot < 0) return false;
  // The full answer (feature, normals) for the winner only.
  *out = closest_point_on_triangle(p_model, corner(best_slot, 0), corner(best_slot, 1), corner(best_slot, 2));
  out->triangle = tri_index_[static_cast<std::size_t>(best_slot)];
  return std::isfinite(out->distance_mm);
}

std::size_t ClosestPointIndex::memory_bytes() const {
  return nodes_.capacity() * sizeof(Node) + tri_xyz_.capacity() * sizeof(float) + degenerate_.capacity() +
         tri_index_.capacity() * sizeof(std::int32_t);
}

}  // namespace st
