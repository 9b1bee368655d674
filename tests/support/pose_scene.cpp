#include "support/pose_scene.h"

#include <array>
#include <cmath>
#include <cstring>
#include <random>
#include <string>

#include "support/support.h"
#include "tests/support/draws.h"

namespace st::test {

LiverMesh load_liver_mesh() {
  LiverMesh mesh;
  const std::string bytes = read_file_bytes(shared_data("liver/liver.ply"));
  const std::size_t header_end = bytes.find("end_header\n");
  if (header_end == std::string::npos) return mesh;
  int nv = 0, nf = 0;
  const std::size_t v_at = bytes.find("element vertex ");
  const std::size_t f_at = bytes.find("element face ");
  if (v_at == std::string::npos || f_at == std::string::npos) return mesh;
  nv = std::stoi(bytes.substr(v_at + 15, 12));
  nf = std::stoi(bytes.substr(f_at + 13, 12));
  std::size_t at = header_end + 11;
  if (bytes.size() < at + static_cast<std::size_t>(nv) * 12) return mesh;
  for (int i = 0; i < nv; ++i, at += 12) {
    float xyz[3];
    std::memcpy(xyz, bytes.data() + at, 12);
    mesh.vertices.emplace_back(xyz[0], xyz[1], xyz[2]);
  }
  for (int i = 0; i < nf && at + 13 <= bytes.size(); ++i, at += 13) {
    if (static_cast<unsigned char>(bytes[at]) != 3) return {};
    std::array<int, 3> tri;
    std::memcpy(tri.data(), bytes.data() + at + 1, 12);
    mesh.triangles.push_back(tri);
  }
  return mesh;
}

namespace {

const LiverMesh& liver() {
  static const LiverMesh mesh = load_liver_mesh();
  return mesh;
}

Vec3 triangle_normal(const LiverMesh& m, int t) {
  const auto& tri = m.triangles[t];
  const Vec3 n =
      (m.vertices[tri[1]] - m.vertices[tri[0]]).cross(m.vertices[tri[2]] - m.vertices[tri[0]]);
  return n.normalized();
}

// Camera at distance d from surface point q, looking at q from a direction
// within ~30 deg of the normal n, with a random roll.
SE3 look_at(const Vec3& q, const Vec3& n, double d, std::mt19937& rng) {
  const Vec3 dir = (n + 0.5 * random_unit(rng)).normalized();
  const Vec3 centre = q + d * dir;
  const Vec3 z = (q - centre).normalized();
  Vec3 x = z.unitOrthogonal();
  const double roll = std::uniform_real_distribution<double>(-M_PI, M_PI)(rng);
  x = Eigen::AngleAxisd(roll, z) * x;
  Mat3 R_model_camera;
  R_model_camera << x, z.cross(x), z;
  return SE3(R_model_camera, centre).inverse();
}

bool sees(const PoseScene& s, const Vec3& p_model, const Vec3& n_model) {
  const Vec3 p = s.T_camera_model * p_model;
  const Vec3 centre_model = s.T_camera_model.inverse().translation();
  if (n_model.dot(centre_model - p_model) <= 0 || p.z() < 50 || p.z() > 150) return false;
  return s.K.in_image(s.K.project(p), 8.0);
}

}  // namespace

PoseScene make_liver_scene(const PoseSceneOptions& opt) {
  const LiverMesh& m = liver();
  PoseScene s;
  if (m.triangles.empty()) return s;
  std::mt19937 rng(opt.seed);
  std::uniform_int_distribution<int> pick_tri(0, static_cast<int>(m.triangles.size()) - 1);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::vector<int> candidates;
  while (candidates.size() < 50) {  // retry until the view holds a surface patch
    const int t0 = pick_tri(rng);
    const auto& tri = m.triangles[t0];
    const Vec3 q = (m.vertices[tri[0]] + m.vertices[tri[1]] + m.vertices[tri[2]]) / 3.0;
    s.T_camera_model = look_at(q, triangle_normal(m, t0), opt.distance_mm, rng);
    candidates.clear();
    for (int t = 0; t < static_cast<int>(m.triangles.size()); ++t) {
      const auto& tr = m.triangles[t];
      if (sees(s, (m.vertices[tr[0]] + m.vertices[tr[1]] + m.vertices[tr[2]]) / 3.0,
               triangle_normal(m, t)))
        candidates.push_back(t);
    }
  }
  std::uniform_int_distribution<int> pick(0, static_cast<int>(candidates.size()) - 1);
  std::uniform_int_distribution<int> pick_octave(0, opt.max_octave);
  std::normal_distribution<double> noise(0.0, 1.0);
  while (static_cast<int>(s.p_model.size()) < opt.num_points) {
    const auto& tr = m.triangles[candidates[pick(rng)]];
    double a = u01(rng), b = u01(rng);
    if (a + b > 1) a = 1 - a, b = 1 - b;
    const Vec3 p = m.vertices[tr[0]] + a * (m.vertices[tr[1]] - m.vertices[tr[0]]) +
                   b * (m.vertices[tr[2]] - m.vertices[tr[0]]);
    const Vec2 px = s.K.project(s.T_camera_model * p);
    if (!s.K.in_image(px, 2.0)) continue;
    const int oct = pick_octave(rng);
    const double sigma = std::pow(1.2, oct) * opt.noise_px;
    s.p_model.push_back(p);
    s.px_ideal.push_back(px + sigma * draw_vec2(noise, rng));
    s.octave.push_back(oct);
    s.information.push_back(octave_information(oct));
    s.is_outlier.push_back(0);
  }
  // Gross outliers: the observation moved 20-300 px in a random direction.
  const int n_out = static_cast<int>(std::lround(opt.outlier_ratio * opt.num_points));
  for (int k = 0; k < n_out; ++k) {
    const double angle = u01(rng) * 2 * M_PI, dist = 20 + 280 * u01(rng);
    s.px_ideal[k] += dist * Vec2(std::cos(angle), std::sin(angle));
    s.is_outlier[k] = 1;
  }
  return s;
}

SE3 perturb(const SE3& T, double rotation_deg, double translation_mm, std::uint32_t seed) {
  std::mt19937 rng(seed);
  Vec6 xi;
  xi.head<3>() = random_unit(rng) * rotation_deg * M_PI / 180.0;
  xi.tail<3>() = random_unit(rng) * translation_mm;
  return SE3::exp(xi) * T;
}

double vertex_reprojection_px(const Mesh& mesh, const Pinhole& K, const SE3& T, const SE3& truth, int stride,
                              int* count) {
  double sum = 0;
  int n = 0;
  for (int i = 0; i < mesh.vertex_count(); i += stride) {
    const Vec3 pt = truth * mesh.vertex(i), pe = T * mesh.vertex(i);
    if (pt.z() < 1.0 || pe.z() < 1.0) continue;
    const Vec2 a = K.project(pt);
    if (!K.in_image(a)) continue;
    sum += (K.project(pe) - a).norm();
    ++n;
  }
  if (count) *count = n;
  return n > 0 ? sum / n : 0.0;
}

}  // namespace st::test
