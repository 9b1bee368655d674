#include "core/mesh_io.h"

#include <cmath>
#include <cstdio>
#include <cstring>

#include "core/capacity.h"

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

std::string summarise(const MeshReport& r, bool winding_known) {
  const Vec3 e = r.max - r.min;
  char buf[256];
  std::snprintf(buf, sizeof buf, "%d triangles, %d vertices, extent %.1f x %.1f x %.1f mm, volume %.1f cm^3",
                r.triangles, r.vertices, e.x(), e.y(), e.z(), r.signed_volume_mm3 / 1000.0);
  std::string s = buf;
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
