#include "core/formats/mesh_io.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <vector>

#include "core/base/capacity.h"

namespace st {

Result<Mesh> parse_mesh(std::string_view bytes) {
  if (bytes.substr(0, 3) == "ply") return parse_ply(bytes);
  if (bytes.size() >= 84 || bytes.find("solid") != std::string_view::npos) return parse_stl(bytes);
  return make_error("mesh is neither PLY (starts with 'ply') nor STL (binary, or ascii 'solid')");
}

namespace {

Status check_structure(const Mesh& m) {
  if (m.x.size() != m.y.size() || m.x.size() != m.z.size() || m.tri.size() % 3 != 0)
    return make_error("mesh arrays are inconsistent (x/y/z sizes differ or indices not in triples)");
  if (m.vertex_count() == 0 || m.triangle_count() == 0)
    return make_error("mesh is empty (" + std::to_string(m.vertex_count()) + " vertices, " +
                      std::to_string(m.triangle_count()) + " triangles)");
  if (m.vertex_count() > kMaxMeshVertices || m.triangle_count() > kMaxMeshTriangles)
    return make_error("mesh has " + std::to_string(m.vertex_count()) + " vertices and " +
                      std::to_string(m.triangle_count()) + " triangles, above the supported " +
                      std::to_string(kMaxMeshVertices) + " / " + std::to_string(kMaxMeshTriangles));
  for (std::size_t i = 0; i < m.tri.size(); ++i)
    if (m.tri[i] < 0 || m.tri[i] >= m.vertex_count())
      return make_error("triangle " + std::to_string(i / 3) + " refers to vertex " +
                        std::to_string(m.tri[i]) + ", outside 0.." +
                        std::to_string(m.vertex_count() - 1));
  for (int i = 0; i < m.vertex_count(); ++i)
    if (!m.vertex(i).allFinite())
      return make_error("vertex " + std::to_string(i) + " has a non-finite coordinate");
  return Status::Ok();
}

// Signed volume by the divergence theorem, about the box centre to keep
// the sum well conditioned for meshes far from the origin (CT frames).
double signed_volume(const Mesh& m, const Vec3& centre) {
  double six_v = 0.0;
  for (int t = 0; t < m.triangle_count(); ++t) {
    const Vec3 a = m.vertex(m.tri[3 * t]) - centre, b = m.vertex(m.tri[3 * t + 1]) - centre,
               c = m.vertex(m.tri[3 * t + 2]) - centre;
    six_v += a.dot(b.cross(c));
  }
  return six_v / 6.0;
}

// Makes neighbouring faces agree: across an edge shared by exactly two
// faces, a consistently wound surface runs the edge once in each direction.
// Faces are visited breadth-first from a seed in every connected component
// (through such edges), each given the orientation its neighbour implies;
// then, per component, the smaller group is the one flipped (the seed's
// choice is arbitrary, the majority is what the exporter meant). Edges of
// three or more faces (non-manifold) link nothing. Returns the faces
// flipped. A non-orientable component (a Moebius band) keeps the
// orientation its first visit gave each face.
int orient_consistently(Mesh& m) {
  const int nt = m.triangle_count();
  // One record per directed edge: the undirected edge's key, then the face
  // and whether it runs from the smaller to the larger vertex.
  struct EdgeUse {
    std::uint64_t key;
    std::int32_t face;
    bool forward;
    bool operator<(const EdgeUse& o) const { return key < o.key || (key == o.key && face < o.face); }
  };
  std::vector<EdgeUse> uses;
  uses.reserve(static_cast<std::size_t>(nt) * 3);
  for (int t = 0; t < nt; ++t)
    for (int k = 0; k < 3; ++k) {
      const std::int32_t a = m.tri[3 * t + k], b = m.tri[3 * t + (k + 1) % 3];
      const auto lo = static_cast<std::uint64_t>(std::min(a, b)), hi = static_cast<std::uint64_t>(std::max(a, b));
      uses.push_back({(lo << 32) | hi, t, a < b});
    }
  std::sort(uses.begin(), uses.end());
  // Manifold neighbours (up to 3 per face) and whether each pair runs its
  // shared edge the same way (then one of the two must flip).
  std::vector<std::int32_t> nb(static_cast<std::size_t>(nt) * 3, -1);
  std::vector<char> same(static_cast<std::size_t>(nt) * 3, 0);
  const auto link = [&](std::int32_t f, std::int32_t g, bool same_way) {
    for (int k = 0; k < 3; ++k) {
      const std::size_t i = static_cast<std::size_t>(f) * 3 + static_cast<std::size_t>(k);
      if (nb[i] < 0) {
        nb[i] = g;
        same[i] = same_way ? 1 : 0;
        return;
      }
    }
  };
  for (std::size_t i = 0; i < uses.size();) {
    std::size_t j = i + 1;
    while (j < uses.size() && uses[j].key == uses[i].key) ++j;
    if (j - i == 2 && uses[i].face != uses[i + 1].face) {
      const bool same_way = uses[i].forward == uses[i + 1].forward;
      link(uses[i].face, uses[i + 1].face, same_way);
      link(uses[i + 1].face, uses[i].face, same_way);
    }
    i = j;
  }
  std::vector<EdgeUse>().swap(uses);  // the largest buffer: released before the walk
  std::vector<signed char> flip(static_cast<std::size_t>(nt), -1);  // -1 unvisited, 0 keep, 1 flip
  std::vector<std::int32_t> queue;
  int flipped_total = 0;
  for (int seed = 0; seed < nt; ++seed) {
    if (flip[static_cast<std::size_t>(seed)] >= 0) continue;
    queue.clear();
    queue.push_back(seed);
    flip[static_cast<std::size_t>(seed)] = 0;
    int flipped = 0;
    for (std::size_t q = 0; q < queue.size(); ++q) {
      const std::int32_t f = queue[q];
      for (int k = 0; k < 3; ++k) {
        const std::size_t i = static_cast<std::size_t>(f) * 3 + static_cast<std::size_t>(k);
        const std::int32_t g = nb[i];
        if (g < 0 || flip[static_cast<std::size_t>(g)] >= 0) continue;
        flip[static_cast<std::size_t>(g)] = static_cast<signed char>(flip[static_cast<std::size_t>(f)] ^ same[i]);
        flipped += flip[static_cast<std::size_t>(g)];
        queue.push_back(g);
      }
    }
    const bool invert = 2 * flipped > static_cast<int>(queue.size());
    for (const std::int32_t f : queue) {
      const bool do_flip = (flip[static_cast<std::size_t>(f)] != 0) != invert;
      if (do_flip) {
        std::swap(m.tri[3 * static_cast<std::size_t>(f) + 1], m.tri[3 * static_cast<std::size_t>(f) + 2]);
        ++flipped_total;
      }
    }
  }
  return flipped_total;
}

std::string summarise(const MeshReport& r, bool winding_known) {
  const Vec3 e = r.max - r.min;
  char buf[256];
  std::snprintf(buf, sizeof buf, "%d triangles, %d vertices, extent %.1f x %.1f x %.1f mm, volume %.1f cm^3",
                r.triangles, r.vertices, e.x(), e.y(), e.z(), r.signed_volume_mm3 / 1000.0);
  std::string s = buf;
  if (r.reoriented > 0)
    s += ", " + std::to_string(r.reoriented) + " faces wound against their neighbours: turned to agree";
  if (!winding_known) return s + ", winding unknown (open or flat surface: signed volume ~ 0)";
  return s + (r.flipped ? ", faces were wound inward (negative signed volume): flipped to outward"
                        : ", outward winding");
}

}  // namespace

Status validate_and_orient(Mesh& mesh, MeshReport* report) {
  if (Status s = check_structure(mesh); !s) return s;
  MeshReport r;
  r.vertices = mesh.vertex_count();
  r.triangles = mesh.triangle_count();
  r.min = r.max = mesh.vertex(0);
  for (int i = 1; i < r.vertices; ++i) {
    r.min = r.min.cwiseMin(mesh.vertex(i));
    r.max = r.max.cwiseMax(mesh.vertex(i));
  }
  r.reoriented = orient_consistently(mesh);
  const Vec3 extent = r.max - r.min;
  const double box_volume = extent.x() * extent.y() * extent.z();
  double volume = signed_volume(mesh, 0.5 * (r.min + r.max));
  const bool winding_known = std::abs(volume) > 1e-6 * box_volume && box_volume > 0.0;
  if (winding_known && volume < 0.0) {
    for (int t = 0; t < r.triangles; ++t) std::swap(mesh.tri[3 * t + 1], mesh.tri[3 * t + 2]);
    volume = -volume;
    r.flipped = true;
  }
  r.signed_volume_mm3 = volume;
  r.summary = summarise(r, winding_known);
  if (report) *report = std::move(r);
  return Status::Ok();
}

namespace {
void put_u32_le(std::string& out, std::uint32_t v) {
  for (int k = 0; k < 4; ++k) out.push_back(static_cast<char>((v >> (8 * k)) & 0xffu));
}
void put_f32_le(std::string& out, float f) {
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  put_u32_le(out, u);
}
}  // namespace

std::string format_ply_binary(const Mesh& mesh, const std::uint8_t* face_rgb) {
  std::string out =
      "ply\nformat binary_little_endian 1.0\ncomment ScopeTrack mesh, model frame, mm\n"
      "element vertex " + std::to_string(mesh.vertex_count()) +
      "\nproperty float x\nproperty float y\nproperty float z\n"
      "element face " + std::to_string(mesh.triangle_count()) +
      "\nproperty list uchar int vertex_indices\n";
  if (face_rgb) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  out += "end_header\n";
  const std::size_t face_bytes = 13 + (face_rgb ? 3 : 0);
  out.reserve(out.size() + 12 * static_cast<std::size_t>(mesh.vertex_count()) +
              face_bytes * static_cast<std::size_t>(mesh.triangle_count()));
  for (int i = 0; i < mesh.vertex_count(); ++i) {
    put_f32_le(out, mesh.x[static_cast<std::size_t>(i)]);
    put_f32_le(out, mesh.y[static_cast<std::size_t>(i)]);
    put_f32_le(out, mesh.z[static_cast<std::size_t>(i)]);
  }
  for (int t = 0; t < mesh.triangle_count(); ++t) {
    out.push_back(3);
    for (int k = 0; k < 3; ++k)
      put_u32_le(out, static_cast<std::uint32_t>(mesh.tri[static_cast<std::size_t>(3 * t + k)]));
    if (face_rgb)
      out.append(reinterpret_cast<const char*>(face_rgb + 3 * static_cast<std::size_t>(t)), 3);
  }
  return out;
}

}  // namespace st
