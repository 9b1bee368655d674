#include "core/closest_point.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

namespace st {

namespace {

constexpr int kLeafTriangles = 4;
constexpr int kMaxDepth = 60;  // median splits: depth <= log2(triangles) + 1

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
  if (!(n.squaredNorm() > 1e-24 * std::max(1.0, ab.squaredNorm() * ac.squaredNorm()))) {
    const double d = std::min({closest_on_segment(p, a, b).distance_mm, closest_on_segment(p, a, c).distance_mm,
                               closest_on_segment(p, b, c).distance_mm});
    return d * d;
  }
  return (p - region_point(triangle_region(p, a, b, c), a, b, c)).squaredNorm();
}

SurfacePoint closest_point_on_triangle(const Vec3& p, const Vec3& a, const Vec3& b, const Vec3& c) {
  const Vec3 ab = b - a, ac = c - a;
  const Vec3 n = ab.cross(ac);
  if (!(n.squaredNorm() > 1e-24 * std::max(1.0, ab.squaredNorm() * ac.squaredNorm()))) {
    SurfacePoint best = closest_on_segment(p, a, b);
    for (const SurfacePoint& s : {closest_on_segment(p, a, c), closest_on_segment(p, b, c)})
      if (s.distance_mm < best.distance_mm) best = s;
    return best;  // face_normal stays +z: a degenerate triangle has none
  }
  SurfacePoint s = closest_by_region(p, a, b, c, n.normalized());
  s.face_normal = n.normalized();
  return s;
}

Status ClosestPointIndex::configure(const Mesh& mesh) {
  nodes_.clear();
  tri_xyz_.clear();
  tri_index_.clear();
  depth_ = 0;
  const int nt = mesh.triangle_count(), nv = mesh.vertex_count();
  if (nt <= 0) return make_error("closest point: the mesh has no triangles");
  for (const std::int32_t v : mesh.tri)
    if (v < 0 || v >= nv) return make_error("closest point: triangle index " + std::to_string(v) + " outside the vertices");
  for (int v = 0; v < nv; ++v)
    if (!mesh.vertex(v).allFinite()) return make_error("closest point: vertex " + std::to_string(v) + " is not finite");
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
  nodes_.reserve(static_cast<std::size_t>(2 * (nt / kLeafTriangles + 1)));
  tri_xyz_.resize(static_cast<std::size_t>(nt) * 9);
  build(0, nt, 1, &centroid);
  if (depth_ > kMaxDepth) return make_error("closest point: hierarchy deeper than the traversal stack");
  for (int s = 0; s < nt; ++s) {
    const int t = tri_index_[static_cast<std::size_t>(s)];
    for (int j = 0; j < 3; ++j) {
      const int v = mesh.tri[static_cast<std::size_t>(3 * t + j)];
      float* dst = &tri_xyz_[static_cast<std::size_t>(9 * s + 3 * j)];
      dst[0] = mesh.x[static_cast<std::size_t>(v)];
      dst[1] = mesh.y[static_cast<std::size_t>(v)];
      dst[2] = mesh.z[static_cast<std::size_t>(v)];
    }
  }
  // Boxes from the vertices (children before parents: nodes are in pre-order, so walk backwards).
  for (int i = node_count() - 1; i >= 0; --i) {
    Node& n = nodes_[static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k) {
      n.lo[k] = std::numeric_limits<float>::max();
      n.hi[k] = std::numeric_limits<float>::lowest();
    }
    if (n.count > 0) {
      for (int s = n.first; s < n.first + n.count; ++s)
        for (int j = 0; j < 3; ++j)
          for (int k = 0; k < 3; ++k) {
            const float v = tri_xyz_[static_cast<std::size_t>(9 * s + 3 * j + k)];
            n.lo[k] = std::min(n.lo[k], v);
            n.hi[k] = std::max(n.hi[k], v);
          }
    } else {
      const Node& l = nodes_[static_cast<std::size_t>(i + 1)];
      const Node& r = nodes_[static_cast<std::size_t>(n.first)];
      for (int k = 0; k < 3; ++k) {
        n.lo[k] = std::min(l.lo[k], r.lo[k]);
        n.hi[k] = std::max(l.hi[k], r.hi[k]);
      }
    }
  }
  return Status::Ok();
}

// Pre-order build over slots [first, first + count): split at the median
// centroid of the widest centroid extent. Returns the node index.
int ClosestPointIndex::build(int first, int count, int level, std::vector<float>* centroid) {
  depth_ = std::max(depth_, level);
  const int id = node_count();
  nodes_.push_back(Node{});
  if (count <= kLeafTriangles) {
    nodes_[static_cast<std::size_t>(id)].first = first;
    nodes_[static_cast<std::size_t>(id)].count = count;
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
  nodes_[static_cast<std::size_t>(id)].first = right;
  nodes_[static_cast<std::size_t>(id)].count = 0;
  return id;
}

double ClosestPointIndex::box_distance2(const Node& n, const Vec3& p) const {
  double d2 = 0;
  for (int k = 0; k < 3; ++k) {
    const double lo = static_cast<double>(n.lo[k]), hi = static_cast<double>(n.hi[k]);
    const double d = p[k] < lo ? lo - p[k] : p[k] > hi ? p[k] - hi : 0.0;
    d2 += d * d;
  }
  return d2;
}

Vec3 ClosestPointIndex::corner(int slot, int k) const {
  const float* v = &tri_xyz_[static_cast<std::size_t>(9 * slot + 3 * k)];
  return {static_cast<double>(v[0]), static_cast<double>(v[1]), static_cast<double>(v[2])};
}

bool ClosestPointIndex::closest(const Vec3& p_model, SurfacePoint* out) const {
  if (nodes_.empty() || !p_model.allFinite()) return false;
  // Each entry keeps its box distance, computed once when pushed.
  struct Entry {
    std::int32_t node;
    double d2;
  };
  std::array<Entry, kMaxDepth + 2> stack{};
  int top = 0;
  stack[static_cast<std::size_t>(top++)] = Entry{0, box_distance2(nodes_[0], p_model)};
  double best2 = std::numeric_limits<double>::infinity();
  int best_slot = -1;
  while (top > 0) {
    const Entry e = stack[static_cast<std::size_t>(--top)];
    if (e.d2 >= best2) continue;
    const Node& n = nodes_[static_cast<std::size_t>(e.node)];
    if (n.count > 0) {
      for (int s = n.first; s < n.first + n.count; ++s) {
        const double d2 = triangle_distance2(p_model, corner(s, 0), corner(s, 1), corner(s, 2));
        if (d2 < best2) {
          best2 = d2;
          best_slot = s;
        }
      }
      continue;
    }
    // Push the farther child first so that the nearer one is searched next.
    const Entry l{e.node + 1, box_distance2(nodes_[static_cast<std::size_t>(e.node + 1)], p_model)};
    const Entry r{n.first, box_distance2(nodes_[static_cast<std::size_t>(n.first)], p_model)};
    stack[static_cast<std::size_t>(top++)] = l.d2 <= r.d2 ? r : l;
    stack[static_cast<std::size_t>(top++)] = l.d2 <= r.d2 ? l : r;
  }
  if (best_slot < 0) return false;
  // The full answer (feature, normals) for the winner only.
  *out = closest_point_on_triangle(p_model, corner(best_slot, 0), corner(best_slot, 1), corner(best_slot, 2));
  out->triangle = tri_index_[static_cast<std::size_t>(best_slot)];
  return std::isfinite(out->distance_mm);
}

std::size_t ClosestPointIndex::memory_bytes() const {
  return nodes_.capacity() * sizeof(Node) + tri_xyz_.capacity() * sizeof(float) +
         tri_index_.capacity() * sizeof(std::int32_t);
}

}  // namespace st
