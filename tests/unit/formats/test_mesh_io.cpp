#include <doctest/doctest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "core/base/capacity.h"
#include "core/formats/mesh_io.h"
#include "hal/storage/mesh_file.h"
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

TEST_CASE("mesh_io: inward winding is detected, flipped and reported") {
  Mesh m = cube(20);
  for (int t = 0; t < m.triangle_count(); ++t) std::swap(m.tri[3 * t + 1], m.tri[3 * t + 2]);
  MeshReport r;
  REQUIRE(validate_and_orient(m, &r).ok());
  CHECK(r.flipped);
  CHECK(r.signed_volume_mm3 == doctest::Approx(8000.0));
  CHECK(r.summary.find("wound inward") != std::string::npos);
  CHECK(m.tri == cube(20).tri);
  // Through the file path too: an inward PLY and an inward STL.
  const auto dir = test::scratch_dir("mesh_inward");
  Mesh inward = cube(20);
  for (int t = 0; t < inward.triangle_count(); ++t) std::swap(inward.tri[3 * t], inward.tri[3 * t + 1]);
  REQUIRE(save_mesh_ply(dir / "in.ply", inward).ok());
  MeshReport r2;
  auto loaded = load_mesh_file(dir / "in.ply", &r2);
  REQUIRE(loaded.ok());
  CHECK(r2.flipped);
  // An open surface: the winding cannot be judged and is left alone.
  Mesh open;
  open.add_vertex(0, 0, 0);
  open.add_vertex(1, 0, 0);
  open.add_vertex(0, 1, 0);
  open.add_triangle(0, 1, 2);
  MeshReport r3;
  REQUIRE(validate_and_orient(open, &r3).ok());
  CHECK_FALSE(r3.flipped);
  CHECK(r3.summary.find("winding unknown") != std::string::npos);
}

TEST_CASE("mesh_io: faces wound against their neighbours are turned to agree (10 % of the CT liver)") {
  auto liver = load_mesh_file(test::shared_data("liver/liver.ply"), nullptr);
  REQUIRE(liver.ok());
  Mesh m = liver.value();
  std::mt19937 rng(5);
  int turned = 0;
  for (int t = 0; t < m.triangle_count(); ++t)
    if (rng() % 10 == 0) {
      std::swap(m.tri[3 * t + 1], m.tri[3 * t + 2]);
      ++turned;
    }
  REQUIRE(turned > 1500);
  MeshReport r;
  REQUIRE(validate_and_orient(m, &r).ok());
  CHECK(r.reoriented == turned);
  CHECK_FALSE(r.flipped);
  CHECK(m.tri == liver->tri);  // exactly the faces turned, each back as it was
  CHECK(r.summary.find(std::to_string(turned) + " faces wound against their neighbours") != std::string::npos);
  // The majority decides, then the volume: 90 % of the faces inward.
  Mesh inward = liver.value();
  for (int t = 0; t < inward.triangle_count(); ++t)
    if (rng() % 10 != 0) std::swap(inward.tri[3 * t + 1], inward.tri[3 * t + 2]);
  MeshReport r2;
  REQUIRE(validate_and_orient(inward, &r2).ok());
  CHECK(r2.flipped);
  CHECK(r2.reoriented > 1500);
  CHECK(r2.reoriented < 2500);
  CHECK(inward.tri == liver->tri);
  // A consistent mesh is left alone.
  Mesh same = liver.value();
  MeshReport r3;
  REQUIRE(validate_and_orient(same, &r3).ok());
  CHECK(r3.reoriented == 0);
  CHECK(same.tri == liver->tri);
}

TEST_CASE("mesh_io: orientation repair per connected part, non-manifold edges link nothing") {
  // Two cubes apart: the second has one face (two triangles) turned.
  Mesh m = cube(10);
  Mesh second = cube(10);
  std::swap(second.tri[1], second.tri[2]);
  std::swap(second.tri[4], second.tri[5]);
  const auto base = static_cast<std::int32_t>(m.vertex_count());
  for (int i = 0; i < second.vertex_count(); ++i) m.add_vertex(second.x[i] + 50.f, second.y[i], second.z[i]);
  for (const std::int32_t v : second.tri) m.tri.push_back(v + base);
  MeshReport r;
  REQUIRE(validate_and_orient(m, &r).ok());
  CHECK(r.reoriented == 2);
  CHECK_FALSE(r.flipped);
  CHECK(r.signed_volume_mm3 == doctest::Approx(2000.0));
  // A fin: a third triangle on an edge of a closed cube. That edge has three
  // faces and links none of them; the fin, alone in its part, stays as it is.
  Mesh fin = cube(10);
  fin.add_vertex(5, 5, 30);
  fin.add_triangle(fin.tri[0], fin.tri[1], 8);
  const std::vector<std::int32_t> before = fin.tri;
  MeshReport r2;
  REQUIRE(validate_and_orient(fin, &r2).ok());
  CHECK(r2.reoriented == 0);
  CHECK(fin.tri == before);
}

namespace {
std::string binary_stl(const Mesh& m) {
  std::string s(80, ' ');
  auto u32 = [&](std::uint32_t v) { for (int k = 0; k < 4; ++k) s.push_back(static_cast<char>(v >> (8 * k))); };
  auto f32 = [&](float f) { std::uint32_t u; std::memcpy(&u, &f, 4); u32(u); };
  u32(static_cast<std::uint32_t>(m.triangle_count()));
  for (int t = 0; t < m.triangle_count(); ++t) {
    for (int k = 0; k < 3; ++k) f32(0.0f);
    for (int k = 0; k < 3; ++k) {
      const int v = m.tri[static_cast<std::size_t>(3 * t + k)];
      f32(m.x[static_cast<std::size_t>(v)]); f32(m.y[static_cast<std::size_t>(v)]); f32(m.z[static_cast<std::size_t>(v)]);
    }
    s.push_back(0);
    s.push_back(0);
  }
  return s;
}
std::string ascii_stl(const Mesh& m) {
  std::string s = "solid cube exported\n";
  for (int t = 0; t < m.triangle_count(); ++t) {
    s += "  facet normal 0 0 0\n    outer loop\n";
    for (int k = 0; k < 3; ++k) {
      const auto v = static_cast<std::size_t>(m.tri[static_cast<std::size_t>(3 * t + k)]);
      s += "      vertex " + std::to_string(m.x[v]) + " " + std::to_string(m.y[v]) + " " + std::to_string(m.z[v]) + "\n";
    }
    s += "    endloop\n  endfacet\n";
  }
  return s + "endsolid cube\n";
}
}  // namespace

TEST_CASE("mesh_io: STL binary and ascii load, weld and sniff") {
  const Mesh c = cube(10);
  for (const std::string& bytes : {binary_stl(c), ascii_stl(c)}) {
    auto m = parse_mesh(bytes);
    REQUIRE_MESSAGE(m.ok(), (m.ok() ? "" : m.message()));
    CHECK(m->triangle_count() == 12);
    CHECK(m->vertex_count() == 8);  // welded
    MeshReport r;
    REQUIRE(validate_and_orient(m.value(), &r).ok());
    CHECK_FALSE(r.flipped);
    CHECK(r.signed_volume_mm3 == doctest::Approx(1000.0));
  }
  // A binary STL whose header starts with "solid" is still binary.
  std::string b = binary_stl(c);
  b.replace(0, 5, "solid");
  auto m = parse_stl(b);
  REQUIRE(m.ok());
  CHECK(m->triangle_count() == 12);
}

TEST_CASE("mesh_io: bad PLY input gives clear errors") {
  const std::string tri = "0 0 0\n1 0 0\n0 1 0\n";
  struct Case { std::string bytes; const char* needle; };
  std::string big = format_ply_binary(cube(1));
  std::string huge = big;
  huge.replace(huge.find("element vertex 8"), 16, "element vertex 1999999");
  std::string nan_bin = big;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan_bin.data() + nan_bin.find("end_header\n") + 11 + 4, &nan, 4);
  const Case cases[] = {
      {"", "must start with the line 'ply'"},
      {"plyx\n", "must start with the line 'ply'"},
      {"\x89PNG\r\n\x1a\n garbage", "must start with the line 'ply'"},
      {"ply\nformat ascii 1.0\nelement vertex 3\n", "end_header"},                  // truncated header
      {"ply\nformat foo 1.0\nend_header\n", "unknown format"},
      {"ply\nend_header\n", "no 'format'"},
      {"ply\nformat ascii 1.0\nelement vertex 3\nproperty quad x\nend_header\n", "unknown property type"},
      {"ply\nformat ascii 1.0\nbogus\nend_header\n", "unknown keyword"},
      {ascii_ply_header(3, 1) + tri + "3 0 1 3\n", "outside 0..2"},                // index out of range
      {ascii_ply_header(3, 1) + tri + "3 0 -1 2\n", "outside 0..2"},
      {ascii_ply_header(3, 1) + tri + "3 0 1.5 2\n", "outside 0..2"},
      {ascii_ply_header(3, 1) + tri + "2 0 1\n", "at least 3"},
      {ascii_ply_header(3, 1) + tri + "100000 0 1\n", "list count"},
      {ascii_ply_header(3, 1) + "0 0 nan\n1 0 0\n0 1 0\n3 0 1 2\n", "non-finite"},  // NaN
      {ascii_ply_header(3, 1) + "0 0 1e300\n1 0 0\n0 1 0\n3 0 1 2\n", "non-finite"},
      {ascii_ply_header(3, 1) + "0 0 0\n1 0\n", "remain"},                           // truncated body
      {ascii_ply_header(3, 1) + "0 0 0\n1 0 0\n0 1 0\n3 0 1\n", "missing index"},
      {ascii_ply_header(3, 1) + "0 0 0\n1 0 zz\n0 1 0\n3 0 1 2\n", "malformed"},
      {ascii_ply_header(3000000, 1), "more than"},                                   // huge count, capped
      {ascii_ply_header(2000000, 1) + tri, "remain"},                                // declared, not present
      {ascii_ply_header(3, 5000000), "more than"},
      {ascii_ply_header(0, 0), "empty"},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n", "no vertex or no face"},
      {"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n0 0\n", "x, y, z"},
      {huge, "remain"},
      {big.substr(0, big.size() - 7), "truncated"},
      {nan_bin, "non-finite"},
  };
  for (const Case& c : cases) {
    Result<Mesh> r = parse_ply(c.bytes);
    Status s = r.ok() ? validate_and_orient(r.value(), nullptr) : Status(r.error());
    REQUIRE_FALSE(s.ok());
    INFO(s.message());
    CHECK(s.message().find(c.needle) != std::string::npos);
  }
}

TEST_CASE("mesh_io: bad STL input and bad meshes give clear errors") {
  const std::string good = binary_stl(cube(1));
  std::string huge = good.substr(0, 84);
  huge[80] = huge[81] = huge[82] = '\xff';
  huge[83] = '\x7f';
  std::string nan_stl = good;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  std::memcpy(nan_stl.data() + 84 + 12, &nan, 4);
  std::string zero = good.substr(0, 80) + std::string(4, '\0');
  struct Case { std::string bytes; const char* needle; };
  const Case cases[] = {
      {good.substr(0, 50), "shorter than its 84-byte header"},
      {good.substr(0, good.size() - 10), "truncated"},
      {huge, "more than"},
      {zero, "no triangles"},
      {nan_stl, "non-finite"},
      {"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nendloop\nendfacet\nendsolid\n", "expected 'vertex'"},
      {"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 nan\nvertex 0 1 0\nendloop\nendfacet\nendsolid\n", "finite"},
      {"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n", "expected 'vertex'"},
      {"solid x\n", "without 'endsolid'"},
      {"solid x\nendsolid x\n", "no triangles"},
      {"solid x\n  garbage\n", "unexpected"},
  };
  for (const Case& c : cases) {
    auto r = parse_stl(c.bytes);
    REQUIRE_FALSE(r.ok());
    INFO(r.message());
    CHECK(r.message().find(c.needle) != std::string::npos);
  }
  auto unknown = parse_mesh("hello");
  REQUIRE_FALSE(unknown.ok());
  CHECK(unknown.message().find("neither PLY") != std::string::npos);
  // Meshes built in code are validated too.
  Mesh m = cube(1);
  m.tri[5] = 8;
  CHECK(validate_and_orient(m, nullptr).message().find("outside 0..7") != std::string::npos);
  m = cube(1);
  m.x[3] = std::numeric_limits<float>::infinity();
  CHECK(validate_and_orient(m, nullptr).message().find("non-finite") != std::string::npos);
  Mesh empty;
  CHECK(validate_and_orient(empty, nullptr).message().find("empty") != std::string::npos);
}

TEST_CASE("mesh_io: a truncated copy of the real liver fails cleanly at every cut") {
  const std::string bytes = test::read_file_bytes(test::shared_data("liver/liver.ply"));
  REQUIRE(bytes.size() > 1000);
  for (std::size_t cut : {std::size_t{0}, std::size_t{10}, std::size_t{200}, std::size_t{5000},
                          bytes.size() / 2, bytes.size() - 1}) {
    auto r = parse_ply(std::string_view(bytes).substr(0, cut));
    CHECK_FALSE(r.ok());
  }
  auto r = load_mesh_file(test::shared_data("liver/does-not-exist.ply"), nullptr);
  REQUIRE_FALSE(r.ok());
  CHECK(r.message().find("does-not-exist.ply") != std::string::npos);
}
