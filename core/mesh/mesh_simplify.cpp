#include "core/mesh/mesh_simplify.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include <Eigen/Eigenvalues>

namespace st {
namespace {

// Cells per axis stay below 2^20, so a cell's three indices and a normal
// class (3 bits) pack into one 63-bit key.
constexpr double kMaxCellsPerAxis = double(1 << 20) - 2.0;

constexpr std::uint8_t kUnused = 0xFF;  // a vertex no triangle refers to

// Per vertex, which of the six axis directions its area-weighted normal is
// nearest to (kUnused for a vertex no triangle uses). The two sides of a
// part thinner than a cell face away from each other, and their vertices
// must not merge into one point in between: a cell's vertices are
// clustered by this class too. It does not depend on the cell size, so it
// is computed once for all passes.
std::vector<std::uint8_t> normal_classes(const Mesh& m) {
  const auto nv = static_cast<std::size_t>(m.vertex_count());
  std::vector<Vec3> normal(nv, Vec3::Zero());
  std::vector<std::uint8_t> used(nv, 0);
  for (int t = 0; t < m.triangle_count(); ++t) {
    const Vec3 p0 = m.vertex(m.tri[3 * t]), p1 = m.vertex(m.tri[3 * t + 1]), p2 = m.vertex(m.tri[3 * t + 2]);
    const Vec3 n2 = (p1 - p0).cross(p2 - p0);
    for (int k = 0; k < 3; ++k) {
      normal[static_cast<std::size_t>(m.tri[3 * t + k])] += n2;
      used[static_cast<std::size_t>(m.tri[3 * t + k])] = 1;
    }
  }
  std::vector<std::uint8_t> cls(nv, kUnused);
  for (std::size_t v = 0; v < nv; ++v) {
    if (!used[v]) continue;
    int axis = 0;
    normal[v].cwiseAbs().maxCoeff(&axis);
    cls[v] = static_cast<std::uint8_t>(2 * axis + (normal[v][axis] < 0 ? 1 : 0));
  }
  return cls;
}

struct Bounds {
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity());
  Vec3 hi = -Vec3::Constant(std::numeric_limits<double>::infinity());
};

bool all_finite(const Mesh& m) {
  for (int i = 0; i < m.vertex_count(); ++i)
    if (!std::isfinite(m.x[i]) || !std::isfinite(m.y[i]) || !std::isfinite(m.z[i])) return false;
  return true;
}

bool indices_valid(const Mesh& m) {
  const int n = m.vertex_count();
  return std::all_of(m.tri.begin(), m.tri.end(), [n](std::int32_t v) { return v >= 0 && v < n; });
}

Bounds used_bounds(const Mesh& m) {
  Bounds b;
  for (const std::int32_t v : m.tri) {
    const Vec3 p = m.vertex(v);
    b.lo = b.lo.cwiseMin(p);
    b.hi = b.hi.cwiseMax(p);
  }
  return b;
}

double surface_area(const Mesh& m) {
  double a = 0;
  for (int t = 0; t < m.triangle_count(); ++t) {
    const Vec3 p0 = m.vertex(m.tri[3 * t]), p1 = m.vertex(m.tri[3 * t + 1]), p2 = m.vertex(m.tri[3 * t + 2]);
    a += 0.5 * (p1 - p0).cross(p2 - p0).norm();
  }
  return a;
}

Mesh cluster(const Mesh& m, const std::vector<std::uint8_t>& normal_class, const Bounds& b, double cell) {
  const int nv = m.vertex_count();
  std::vector<std::pair<std::uint64_t, std::int32_t>> keyed;
  keyed.reserve(static_cast<std::size_t>(nv));
  for (int v = 0; v < nv; ++v) {
    const std::uint8_t cls = normal_class[static_cast<std::size_t>(v)];
    if (cls == kUnused) continue;
    const Vec3 q = (m.vertex(v) - b.lo) / cell;
    const auto ix = static_cast<std::uint64_t>(std::floor(q.x()));
    const auto iy = static_cast<std::uint64_t>(std::floor(q.y()));
    const auto iz = static_cast<std::uint64_t>(std::floor(q.z()));
    keyed.emplace_back((ix << 43) | (iy << 23) | (iz << 3) | cls, v);
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<std::int32_t> cluster_of(static_cast<std::size_t>(nv), -1);
  std::vector<Vec3> sum;
  std::vector<int> count;
  for (std::size_t i = 0; i < keyed.size(); ++i) {
    if (i == 0 || keyed[i].first != keyed[i - 1].first) {
      sum.push_back(Vec3::Zero());
      count.push_back(0);
    }
    const std::int32_t v = keyed[i].second;
    cluster_of[static_cast<std::size_t>(v)] = static_cast<std::int32_t>(sum.size() - 1);
    sum.back() += m.vertex(v);
    ++count.back();
  }
  // Each cluster's point: the one nearest, in the least-squares sense, to
  // the planes of the triangles around its vertices (area-weighted plane
  // quadrics, Garland and Heckbert; Lindstrom uses them with clustering).
  // It stays on a flat patch, on a crease where two patches meet, at a
  // corner where three do; where the planes leave a direction free (flat:
  // two), the mean of the vertices fills it in. The mean alone sinks into a
  // convex surface, and where a cell spans a thin part, towards its middle.
  std::vector<Mat3> A(sum.size(), Mat3::Zero());
  std::vector<Vec3> B(sum.size(), Vec3::Zero());
  for (int t = 0; t < m.triangle_count(); ++t) {
    const Vec3 p0 = m.vertex(m.tri[3 * t]), p1 = m.vertex(m.tri[3 * t + 1]), p2 = m.vertex(m.tri[3 * t + 2]);
    const Vec3 n2 = (p1 - p0).cross(p2 - p0);  // twice the area times the unit normal
    const double len = n2.norm();
    if (!(len > 0)) continue;
    const Vec3 n = n2 / len;
    const Mat3 Q = 0.5 * len * n * n.transpose();
    const Vec3 q = 0.5 * len * n * n.dot(p0);
    for (int k = 0; k < 3; ++k) {
      const auto c = static_cast<std::size_t>(cluster_of[static_cast<std::size_t>(m.tri[3 * t + k])]);
      A[c] += Q;
      B[c] += q;
    }
  }
  std::vector<Vec3> point(sum.size());
  for (std::size_t c = 0; c < sum.size(); ++c) {
    const Vec3 mean = sum[c] / static_cast<double>(count[c]);
    point[c] = mean;
    const Eigen::SelfAdjointEigenSolver<Mat3> eig(A[c]);
    const double top = eig.eigenvalues().maxCoeff();
    if (!(top > 0)) continue;
    const Vec3 r = B[c] - A[c] * mean;
    Vec3 x = mean;
    for (int i = 0; i < 3; ++i) {
      const double l = eig.eigenvalues()[i];
      if (l > 1e-3 * top) x += eig.eigenvectors().col(i) * (eig.eigenvectors().col(i).dot(r) / l);
    }
    // A point outside the cell (nearly parallel planes meeting far away):
    // the mean is safer.
    const Vec3 lo = b.lo + cell * ((mean - b.lo) / cell).array().floor().matrix();
    if (((x - lo).array() >= -0.25 * cell).all() && ((x - lo).array() <= 1.25 * cell).all()) point[c] = x;
  }
  // Surviving triangles, each rotated so that its smallest index comes
  // first (winding kept): the same triangle then has one spelling.
  std::vector<std::array<std::int32_t, 3>> tris;
  tris.reserve(static_cast<std::size_t>(m.triangle_count()));
  for (int t = 0; t < m.triangle_count(); ++t) {
    std::array<std::int32_t, 3> c{};
    for (int k = 0; k < 3; ++k) c[static_cast<std::size_t>(k)] = cluster_of[static_cast<std::size_t>(m.tri[3 * t + k])];
    if (c[0] == c[1] || c[1] == c[2] || c[0] == c[2]) continue;
    const auto first = std::min_element(c.begin(), c.end());
    std::rotate(c.begin(), first, c.end());
    tris.push_back(c);
  }
  std::sort(tris.begin(), tris.end());
  tris.erase(std::unique(tris.begin(), tris.end()), tris.end());
  // Only clusters some triangle still uses become vertices.
  std::vector<std::int32_t> out_index(sum.size(), -1);
  Mesh out;
  for (const auto& t : tris) {
    std::array<std::int32_t, 3> o{};
    for (int k = 0; k < 3; ++k) {
      std::int32_t& idx = out_index[static_cast<std::size_t>(t[static_cast<std::size_t>(k)])];
      if (idx < 0) {
        const Vec3& p = point[static_cast<std::size_t>(t[static_cast<std::size_t>(k)])];
        idx = out.vertex_count();
        out.add_vertex(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
      }
      o[static_cast<std::size_t>(k)] = idx;
    }
    out.add_triangle(o[0], o[1], o[2]);
  }
  return out;
}

Status check_mesh(const Mesh& mesh) {
  if (mesh.triangle_count() <= 0) return make_error("mesh simplification: the mesh has no triangles");
  if (mesh.tri.size() % 3 != 0 || mesh.y.size() != mesh.x.size() || mesh.z.size() != mesh.x.size() ||
      !indices_valid(mesh))
    return make_error("mesh simplification: malformed mesh (index out of range or ragged arrays)");
  if (!all_finite(mesh)) return make_error("mesh simplification: a vertex is not finite");
  return Status::Ok();
}

}  // namespace

Result<Mesh> cluster_vertices(const Mesh& mesh, double cell_mm) {
  if (Status s = check_mesh(mesh); !s.ok()) return make_error(s.message());
  if (!(cell_mm > 0) || !std::isfinite(cell_mm))
    return make_error("mesh simplification: cell size must be positive and finite");
  const Bounds b = used_bounds(mesh);
  const double extent = (b.hi - b.lo).maxCoeff();
  if (extent / cell_mm > kMaxCellsPerAxis)
    return make_error("mesh simplification: cell size " + std::to_string(cell_mm) + " mm is too small for a mesh " +
                      std::to_string(extent) + " mm across");
  return cluster(mesh, normal_classes(mesh), b, cell_mm);
}

Result<Mesh> simplify_to_budget(const Mesh& mesh, int max_triangles, SimplifyReport* report) {
  if (Status s = check_mesh(mesh); !s.ok()) return make_error(s.message());
  if (max_triangles < 16) return make_error("mesh simplification: a budget below 16 triangles cannot hold an organ");
  SimplifyReport r;
  r.input_triangles = mesh.triangle_count();
  if (mesh.triangle_count() <= max_triangles) {
    r.output_triangles = mesh.triangle_count();
    r.output_vertices = mesh.vertex_count();
    if (report) *report = r;
    return mesh;
  }
  const Bounds b = used_bounds(mesh);
  const double extent = std::max((b.hi - b.lo).maxCoeff(), 1e-6);
  // A cubic cell crossed by a surface holds about 1.5 c^2 of it, and every
  // cluster carries about two triangles: start a little below the cell
  // that the area predicts and grow.
  const double area = surface_area(mesh);
  double cell = std::max(0.7 * std::sqrt(area / (0.5 * max_triangles)), extent / kMaxCellsPerAxis);
  if (!(cell > 0) || !std::isfinite(cell)) cell = extent / 64.0;
  const std::vector<std::uint8_t> classes = normal_classes(mesh);
  for (r.passes = 1; r.passes <= 200; ++r.passes, cell *= 1.15) {
    Mesh out = cluster(mesh, classes, b, cell);
    if (out.triangle_count() <= max_triangles) {
      if (out.triangle_count() == 0)
        return make_error("mesh simplification: nothing of the mesh is left at the budget of " +
                          std::to_string(max_triangles) + " triangles");
      r.output_triangles = out.triangle_count();
      r.output_vertices = out.vertex_count();
      r.cell_mm = cell;
      if (report) *report = r;
      return out;
    }
  }
  return make_error("mesh simplification: could not meet the budget of " + std::to_string(max_triangles) +
                    " triangles");
}

}  // namespace st
