// Triangle mesh, structure of arrays, model frame, millimetres.
// Faces are counter-clockwise seen from outside (outward normals).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

struct Mesh {
  std::vector<float> x, y, z;      // vertex coordinates, mm
  std::vector<std::int32_t> tri;   // 3 vertex indices per triangle

  int vertex_count() const { return static_cast<int>(x.size()); }
  int triangle_count() const { return static_cast<int>(tri.size() / 3); }
  Vec3 vertex(int i) const {
    return {static_cast<double>(x[i]), static_cast<double>(y[i]), static_cast<double>(z[i])};
  }
  void add_vertex(float vx, float vy, float vz) {
    x.push_back(vx);
    y.push_back(vy);
    z.push_back(vz);
  }
  void add_triangle(std::int32_t a, std::int32_t b, std::int32_t c) {
    tri.push_back(a);
    tri.push_back(b);
    tri.push_back(c);
  }
};

}  // namespace st
