#include <doctest/doctest.h>

#include <cmath>
#include <string>

#include "core/mesh/mesh.h"
#include "tools/sim/liver_mesh.h"
#include "tools/sim/mesh_ops.h"
#include "tools/sim/organ_shapes.h"
#include "tools/sim/noise.h"

using namespace st;
using namespace st::sim;

TEST_CASE("sim: procedural liver is closed, outward, ~20k triangles, liver-sized") {
  const Mesh m = make_liver_mesh();
  CHECK(m.triangle_count() == 20480);
  CHECK(is_closed_oriented(m));
  CHECK(signed_volume(m) > 0.0);  // counter-clockwise seen from outside
  const Vec3 size = bounding_box(m).size();
  MESSAGE("liver bbox " << size.transpose() << " mm, volume " << signed_volume(m) / 1000 << " ml");
  CHECK(size.x() == doctest::Approx(150).epsilon(0.1));
  CHECK(size.y() == doctest::Approx(100).epsilon(0.12));
  CHECK(size.z() == doctest::Approx(70).epsilon(0.15));
  // Asymmetric: the +x half (thin left lobe) holds clearly less volume.
  double v_pos = 0, v_neg = 0;
  for (int t = 0; t < m.triangle_count(); ++t) {
    const Vec3 a = m.vertex(m.tri[3 * t]), b = m.vertex(m.tri[3 * t + 1]), c = m.vertex(m.tri[3 * t + 2]);
    const double v = a.dot(b.cross(c)) / 6.0;
    ((a.x() + b.x() + c.x()) > 0 ? v_pos : v_neg) += v;
  }
  CHECK(v_pos < 0.8 * v_neg);
}

TEST_CASE("sim: liver mesh is deterministic for a seed and differs across seeds") {
  LiverShape s;
  s.subdivisions = 3;
  const Mesh a = make_liver_mesh(s), b = make_liver_mesh(s);
  s.seed = 2;
  const Mesh c = make_liver_mesh(s);
  CHECK(a.x == b.x);
  CHECK(a.tri == b.tri);
  CHECK(a.x != c.x);
}

TEST_CASE("sim: decimation halves the triangles and keeps the surface closed") {
  const Mesh m = make_liver_mesh();
  const Mesh d = decimate(m, m.triangle_count() / 2);
  MESSAGE("decimated " << m.triangle_count() << " -> " << d.triangle_count());
  CHECK(d.triangle_count() <= m.triangle_count() / 2 + 2);
  CHECK(d.triangle_count() >= m.triangle_count() / 2 - 2);
  CHECK(is_closed_oriented(d));
  CHECK(signed_volume(d) == doctest::Approx(signed_volume(m)).epsilon(0.02));
}

TEST_CASE("sim: perturbation moves vertices by at most the amplitude, smoothly") {
  LiverShape s;
  s.subdivisions = 4;
  const Mesh m = make_liver_mesh(s);
  Mesh p = m;
  perturb_along_normals(p, 1.0, 9);
  double max_d = 0, mean_d = 0;
  for (int i = 0; i < m.vertex_count(); ++i) {
    const double d = (p.vertex(i) - m.vertex(i)).norm();
    max_d = std::max(max_d, d);
    mean_d += d / m.vertex_count();
  }
  MESSAGE("perturbation max " << max_d << " mm, mean " << mean_d << " mm");
  CHECK(max_d <= 1.0 + 1e-5);
  CHECK(mean_d > 0.2);
  CHECK(is_closed_oriented(p));
}

TEST_CASE("sim: noise is bounded, deterministic and continuous") {
  const Noise3 n(3), n2(3);
  double lo = 1e9, hi = -1e9;
  for (int i = 0; i < 2000; ++i) {
    const float x = static_cast<float>(i) * 0.173f, y = static_cast<float>(i % 37) * 0.31f, z = 1.7f;
    const float g = n.gradient(x, y, z);
    CHECK(g == n2.gradient(x, y, z));
    lo = std::min(lo, static_cast<double>(g));
    hi = std::max(hi, static_cast<double>(g));
    CHECK(std::abs(n.gradient(x + 1e-3f, y, z) - g) < 0.01f);
    const float v = n.value(x, y, z);
    CHECK(v >= 0.0f);
    CHECK(v <= 1.0f);
  }
  CHECK(lo < -0.3);
  CHECK(hi > 0.3);
  CHECK(lo >= -1.5);
  CHECK(hi <= 1.5);
}

// The other organs: closed, outward, of their anatomy's size, no face
// turned over by the mapping from the sphere (each face's normal still
// points the way its face on the unit sphere did), deterministic per seed.
TEST_CASE("sim: procedural kidney and stomach are closed, outward, organ-sized, with no face turned over") {
  struct Expect {
    OrganKind kind;
    Vec3 size_mm;
  };
  for (const Expect& e : {Expect{OrganKind::Kidney, Vec3(110, 58, 48)}, Expect{OrganKind::Stomach, Vec3(180, 112, 72)}}) {
    const std::string name = organ_name(e.kind);
    CAPTURE(name);
    const Mesh m = make_organ_mesh(e.kind, 1);
    CHECK(m.triangle_count() == 20480);
    CHECK(is_closed_oriented(m));
    CHECK(signed_volume(m) > 0.0);
    const Vec3 size = bounding_box(m).size();
    MESSAGE(name << " bbox " << size.transpose() << " mm, volume " << signed_volume(m) / 1000 << " ml");
    for (int k = 0; k < 3; ++k) CHECK(size[k] == doctest::Approx(e.size_mm[k]).epsilon(0.15));
    const Mesh sphere = make_icosphere(5);
    REQUIRE(sphere.triangle_count() == m.triangle_count());
    double min_cos = 1.0;
    for (int t = 0; t < m.triangle_count(); ++t) {
      const auto normal = [t](const Mesh& s) {
        const Vec3 a = s.vertex(s.tri[3 * t]), b = s.vertex(s.tri[3 * t + 1]), c = s.vertex(s.tri[3 * t + 2]);
        return Vec3((b - a).cross(c - a).normalized());
      };
      min_cos = std::min(min_cos, normal(m).dot(normal(sphere)));
    }
    MESSAGE("smallest cosine between a face's normal and its sphere face's: " << min_cos);
    CHECK(min_cos > 0.0);
    const Mesh again = make_organ_mesh(e.kind, 1), other = make_organ_mesh(e.kind, 2);
    CHECK(again.x == m.x);
    CHECK(other.x != m.x);
  }
  CHECK(parse_organ("kidney").value() == OrganKind::Kidney);
  CHECK_FALSE(parse_organ("spleen").ok());
  LiverShape liver;
  liver.seed = 3;
  CHECK(make_organ_mesh(OrganKind::Liver, 3).x == make_liver_mesh(liver).x);
}
