// Shortest-edge collapse (mesh_ops.h). Greedy passes: in each pass the
// shortest edges whose end points are not yet touched in this pass collapse
// to their midpoint, if the link condition holds (the two end points share
// exactly the two opposite vertices: no pinched, non-manifold result) and no
// surrounding face turns over.
#include <algorithm>
#include <numeric>

#include "tools/sim/mesh_ops.h"

namespace st::sim {
namespace {

struct Work {
  std::vector<Vec3> p;
  std::vector<std::array<std::int32_t, 3>> tri;
  std::vector<char> alive;
  std::vector<std::vector<std::int32_t>> faces_of;  // vertex -> triangles (may hold dead ones)
  int live = 0;
};

std::vector<std::int32_t> neighbours(const Work& w, std::int32_t v) {
  std::vector<std::int32_t> n;
  for (const std::int32_t t : w.faces_of[v]) {
    if (!w.alive[t]) continue;
    for (const std::int32_t u : w.tri[t])
      if (u != v) n.push_back(u);
  }
  std::sort(n.begin(), n.end());
  n.erase(std::unique(n.begin(), n.end()), n.end());
  return n;
}

Vec3 face_normal(const Work& w, const std::array<std::int32_t, 3>& f, std::int32_t moved,
                 const Vec3& to) {
  auto P = [&](std::int32_t v) { return v == moved ? to : w.p[v]; };
  return (P(f[1]) - P(f[0])).cross(P(f[2]) - P(f[0]));
}

// Faces around a or b (not both) keep their orientation when a, b -> m.
bool no_fold(const Work& w, std::int32_t a, std::int32_t b, const Vec3& m) {
  for (const std::int32_t v : {a, b}) {
    for (const std::int32_t t : w.faces_of[v]) {
      if (!w.alive[t]) continue;
      const auto& f = w.tri[t];
      if (std::count(f.begin(), f.end(), a) + std::count(f.begin(), f.end(), b) == 2) continue;
      const Vec3 before = face_normal(w, f, v, w.p[v]);
      const Vec3 after = face_normal(w, f, v, m);
      if (after.norm() < 1e-12 || before.normalized().dot(after.normalized()) < 0.3) return false;
    }
  }
  return true;
}

bool try_collapse(Work& w, std::int32_t a, std::int32_t b, std::vector<char>& touched) {
  const auto na = neighbours(w, a), nb = neighbours(w, b);
  if (na.size() <= 3 || nb.size() <= 3) return false;
  std::vector<std::int32_t> common;
  std::set_intersection(na.begin(), na.end(), nb.begin(), nb.end(), std::back_inserter(common));
  if (common.size() != 2) return false;
  const Vec3 m = 0.5 * (w.p[a] + w.p[b]);
  if (!no_fold(w, a, b, m)) return false;
  for (const std::int32_t t : w.faces_of[b]) {
    if (!w.alive[t]) continue;
    auto& f = w.tri[t];
    if (std::find(f.begin(), f.end(), a) != f.end()) {
      w.alive[t] = 0;
      --w.live;
      continue;
    }
    std::replace(f.begin(), f.end(), b, a);
    w.faces_of[a].push_back(t);
  }
  w.p[a] = m;
  w.faces_of[b].clear();
  touched[a] = touched[b] = 1;
  for (const std::int32_t u : na) touched[u] = 1;
  for (const std::int32_t u : nb) touched[u] = 1;
  return true;
}

Mesh compact(const Work& w) {
  Mesh out;
  std::vector<std::int32_t> remap(w.p.size(), -1);
  for (std::size_t t = 0; t < w.tri.size(); ++t) {
    if (!w.alive[t]) continue;
    std::array<std::int32_t, 3> f{};
    for (int k = 0; k < 3; ++k) {
      std::int32_t& r = remap[w.tri[t][k]];
      if (r < 0) {
        const Vec3& p = w.p[w.tri[t][k]];
        out.add_vertex(static_cast<float>(p.x()), static_cast<float>(p.y()), static_cast<float>(p.z()));
        r = out.vertex_count() - 1;
      }
      f[k] = r;
    }
    out.add_triangle(f[0], f[1], f[2]);
  }
  return out;
}

}  // namespace

Mesh decimate(const Mesh& mesh, int target_triangles) {
  Work w;
  for (int i = 0; i < mesh.vertex_count(); ++i) w.p.push_back(mesh.vertex(i));
  w.faces_of.resize(w.p.size());
  for (int t = 0; t < mesh.triangle_count(); ++t) {
    w.tri.push_back({mesh.tri[3 * t], mesh.tri[3 * t + 1], mesh.tri[3 * t + 2]});
    for (int k = 0; k < 3; ++k) w.faces_of[mesh.tri[3 * t + k]].push_back(t);
  }
  w.alive.assign(w.tri.size(), 1);
  w.live = mesh.triangle_count();
  for (int pass = 0; pass < 50 && w.live > target_triangles; ++pass) {
    std::vector<std::pair<double, std::pair<std::int32_t, std::int32_t>>> edges;
    for (std::size_t t = 0; t < w.tri.size(); ++t) {
      if (!w.alive[t]) continue;
      for (int k = 0; k < 3; ++k) {
        const std::int32_t a = w.tri[t][k], b = w.tri[t][(k + 1) % 3];
        if (a < b) edges.push_back({(w.p[a] - w.p[b]).squaredNorm(), {a, b}});
      }
    }
    std::sort(edges.begin(), edges.end());
    std::vector<char> touched(w.p.size(), 0);
    int collapsed = 0;
    for (const auto& [len2, e] : edges) {
      if (w.live <= target_triangles) break;
      if (touched[e.first] || touched[e.second]) continue;
      if (try_collapse(w, e.first, e.second, touched)) ++collapsed;
    }
    if (collapsed == 0) break;
  }
  return compact(w);
}

}  // namespace st::sim
