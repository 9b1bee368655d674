// PLY reader (ascii, binary_little_endian, binary_big_endian). A generic
// element/property walker: every value of every property is read (so any
// layout can be skipped), x/y/z and the face index list are kept.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "core/base/capacity.h"
#include "core/formats/mesh_io.h"
#include "core/formats/text_scan.h"

namespace st {
namespace {

constexpr std::size_t kMaxPlyHeaderBytes = 64 * 1024;
constexpr int kMaxPolygonVertices = 1024;

enum class PlyFormat { kAscii, kLittle, kBig };
enum class PlyType { kInt8, kUInt8, kInt16, kUInt16, kInt32, kUInt32, kFloat32, kFloat64 };

struct PlyProperty {
  PlyType type = PlyType::kFloat32;
  bool is_list = false;
  PlyType count_type = PlyType::kUInt8;
  std::string name;
};
struct PlyElement {
  std::string name;
  long long count = 0;
  std::vector<PlyProperty> props;
};
struct PlyHeader {
  PlyFormat format = PlyFormat::kAscii;
  std::vector<PlyElement> elements;
  std::size_t data_offset = 0;
};

bool parse_type(std::string_view s, PlyType* t) {
  struct Name { std::string_view a, b; PlyType t; };
  static constexpr std::array<Name, 8> kNames{{{"char", "int8", PlyType::kInt8},
                                               {"uchar", "uint8", PlyType::kUInt8},
                                               {"short", "int16", PlyType::kInt16},
                                               {"ushort", "uint16", PlyType::kUInt16},
                                               {"int", "int32", PlyType::kInt32},
                                               {"uint", "uint32", PlyType::kUInt32},
                                               {"float", "float32", PlyType::kFloat32},
                                               {"double", "float64", PlyType::kFloat64}}};
  for (const Name& n : kNames)
    if (s == n.a || s == n.b) return *t = n.t, true;
  return false;
}

std::size_t type_size(PlyType t) {
  switch (t) {
    case PlyType::kInt8: case PlyType::kUInt8: return 1;
    case PlyType::kInt16: case PlyType::kUInt16: return 2;
    case PlyType::kInt32: case PlyType::kUInt32: case PlyType::kFloat32: return 4;
    case PlyType::kFloat64: return 8;
  }
  return 1;
}

Status parse_property_line(TextScanner& sc, PlyHeader* h, int line) {
  if (h->elements.empty())
    return make_error("PLY header line " + std::to_string(line) + ": property before any element");
  PlyProperty p;
  std::string_view tok = sc.next_token();
  if (tok == "list") {
    p.is_list = true;
    if (!parse_type(sc.next_token(), &p.count_type) || p.count_type == PlyType::kFloat32 ||
        p.count_type == PlyType::kFloat64)
      return make_error("PLY header line " + std::to_string(line) + ": bad list count type");
    tok = sc.next_token();
  }
  if (!parse_type(tok, &p.type))
    return make_error("PLY header line " + std::to_string(line) + ": unknown property type " +
                      quote_bytes(tok));
  p.name = std::string(sc.next_token());
  if (p.name.empty())
    return make_error("PLY header line " + std::to_string(line) + ": property without a name");
  if (h->elements.back().props.size() >= 64)
    return make_error("PLY header line " + std::to_string(line) + ": more than 64 properties");
  h->elements.back().props.push_back(std::move(p));
  return Status::Ok();
}

Status parse_header_line(std::string_view line_text, int line, PlyHeader* h, bool* saw_format) {
  TextScanner sc(line_text);
  const std::string_view key = sc.next_token();
  const std::string where = "PLY header line " + std::to_string(line) + ": ";
  if (key.empty() || key == "comment" || key == "obj_info") return Status::Ok();
  if (key == "format") {
    const std::string_view f = sc.next_token();
    if (f == "ascii") h->format = PlyFormat::kAscii;
    else if (f == "binary_little_endian") h->format = PlyFormat::kLittle;
    else if (f == "binary_big_endian") h->format = PlyFormat::kBig;
    else return make_error(where + "unknown format " + quote_bytes(f));
    *saw_format = true;
    return Status::Ok();
  }
  if (key == "element") {
    PlyElement e;
    e.name = std::string(sc.next_token());
    if (!parse_int64(sc.next_token(), &e.count) || e.count < 0)
      return make_error(where + "element '" + e.name + "' has no valid count");
    if (h->elements.size() >= 16) return make_error(where + "more than 16 elements");
    h->elements.push_back(std::move(e));
    return Status::Ok();
  }
  if (key == "property") return parse_property_line(sc, h, line);
  return make_error(where + "unknown keyword " + quote_bytes(key));
}

Result<PlyHeader> parse_ply_header(std::string_view bytes) {
  if (!(bytes.substr(0, 4) == "ply\n" || bytes.substr(0, 5) == "ply\r\n"))
    return make_error("not a PLY file: it must start with the line 'ply'");
  PlyHeader h;
  bool saw_format = false;
  std::size_t pos = 0;
  for (int line = 1;; ++line) {
    const std::size_t eol = bytes.find('\n', pos);
    if (eol == std::string_view::npos || eol > kMaxPlyHeaderBytes)
      return make_error("PLY header has no 'end_header' line within " +
                        std::to_string(kMaxPlyHeaderBytes) + " bytes (truncated?)");
    std::string_view text = bytes.substr(pos, eol - pos);
    if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
    pos = eol + 1;
    if (line == 1) continue;  // "ply"
    if (text == "end_header") break;
    if (Status s = parse_header_line(text, line, &h, &saw_format); !s) return Error{s.message()};
  }
  if (!saw_format) return make_error("PLY header has no 'format' line");
  h.data_offset = pos;
  return h;
}

// Reads one value of a given type from the body, ascii or binary.
class PlyBody {
 public:
  PlyBody(std::string_view bytes, PlyFormat f) : bytes_(bytes), scan_(bytes), format_(f) {}

  bool read(PlyType t, double* v) {
    if (format_ == PlyFormat::kAscii) return parse_double(scan_.next_token(), v);
    const std::size_t n = type_size(t);
    if (bytes_.size() - pos_ < n) return false;
    std::array<unsigned char, 8> b{};
    std::memcpy(b.data(), bytes_.data() + pos_, n);
    pos_ += n;
    const bool swap = (format_ == PlyFormat::kBig) != (std::endian::native == std::endian::big);
    if (swap) std::reverse(b.begin(), b.begin() + static_cast<std::ptrdiff_t>(n));
    *v = decode(t, b.data());
    return true;
  }
  std::size_t remaining() const {
    return format_ == PlyFormat::kAscii ? scan_.remaining() : bytes_.size() - pos_;
  }
  bool ascii() const { return format_ == PlyFormat::kAscii; }
  int line() const { return scan_.line(); }

 private:
  template <class T>
  static double as(const unsigned char* p) {
    T v;
    std::memcpy(&v, p, sizeof(T));
    return static_cast<double>(v);
  }
  static double decode(PlyType t, const unsigned char* p) {
    switch (t) {
      case PlyType::kInt8: return as<std::int8_t>(p);
      case PlyType::kUInt8: return as<std::uint8_t>(p);
      case PlyType::kInt16: return as<std::int16_t>(p);
      case PlyType::kUInt16: return as<std::uint16_t>(p);
      case PlyType::kInt32: return as<std::int32_t>(p);
      case PlyType::kUInt32: return as<std::uint32_t>(p);
      case PlyType::kFloat32: return as<float>(p);
      case PlyType::kFloat64: return as<double>(p);
    }
    return 0.0;
  }
  std::string_view bytes_;
  TextScanner scan_;
  PlyFormat format_;
  std::size_t pos_ = 0;
};

// Smallest number of bytes one record of `e` can occupy.
std::size_t min_record_bytes(const PlyElement& e, bool ascii) {
  std::size_t n = 0;
  for (const PlyProperty& p : e.props) n += ascii ? 2 : type_size(p.is_list ? p.count_type : p.type);
  return ascii ? (n > 0 ? n - 1 : 0) : n;
}

struct Walk {
  const PlyHeader& header;
  PlyBody body;
  long long declared_vertices = 0;
  Mesh mesh;
};

std::string ply_where(const Walk& w, const char* what, long long index) {
  std::string s = std::string("PLY ") + what + " " + std::to_string(index);
  if (w.body.ascii()) s += " (line " + std::to_string(w.body.line()) + ")";
  return s;
}

Status read_vertex(Walk& w, const PlyElement& e, long long i, const int xyz_prop[3]) {
  std::array<double, 3> xyz{};
  for (int k = 0; k < static_cast<int>(e.props.size()); ++k) {
    const PlyProperty& p = e.props[static_cast<std::size_t>(k)];
    double v = 0;
    if (p.is_list) return make_error("PLY vertex element has a list property '" + p.name + "'");
    if (!w.body.read(p.type, &v))
      return make_error(ply_where(w, "vertex", i) + ": missing or malformed value of '" + p.name +
                        "' (truncated file?)");
    for (int c = 0; c < 3; ++c)
      if (xyz_prop[c] == k) xyz[static_cast<std::size_t>(c)] = v;
  }
  for (double c : xyz)
    if (!std::isfinite(c) || std::abs(c) > 1e30)
      return make_error(ply_where(w, "vertex", i) + " has a non-finite or absurd coordinate");
  w.mesh.add_vertex(static_cast<float>(xyz[0]), static_cast<float>(xyz[1]),
                    static_cast<float>(xyz[2]));
  return Status::Ok();
}

Status read_index_list(Walk& w, const PlyProperty& p, long long face, bool keep) {
  double count_d = 0;
  if (!w.body.read(p.count_type, &count_d))
    return make_error(ply_where(w, "face", face) + ": missing list count (truncated file?)");
  if (count_d != std::floor(count_d) || count_d < 0 || count_d > kMaxPolygonVertices)
    return make_error(ply_where(w, "face", face) + ": list count " + std::to_string(count_d) +
                      " is not an integer in 0.." + std::to_string(kMaxPolygonVertices));
  const int count = static_cast<int>(count_d);
  if (keep && count < 3)
    return make_error(ply_where(w, "face", face) + " has " + std::to_string(count) +
                      " vertices (a face needs at least 3)");
  std::array<std::int32_t, kMaxPolygonVertices> idx{};
  for (int k = 0; k < count; ++k) {
    double v = 0;
    if (!w.body.read(p.type, &v))
      return make_error(ply_where(w, "face", face) + ": missing index (truncated file?)");
    if (keep && (v != std::floor(v) || v < 0 || v >= static_cast<double>(w.declared_vertices)))
      return make_error(ply_where(w, "face", face) + ": vertex index " + std::to_string(v) +
                        " is outside 0.." + std::to_string(w.declared_vertices - 1));
    idx[static_cast<std::size_t>(k)] = keep ? static_cast<std::int32_t>(v) : 0;
  }
  if (!keep) return Status::Ok();
  if (w.mesh.triangle_count() + count - 2 > kMaxMeshTriangles)
    return make_error("PLY mesh has more than " + std::to_string(kMaxMeshTriangles) + " triangles");
  for (int k = 1; k + 1 < count; ++k)  // fan: (0, k, k+1) keeps the polygon's winding
    w.mesh.add_triangle(idx[0], idx[static_cast<std::size_t>(k)], idx[static_cast<std::size_t>(k + 1)]);
  return Status::Ok();
}

Status read_record(Walk& w, const PlyElement& e, long long i, bool is_face) {
  for (const PlyProperty& p : e.props) {
    if (p.is_list) {
      const bool keep = is_face && (p.name == "vertex_indices" || p.name == "vertex_index");
      if (Status s = read_index_list(w, p, i, keep); !s) return s;
    } else {
      double v = 0;
      if (!w.body.read(p.type, &v))
        return make_error(ply_where(w, e.name.c_str(), i) + ": missing or malformed value of '" +
                          p.name + "' (truncated file?)");
    }
  }
  return Status::Ok();
}

Status read_element(Walk& w, const PlyElement& e) {
  if (e.props.empty()) return Status::Ok();  // nothing stored: nothing to read
  const std::size_t min_bytes = min_record_bytes(e, w.body.ascii());
  if (min_bytes > 0 && static_cast<unsigned long long>(e.count) > w.body.remaining() / min_bytes)
    return make_error("PLY element '" + e.name + "' declares " + std::to_string(e.count) +
                      " records but only " + std::to_string(w.body.remaining()) +
                      " bytes remain (truncated file or absurd count)");
  const bool is_vertex = e.name == "vertex";
  const bool is_face = e.name == "face";
  int xyz_prop[3] = {-1, -1, -1};
  if (is_vertex) {
    for (int k = 0; k < static_cast<int>(e.props.size()); ++k)
      for (int c = 0; c < 3; ++c)
        if (e.props[static_cast<std::size_t>(k)].name == std::string(1, static_cast<char>('x' + c)))
          xyz_prop[c] = k;
    if (xyz_prop[0] < 0 || xyz_prop[1] < 0 || xyz_prop[2] < 0)
      return make_error("PLY vertex element lacks one of the properties x, y, z");
    w.mesh.x.reserve(static_cast<std::size_t>(e.count));
    w.mesh.y.reserve(static_cast<std::size_t>(e.count));
    w.mesh.z.reserve(static_cast<std::size_t>(e.count));
  }
  if (is_face) w.mesh.tri.reserve(static_cast<std::size_t>(e.count) * 3);
  for (long long i = 0; i < e.count; ++i) {
    Status s = is_vertex ? read_vertex(w, e, i, xyz_prop) : read_record(w, e, i, is_face);
    if (!s) return s;
  }
  return Status::Ok();
}

Status check_counts(const PlyHeader& h, long long* vertices) {
  bool has_vertex = false, has_face = false;
  for (const PlyElement& e : h.elements) {
    if (e.name == "vertex") {
      if (e.count > kMaxMeshVertices)
        return make_error("PLY declares " + std::to_string(e.count) + " vertices, more than the " +
                          std::to_string(kMaxMeshVertices) + " supported");
      *vertices = e.count;
      has_vertex = true;
    }
    if (e.name == "face") {
      if (e.count > kMaxMeshTriangles)
        return make_error("PLY declares " + std::to_string(e.count) + " faces, more than the " +
                          std::to_string(kMaxMeshTriangles) + " supported");
      bool has_list = false;
      for (const PlyProperty& p : e.props)
        has_list |= p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index");
      if (!has_list) return make_error("PLY face element has no vertex_indices list");
      has_face = true;
    }
  }
  if (!has_vertex || !has_face)
    return make_error("PLY has no vertex or no face element (point clouds are not meshes)");
  return Status::Ok();
}

}  // namespace

Result<Mesh> parse_ply(std::string_view bytes) {
  if (bytes.size() > static_cast<std::size_t>(kMaxMeshFileBytes))
    return make_error("PLY file is larger than " + std::to_string(kMaxMeshFileBytes) + " bytes");
  Result<PlyHeader> header = parse_ply_header(bytes);
  if (!header) return header.error();
  Walk w{header.value(), PlyBody(bytes.substr(header->data_offset), header->format), 0, {}};
  if (Status s = check_counts(w.header, &w.declared_vertices); !s) return Error{s.message()};
  for (const PlyElement& e : w.header.elements)
    if (Status s = read_element(w, e); !s) return Error{s.message()};
  return std::move(w.mesh);
}

}  // namespace st
