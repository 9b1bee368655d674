#include "support/raster_reference.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace st::test {
namespace {

struct CameraTriangle {
  Vec3 p[3];
  Vec3 n;
  double d = 0;  // n . p0; < 0 where the eye sees the outward side
};

CameraTriangle camera_triangle(const Mesh& m, const SE3& T, int t) {
  CameraTriangle c;
  for (int k = 0; k < 3; ++k) c.p[k] = T * m.vertex(m.tri[3 * t + k]);
  c.n = (c.p[1] - c.p[0]).cross(c.p[2] - c.p[0]);
  c.d = c.n.dot(c.p[0]);
  return c;
}

Vec3 pixel_ray(const Pinhole& K, double u, double v) {
  return {(u - K.cx) / K.fx, (v - K.cy) / K.fy, 1.0};
}

// Depth (z) where the pixel ray meets the triangle's plane; NaN if parallel.
double plane_depth(const CameraTriangle& c, const Vec3& ray) {
  const double nr = c.n.dot(ray);
  return nr != 0.0 ? c.d / nr : std::nan("");
}

bool inside_inclusive(const CameraTriangle& c, const Vec3& p) {
  for (int k = 0; k < 3; ++k) {
    const Vec3& a = c.p[k];
    const Vec3& b = c.p[(k + 1) % 3];
    if ((b - a).cross(p - a).dot(c.n) < 0.0) return false;
  }
  return true;
}

// Screen-space outline of the triangle clipped at the near plane.
int screen_outline(const CameraTriangle& c, const Pinhole& K, double near_mm, Vec2* out) {
  int n = 0;
  for (int k = 0; k < 3; ++k) {
    const Vec3& a = c.p[k];
    const Vec3& b = c.p[(k + 1) % 3];
    const bool a_in = a.z() >= near_mm, b_in = b.z() >= near_mm;
    if (a_in) out[n++] = K.project(a);
    if (a_in != b_in) {
      const double t = (near_mm - a.z()) / (b.z() - a.z());
      out[n++] = K.project(a + t * (b - a));
    }
  }
  return n;
}

double distance_to_segment(const Vec2& p, const Vec2& a, const Vec2& b) {
  const Vec2 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (p - (a + t * ab)).norm();
}

bool near_outline(const CameraTriangle& c, const Pinhole& K, double near_mm, const Vec2& px,
                  double tol_px) {
  Vec2 poly[4];
  const int n = screen_outline(c, K, near_mm, poly);
  for (int k = 0; k < n; ++k)
    if (distance_to_segment(px, poly[k], poly[(k + 1) % n]) <= tol_px) return true;
  return false;
}

// Pixel rectangle that can contain the triangle's part beyond the near
// plane (false if there is none).
bool candidate_box(const CameraTriangle& c, const Pinhole& K, double near_mm, int* x0, int* y0,
                   int* x1, int* y1) {
  Vec2 poly[4];
  const int n = screen_outline(c, K, near_mm, poly);
  if (n < 3) return false;
  double umin = 1e300, umax = -1e300, vmin = 1e300, vmax = -1e300;
  for (int k = 0; k < n; ++k) {
    umin = std::min(umin, poly[k].x()), umax = std::max(umax, poly[k].x());
    vmin = std::min(vmin, poly[k].y()), vmax = std::max(vmax, poly[k].y());
  }
  *x0 = static_cast<int>(std::clamp(std::floor(umin) - 1, 0.0, K.width - 1.0));
  *y0 = static_cast<int>(std::clamp(std::floor(vmin) - 1, 0.0, K.height - 1.0));
  *x1 = static_cast<int>(std::clamp(std::ceil(umax) + 1, -1.0, K.width - 1.0));
  *y1 = static_cast<int>(std::clamp(std::ceil(vmax) + 1, -1.0, K.height - 1.0));
  return true;
}

}  // namespace

ReferenceRender reference_render(const Mesh& mesh, const SE3& T, const Pinhole& K, double near_mm,
                                 bool cull_backfaces) {
  ReferenceRender r;
  r.width = K.width;
  r.height = K.height;
  r.depth.assign(static_cast<std::size_t>(K.width) * K.height, 0.0);
  r.id.assign(r.depth.size(), -1);
  for (int t = 0; t < mesh.triangle_count(); ++t) {
    const CameraTriangle c = camera_triangle(mesh, T, t);
    if (c.d == 0.0 || (cull_backfaces && c.d > 0.0)) continue;
    int x0, y0, x1, y1;
    if (!candidate_box(c, K, near_mm, &x0, &y0, &x1, &y1)) continue;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Vec3 ray = pixel_ray(K, x, y);
        const double z = plane_depth(c, ray);
        if (!(z >= near_mm) || !inside_inclusive(c, z * ray)) continue;
        const std::size_t i = static_cast<std::size_t>(y) * K.width + x;
        if (r.id[i] < 0 || z < r.depth[i]) {
          r.depth[i] = z;
          r.id[i] = t;
        }
      }
    }
  }
  return r;
}

std::string RasterComparison::summary() const {
  char buf[400];
  std::snprintf(buf, sizeof buf,
                "pixels %ld covered(ref) %ld agree %.5f%% ties %ld boundary %ld unexplained %ld "
                "cracks %ld max_rel_depth_err %.2e",
                pixels, covered_reference, 100.0 * agreement(), depth_ties, on_boundary,
                unexplained, cracks, max_rel_depth_error);
  return buf;
}

RasterComparison compare_with_reference(const MeshRasterizer& r, const Mesh& mesh,
                                        const ReferenceRender& ref) {
  RasterComparison c;
  const auto ids = r.triangle_id();
  const auto depth = r.depth();
  const auto mask = r.mask();
  const Pinhole& K = r.camera();
  const double near_mm = r.config().near_mm, tol_px = 1e-3;
  for (int y = 0; y < ref.height; ++y) {
    for (int x = 0; x < ref.width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * ref.width + x;
      const std::int32_t a = ids(x, y), b = ref.id[i];
      ++c.pixels;
      c.covered_reference += b >= 0;
      const bool ours_covered = mask(x, y) != 0;
      if (ours_covered != (a >= 0) || (a >= 0) != (depth(x, y) > 0)) ++c.unexplained;
      if (a == b) {
        ++c.agree;
        if (a >= 0)
          c.max_rel_depth_error = std::max(
              c.max_rel_depth_error, std::abs(double{depth(x, y)} - ref.depth[i]) / ref.depth[i]);
        continue;
      }
      const Vec2 px(x, y);
      const Vec3 ray = pixel_ray(K, x, y);
      if (a >= 0 && b >= 0) {
        const double za = plane_depth(camera_triangle(mesh, r.T_camera_model(), a), ray);
        if (std::abs(za - ref.depth[i]) <= 1e-4 * ref.depth[i]) {
          ++c.depth_ties;
          c.max_rel_depth_error = std::max(
              c.max_rel_depth_error, std::abs(double{depth(x, y)} - ref.depth[i]) / ref.depth[i]);
          continue;
        }
      }
      const bool boundary = (a >= 0 && near_outline(camera_triangle(mesh, r.T_camera_model(), a), K,
                                                    near_mm, px, tol_px)) ||
                            (b >= 0 && near_outline(camera_triangle(mesh, r.T_camera_model(), b), K,
                                                    near_mm, px, tol_px));
      if (boundary)
        ++c.on_boundary;
      else
        ++c.unexplained;
    }
  }
  for (int y = 1; y + 1 < ref.height; ++y) {
    for (int x = 1; x + 1 < ref.width; ++x) {
      bool interior = true;
      for (int dy = -1; dy <= 1 && interior; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          interior = interior && ref.id[static_cast<std::size_t>(y + dy) * ref.width + x + dx] >= 0;
      if (interior && mask(x, y) == 0) ++c.cracks;
    }
  }
  return c;
}

void orient_towards_origin(Mesh* m) {
  for (int t = 0; t < m->triangle_count(); ++t) {
    const Vec3 p0 = m->vertex(m->tri[3 * t]), p1 = m->vertex(m->tri[3 * t + 1]),
               p2 = m->vertex(m->tri[3 * t + 2]);
    if ((p1 - p0).cross(p2 - p0).dot(p0) > 0) std::swap(m->tri[3 * t + 1], m->tri[3 * t + 2]);
  }
}

namespace {

// The point seen at pixel (u, v) on the plane z = z0 + gx X + gy Y.
void add_on_plane(Mesh* m, const Pinhole& K, double u, double v, double z0, double gx, double gy) {
  const double qx = (u - K.cx) / K.fx, qy = (v - K.cy) / K.fy;
  const double z = z0 / (1.0 - gx * qx - gy * qy);
  m->add_vertex(static_cast<float>(qx * z), static_cast<float>(qy * z), static_cast<float>(z));
}

void add_fan(Mesh* m, const Pinhole& K, double cu, double cv, double radius, int spokes,
             bool pixel_aligned, double z0, double gx, double gy) {
  const int centre = m->vertex_count();
  add_on_plane(m, K, cu, cv, z0, gx, gy);
  for (int k = 0; k < spokes; ++k) {
    const double a = 2 * M_PI * k / spokes + (pixel_aligned ? 0.0 : 0.37);
    double u = cu + radius * std::cos(a), v = cv + radius * std::sin(a);
    if (pixel_aligned)
      u = std::round(u), v = std::round(v);
    else
      u += 0.3 * std::sin(7.0 * k), v += 0.3 * std::cos(5.0 * k);
    add_on_plane(m, K, u, v, z0, gx, gy);
  }
  for (int k = 0; k < spokes; ++k)
    m->add_triangle(centre, centre + 1 + k, centre + 1 + (k + 1) % spokes);
}

}  // namespace

Mesh fan_mesh(const Pinhole& K, bool pixel_aligned) {
  Mesh m;
  const double r = 0.3 * K.height;
  if (pixel_aligned) {
    // Centres and rim on pixel centres: many edges run exactly through
    // pixel centres, where only the fill rule decides.
    add_fan(&m, K, std::floor(0.3 * K.width), std::floor(0.5 * K.height), r, 24, true, 100, 0, 0);
    add_fan(&m, K, std::floor(0.75 * K.width), std::floor(0.5 * K.height), r, 16, true, 100, 0, 0);
  } else {
    add_fan(&m, K, 0.3 * K.width + 0.25, 0.5 * K.height - 0.4, r, 37, false, 100, 0.2, -0.1);
    add_fan(&m, K, 0.75 * K.width - 0.1, 0.5 * K.height + 0.2, r, 61, false, 140, -0.3, 0.3);
  }
  orient_towards_origin(&m);
  return m;
}

Mesh sliver_mesh(const Pinhole& K) {
  Mesh m;
  // A strip of long thin triangles (200 px long, ~4 px wide).
  const int n = 60;
  for (int i = 0; i <= n; ++i) {
    add_on_plane(&m, K, 10 + i * 4.1, 0.2 * K.height + 0.3, 120, 0.0, 0.05);
    add_on_plane(&m, K, 10 + i * 4.1 + 200.7, 0.2 * K.height + 3.9, 120, 0.0, 0.05);
  }
  for (int i = 0; i < n; ++i) {
    m.add_triangle(2 * i, 2 * i + 2, 2 * i + 1);
    m.add_triangle(2 * i + 2, 2 * i + 3, 2 * i + 1);
  }
  // Needles from one apex: 0.7 px wide at the far end, nothing at the apex.
  const int apex = m.vertex_count();
  add_on_plane(&m, K, 0.5 * K.width + 0.13, 0.9 * K.height, 150, 0.1, 0.0);
  for (int i = 0; i <= 40; ++i)
    add_on_plane(&m, K, 0.3 * K.width + i * 0.7, 0.35 * K.height, 150, 0.1, 0.0);
  for (int i = 0; i < 40; ++i) m.add_triangle(apex, apex + 1 + i, apex + 2 + i);
  orient_towards_origin(&m);
  return m;
}

Mesh near_plane_mesh() {
  Mesh m;
  // A floor 12 mm below the eye from 200 mm behind it to 800 mm ahead.
  const int nx = 6, nz = 10;
  for (int j = 0; j <= nz; ++j)
    for (int i = 0; i <= nx; ++i)
      m.add_vertex(-300.0f + 600.0f * i / nx, 12.0f, -200.0f + 1000.0f * j / nz);
  for (int j = 0; j < nz; ++j)
    for (int i = 0; i < nx; ++i) {
      const int a = j * (nx + 1) + i;
      m.add_triangle(a, a + 1, a + nx + 1);
      m.add_triangle(a + 1, a + nx + 2, a + nx + 1);
    }
  // A wall piece through z = 0 and z = near, and one with two vertices behind.
  const int w = m.vertex_count();
  m.add_vertex(-50, -50, -20);
  m.add_vertex(50, -40, 30);
  m.add_vertex(0, 30, 5);
  m.add_triangle(w, w + 1, w + 2);
  m.add_vertex(-80, -30, -40);
  m.add_vertex(60, -20, -10);
  m.add_vertex(10, 20, 60);
  m.add_triangle(w + 3, w + 4, w + 5);
  orient_towards_origin(&m);
  return m;
}

Mesh far_outside_mesh() {
  Mesh m;
  // A backdrop far larger than the guard band.
  m.add_vertex(-1e6f, -1e6f, 500);
  m.add_vertex(1e6f, -1e6f, 500);
  m.add_vertex(1e6f, 1e6f, 500);
  m.add_vertex(-1e6f, 1e6f, 500);
  m.add_triangle(0, 1, 2);
  m.add_triangle(0, 2, 3);
  // A huge tilted triangle in front of it, partly in view.
  m.add_vertex(1e5f, -10, 300);
  m.add_vertex(-1e5f, 0, 200);
  m.add_vertex(0, 1e5f, 400);
  m.add_triangle(4, 5, 6);
  // Triangles entirely outside the view (left, right, above, below).
  const float off[4][2] = {{1e4f, 0}, {-1e4f, 0}, {0, 1e4f}, {0, -1e4f}};
  for (const auto& o : off) {
    const int b = m.vertex_count();
    m.add_vertex(o[0], o[1], 100);
    m.add_vertex(o[0] + 50, o[1], 100);
    m.add_vertex(o[0], o[1] + 50, 100);
    m.add_triangle(b, b + 1, b + 2);
  }
  orient_towards_origin(&m);
  return m;
}

Mesh sphere_mesh(const Vec3& c, double radius, int rings, int segments) {
  Mesh m;
  m.add_vertex(float(c.x()), float(c.y()), float(c.z() + radius));
  for (int i = 1; i < rings; ++i) {
    const double th = M_PI * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double ph = 2 * M_PI * j / segments;
      m.add_vertex(float(c.x() + radius * std::sin(th) * std::cos(ph)),
                   float(c.y() + radius * std::sin(th) * std::sin(ph)),
                   float(c.z() + radius * std::cos(th)));
    }
  }
  const int south = m.vertex_count();
  m.add_vertex(float(c.x()), float(c.y()), float(c.z() - radius));
  auto ring = [&](int i, int j) { return 1 + (i - 1) * segments + (j % segments); };
  for (int j = 0; j < segments; ++j) {
    m.add_triangle(0, ring(1, j), ring(1, j + 1));
    m.add_triangle(south, ring(rings - 1, j + 1), ring(rings - 1, j));
    for (int i = 1; i + 1 < rings; ++i) {
      m.add_triangle(ring(i, j), ring(i + 1, j), ring(i + 1, j + 1));
      m.add_triangle(ring(i, j), ring(i + 1, j + 1), ring(i, j + 1));
    }
  }
  // Make every face point outwards.
  for (int t = 0; t < m.triangle_count(); ++t) {
    const Vec3 p0 = m.vertex(m.tri[3 * t]), p1 = m.vertex(m.tri[3 * t + 1]),
               p2 = m.vertex(m.tri[3 * t + 2]);
    if ((p1 - p0).cross(p2 - p0).dot((p0 + p1 + p2) / 3 - c) < 0)
      std::swap(m.tri[3 * t + 1], m.tri[3 * t + 2]);
  }
  return m;
}

}  // namespace st::test
