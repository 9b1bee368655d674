// Reads exactly the binary little-endian PLY layout of
// ../shared/data/liver/liver.ply (float x y z vertices, uchar-counted int
// triangle lists) into a Mesh. For tests and the bench only, until the
// project's PLY parser lands; header-only so that scopetrack-bench can use
// it without a build change. Refuses anything else with an error.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "core/base/capacity.h"
#include "core/mesh/mesh.h"
#include "core/base/result.h"

namespace st::test {

inline Result<Mesh> read_binary_ply_for_tests(std::string_view bytes) {
  const std::size_t end = bytes.find("end_header\n");
  if (bytes.substr(0, 4) != "ply\n" || end == std::string_view::npos)
    return make_error("test PLY: not a PLY file with end_header");
  const std::string_view header = bytes.substr(0, end);
  long long nv = -1, nf = -1;
  const char* expect[] = {"format binary_little_endian 1.0", "property float x", "property float y",
                          "property float z", "property list uchar int vertex_indices"};
  for (const char* e : expect)
    if (header.find(e) == std::string_view::npos)
      return make_error(std::string("test PLY: header lacks '") + e + "'");
  const std::size_t v = header.find("element vertex "), f = header.find("element face ");
  if (v == std::string_view::npos || f == std::string_view::npos || f < v)
    return make_error("test PLY: needs element vertex then element face");
  nv = std::atoll(std::string(header.substr(v + 15, 12)).c_str());
  nf = std::atoll(std::string(header.substr(f + 13, 12)).c_str());
  if (nv <= 0 || nf <= 0 || nv > kMaxMeshVertices || nf > kMaxMeshTriangles)
    return make_error("test PLY: element counts out of range");
  const std::size_t body = end + 11;
  const std::size_t need = static_cast<std::size_t>(nv) * 12 + static_cast<std::size_t>(nf) * 13;
  if (bytes.size() - body != need) return make_error("test PLY: body size does not match counts");
  Mesh m;
  m.x.resize(nv);
  m.y.resize(nv);
  m.z.resize(nv);
  const char* p = bytes.data() + body;
  for (long long i = 0; i < nv; ++i, p += 12) {
    std::memcpy(&m.x[i], p, 4);
    std::memcpy(&m.y[i], p + 4, 4);
    std::memcpy(&m.z[i], p + 8, 4);
  }
  m.tri.resize(static_cast<std::size_t>(nf) * 3);
  for (long long i = 0; i < nf; ++i, p += 13) {
    if (static_cast<unsigned char>(p[0]) != 3) return make_error("test PLY: non-triangle face");
    std::memcpy(&m.tri[3 * i], p + 1, 12);
    for (int k = 0; k < 3; ++k)
      if (m.tri[3 * i + k] < 0 || m.tri[3 * i + k] >= nv)
        return make_error("test PLY: vertex index out of range");
  }
  return m;
}

}  // namespace st::test
