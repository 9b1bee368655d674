#include <doctest/doctest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "core/capacity.h"
#include "core/mesh_io.h"
#include "hal/mesh_file.h"
#include "support/support.h"

using namespace st;

namespace {

// A closed, outward unit-ish cube (12 triangles, 8 vertices), side s mm.
Mesh cube(float s) {
  Mesh m;
  for (int i = 0; i < 8; ++i) m.add_vertex((i & 1) ? s : 0, (i & 2) ? s : 0, (i & 4) ? s : 0);
  const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                        {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  for (const auto& t : f) m.add_triangle(t[0], t[1], t[2]);
  return m;
}

std::string ascii_ply_header(int vertices, int faces, const char* vertex_type = "float",
                             const char* list = "uchar int") {
  return std::string("ply\nformat ascii 1.0\ncomment test\nelement vertex ") + std::to_string(vertices) +
         "\nproperty " + vertex_type + " x\nproperty " + vertex_type + " y\nproperty " + vertex_type +
         " z\nelement face " + std::to_string(faces) + "\nproperty list " + list +
         " vertex_indices\nend_header\n";
}

}  // namespace

TEST_CASE("mesh_io: binary PLY write/parse round trip, with and without colours") {
  const Mesh m = cube(10);
  std::vector<std::uint8_t> rgb(36);
  for (std::size_t i = 0; i < rgb.size(); ++i) rgb[i] = static_cast<std::uint8_t>(7 * i);
  for (const std::uint8_t* colours : {static_cast<const std::uint8_t*>(nullptr), static_cast<const std::uint8_t*>(rgb.data())}) {
    auto back = parse_ply(format_ply_binary(m, colours));
    REQUIRE(back.ok());
    CHECK(back->x == m.x);
    CHECK(back->y == m.y);
    CHECK(back->z == m.z);
    CHECK(back->tri == m.tri);
  }
  MeshReport r;
  Mesh c = cube(10);
  REQUIRE(validate_and_orient(c, &r).ok());
  CHECK_FALSE(r.flipped);
  CHECK(r.signed_volume_mm3 == doctest::Approx(1000.0));
  CHECK(r.triangles == 12);
  CHECK(r.vertices == 8);
}

TEST_CASE("mesh_io: the real CT liver loads as 20,000 outward triangles") {
  MeshReport r;
  auto m = load_mesh_file(test::shared_data("liver/liver.ply"), &r);
  REQUIRE_MESSAGE(m.ok(), (m.ok() ? "" : m.message()));
  CHECK(m->triangle_count() == 20000);
  CHECK(m->vertex_count() == 10012);
  CHECK_FALSE(r.flipped);
  CHECK(r.signed_volume_mm3 > 0);
  const Vec3 e = r.max - r.min;
  CHECK(e.x() == doctest::Approx(221).epsilon(0.02));
  CHECK(e.y() == doctest::Approx(214).epsilon(0.02));
  CHECK(e.z() == doctest::Approx(190).epsilon(0.02));
  MESSAGE(r.summary);
}

TEST_CASE("mesh_io: ascii PLY with double vertices, extra properties, quads") {
  const std::string ply =
      "ply\r\nformat ascii 1.0\r\nelement vertex 4\r\nproperty double x\r\nproperty double y\r\n"
      "property float confidence\r\nproperty double z\r\nelement face 1\r\n"
      "property uchar flags\r\nproperty list ushort uint vertex_index\r\nend_header\r\n"
      "0 0 0.5 0\n1 0 0.5 0\n1 1 0.5 0\n0 1 0.5 0\n7 4 0 1 2 3\n";
  auto m = parse_ply(ply);
  REQUIRE_MESSAGE(m.ok(), (m.ok() ? "" : m.message()));
  CHECK(m->vertex_count() == 4);
  REQUIRE(m->triangle_count() == 2);
  CHECK(m->tri == std::vector<std::int32_t>{0, 1, 2, 0, 2, 3});
  CHECK(m->z[2] == 0.0f);
  auto m2 = parse_ply(ascii_ply_header(3, 1, "float", "int short") + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n");
  REQUIRE(m2.ok());
  CHECK(m2->triangle_count() == 1);
}
