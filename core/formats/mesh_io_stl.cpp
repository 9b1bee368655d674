// STL reader (binary and ascii). STL stores a triangle soup; identical
// vertices (bit-equal coordinates) are merged so the mesh is indexed.
#include <cmath>
#include <cstring>
#include <unordered_map>

#include "core/base/capacity.h"
#include "core/formats/mesh_io.h"
#include "core/formats/text_scan.h"

namespace st {
namespace {

constexpr std::size_t kStlHeaderBytes = 84;  // 80-byte comment + uint32 facet count
constexpr std::size_t kStlFacetBytes = 50;   // normal, 3 vertices (float32 x 12), uint16 attribute

struct VertexKey {
  std::uint32_t x, y, z;
  bool operator==(const VertexKey&) const = default;
};
struct VertexKeyHash {
  std::size_t operator()(const VertexKey& k) const {
    return (static_cast<std::size_t>(k.x) * 73856093u) ^ (static_cast<std::size_t>(k.y) * 19349663u) ^
           (static_cast<std::size_t>(k.z) * 83492791u);
  }
};

class Welder {
 public:
  explicit Welder(std::size_t expected_triangles) {
    map_.reserve(expected_triangles / 2 + 16);
    mesh_.tri.reserve(expected_triangles * 3);
  }
  std::int32_t add(float x, float y, float z) {
    x += 0.0f;  // -0 and +0 are one vertex
    y += 0.0f;
    z += 0.0f;
    VertexKey k{};
    std::memcpy(&k.x, &x, 4);
    std::memcpy(&k.y, &y, 4);
    std::memcpy(&k.z, &z, 4);
    const auto [it, inserted] = map_.try_emplace(k, mesh_.vertex_count());
    if (inserted) mesh_.add_vertex(x, y, z);
    return it->second;
  }
  void add_triangle(const std::int32_t v[3]) { mesh_.add_triangle(v[0], v[1], v[2]); }
  int triangles() const { return mesh_.triangle_count(); }
  Mesh take() { return std::move(mesh_); }

 private:
  std::unordered_map<VertexKey, std::int32_t, VertexKeyHash> map_;
  Mesh mesh_;
};

bool finite_coord(double v) { return std::isfinite(v) && std::abs(v) < 1e30; }

std::uint32_t read_u32_le(const char* p) {
  const auto* b = reinterpret_cast<const unsigned char*>(p);
  return static_cast<std::uint32_t>(b[0]) | (static_cast<std::uint32_t>(b[1]) << 8) |
         (static_cast<std::uint32_t>(b[2]) << 16) | (static_cast<std::uint32_t>(b[3]) << 24);
}
float read_f32_le(const char* p) {
  const std::uint32_t u = read_u32_le(p);
  float f;
  std::memcpy(&f, &u, 4);
  return f;
}

Result<Mesh> parse_stl_binary(std::string_view bytes) {
  if (bytes.size() < kStlHeaderBytes)
    return make_error("binary STL is " + std::to_string(bytes.size()) +
                      " bytes, shorter than its 84-byte header");
  const std::uint32_t n = read_u32_le(bytes.data() + 80);
  if (n == 0) return make_error("STL has no triangles");
  if (n > kMaxMeshTriangles)
    return make_error("STL declares " + std::to_string(n) + " triangles, more than the " +
                      std::to_string(kMaxMeshTriangles) + " supported");
  const std::size_t need = kStlHeaderBytes + kStlFacetBytes * n;
  if (bytes.size() < need)
    return make_error("binary STL is truncated: " + std::to_string(n) + " triangles need " +
                      std::to_string(need) + " bytes, the file has " + std::to_string(bytes.size()));
  Welder welder(n);
  for (std::uint32_t f = 0; f < n; ++f) {
    const char* p = bytes.data() + kStlHeaderBytes + kStlFacetBytes * f + 12;  // skip the normal
    std::int32_t v[3];
    for (int k = 0; k < 3; ++k) {
      const float x = read_f32_le(p + 12 * k), y = read_f32_le(p + 12 * k + 4),
                  z = read_f32_le(p + 12 * k + 8);
      if (!finite_coord(static_cast<double>(x)) || !finite_coord(static_cast<double>(y)) ||
          !finite_coord(static_cast<double>(z)))
        return make_error("STL triangle " + std::to_string(f) + " has a non-finite coordinate");
      v[k] = welder.add(x, y, z);
    }
    welder.add_triangle(v);
  }
  return welder.take();
}

Status expect(TextScanner& sc, std::string_view word) {
  const std::string_view tok = sc.next_token();
  if (tok == word) return Status::Ok();
  return make_error("ASCII STL line " + std::to_string(sc.line()) + ": expected '" +
                    std::string(word) + "', found " + quote_bytes(tok));
}

Status parse_ascii_facet(TextScanner& sc, Welder& welder) {
  if (Status s = expect(sc, "normal"); !s) return s;
  for (int k = 0; k < 3; ++k) sc.next_token();  // the normal is recomputed from the winding
  if (Status s = expect(sc, "outer"); !s) return s;
  if (Status s = expect(sc, "loop"); !s) return s;
  std::int32_t v[3];
  for (int k = 0; k < 3; ++k) {
    if (Status s = expect(sc, "vertex"); !s) return s;
    double c[3];
    for (double& ci : c)
      if (!parse_double(sc.next_token(), &ci) || !finite_coord(ci))
        return make_error("ASCII STL line " + std::to_string(sc.line()) +
                          ": vertex coordinate is missing or not a finite number");
    v[k] = welder.add(static_cast<float>(c[0]), static_cast<float>(c[1]), static_cast<float>(c[2]));
  }
  if (Status s = expect(sc, "endloop"); !s) return s;
  if (Status s = expect(sc, "endfacet"); !s) return s;
  welder.add_triangle(v);
  return Status::Ok();
}

Result<Mesh> parse_stl_ascii(std::string_view bytes) {
  TextScanner sc(bytes);
  Welder welder(bytes.size() / 256);  // a facet takes ~250 bytes of text
  bool in_solid = false;
  while (!sc.at_end()) {
    const std::string_view tok = sc.next_token();
    if (!in_solid && tok == "solid") {
      sc.skip_line();  // the solid's name
      in_solid = true;
    } else if (in_solid && tok == "endsolid") {
      sc.skip_line();
      in_solid = false;
    } else if (in_solid && tok == "facet") {
      if (welder.triangles() >= kMaxMeshTriangles)
        return make_error("ASCII STL has more than " + std::to_string(kMaxMeshTriangles) + " triangles");
      if (Status s = parse_ascii_facet(sc, welder); !s) return Error{s.message()};
    } else {
      return make_error("ASCII STL line " + std::to_string(sc.line()) + ": unexpected " +
                        quote_bytes(tok));
    }
  }
  if (in_solid) return make_error("ASCII STL ends without 'endsolid' (truncated file?)");
  if (welder.triangles() == 0) return make_error("STL has no triangles");
  return welder.take();
}

bool starts_with_solid(std::string_view bytes) {
  const std::size_t start = bytes.find_first_not_of(" \t\r\n");
  return start != std::string_view::npos && bytes.substr(start, 5) == "solid";
}

}  // namespace

// Binary when the size matches the declared count exactly (binary files may
// also begin with "solid"), else ascii when it begins with "solid".
bool looks_like_binary_stl(std::string_view bytes) {
  if (bytes.size() < kStlHeaderBytes) return false;
  const std::uint64_t n = read_u32_le(bytes.data() + 80);
  return bytes.size() == kStlHeaderBytes + kStlFacetBytes * n;
}

Result<Mesh> parse_stl(std::string_view bytes) {
  if (bytes.size() > static_cast<std::size_t>(kMaxMeshFileBytes))
    return make_error("STL file is larger than " + std::to_string(kMaxMeshFileBytes) + " bytes");
  if (looks_like_binary_stl(bytes) || !starts_with_solid(bytes)) return parse_stl_binary(bytes);
  return parse_stl_ascii(bytes);
}

}  // namespace st
