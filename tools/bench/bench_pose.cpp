// Stage "pose": the per-frame pose LM (PoseSolver), the relocalisation
// RANSAC (PnpRansac over P3P) and the bare P3P solver on synthetic
// laparoscopic geometry: a smooth organ-like surface 60-140 mm in front of a
// 1280x720 camera with fx = 1000, level-0 pixel noise 1 px scaled by
// 1.2^octave (octaves 0-7), gross outliers displaced 20-300 px.
// `scopetrack-bench pose variants` adds rows for option trade-offs.
// No baseline: calib3d is not linked into the bench (the tests print
// cv::solvePnPRansac next to ours).
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "bench.h"
#include "core/pose/correspondences.h"
#include "core/pose/p3p.h"
#include "core/pose/pnp_ransac.h"
#include "core/pose/pose_solver.h"
#include "tests/support/draws.h"

namespace st::bench {
namespace {

struct Scene {
  Pinhole K{1000.0, 1000.0, 639.5, 359.5, 1280, 720};
  SE3 T_camera_model;
  std::vector<Vec3> p_model;
  std::vector<Vec2> px;
  std::vector<double> info;
  Correspondences view() const {
    return {p_model.data(), px.data(), info.data(), static_cast<int>(p_model.size())};
  }
};

Scene make_scene(int n, double outlier_ratio, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0), s(-1.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  Scene sc;
  Vec6 xi;
  xi << 2 * s(rng), 2 * s(rng), 2 * s(rng), 200 * s(rng), 200 * s(rng), 200 * s(rng);
  sc.T_camera_model = SE3::exp(xi);
  const SE3 T_model_camera = sc.T_camera_model.inverse();
  const double tilt_x = 0.4 * s(rng), tilt_y = 0.4 * s(rng);
  for (int i = 0; i < n; ++i) {
    const Vec2 unit = test::draw_vec2(u, rng);
    const Vec2 px(8 + unit.x() * 1263, 8 + unit.y() * 703);
    const double xn = (px.x() - sc.K.cx) / sc.K.fx, yn = (px.y() - sc.K.cy) / sc.K.fy;
    // Smooth tilted, bulging surface: depth 60-140 mm.
    const double z = 100 + 60 * (tilt_x * xn + tilt_y * yn) - 25 * (xn * xn + yn * yn) +
                     5 * std::sin(6 * xn) * std::cos(5 * yn);
    const int octave = static_cast<int>(u(rng) * 8) % 8;
    const double sigma = std::pow(1.2, octave);
    sc.p_model.push_back(T_model_camera * Vec3(xn * z, yn * z, z));
    sc.px.push_back(px + sigma * test::draw_vec2(g, rng));
    sc.info.push_back(octave_information(octave));
  }
  const int n_out = static_cast<int>(std::lround(outlier_ratio * n));
  for (int k = 0; k < n_out; ++k) {
    const double a = u(rng) * 2 * M_PI, d = 20 + 280 * u(rng);
    sc.px[k] += d * Vec2(std::cos(a), std::sin(a));
  }
  return sc;
}

double centre_error_mm(const SE3& a, const SE3& b) {
  return (a.inverse().translation() - b.inverse().translation()).norm();
}

// Pose LM from a constant-velocity-like prediction error (2 deg, 5 mm).
Row bench_lm(const Options& opt, int inliers, double outlier_ratio,
             const PoseSolverOptions& po = {}, const std::string& label = "") {
  const int n = static_cast<int>(std::lround(inliers / (1.0 - outlier_ratio)));
  std::vector<Scene> scenes;
  for (std::uint32_t k = 0; k < 10; ++k) scenes.push_back(make_scene(n, outlier_ratio, 100 + k));
  PoseSolver solver;
  if (!solver.configure(n, po).ok()) return {};
  Row row;
  row.name = "pose LM " + std::to_string(n) + " corr (" + std::to_string(inliers) + " inl)" + label;
  std::mt19937 rng(5);
  std::normal_distribution<double> g(0.0, 1.0);
  const int iterations = opt.iterations > 0 ? opt.iterations : 1000;
  double iters = 0, rounds = 0;
  std::vector<double> err;
  for (int it = 0; it < iterations; ++it) {
    const Scene& sc = scenes[static_cast<std::size_t>(it) % scenes.size()];
    // Filled by halves: GCC 12 reports a false -Warray-bounds inside Eigen's
    // AVX comma initialiser (host-avx2 board).
    Vec6 xi;
    xi.head<3>() = test::draw_vec3(g, rng).normalized() * (2.0 * M_PI / 180.0);
    xi.tail<3>() = test::draw_vec3(g, rng).normalized() * 5.0;
    SE3 T = SE3::exp(xi) * sc.T_camera_model;
    PoseSolverSummary s;
    const double t0 = now_ms();
    solver.solve(sc.view(), sc.K, &T, &s);
    row.samples_ms.push_back(now_ms() - t0);
    iters += s.iterations;
    rounds += s.rounds;
    err.push_back(centre_error_mm(T, sc.T_camera_model));
  }
  char note[160];
  std::snprintf(note, sizeof note,
                "mean LM iterations %.1f, rounds %.2f; median camera-centre error %.3f mm",
                iters / iterations, rounds / iterations, median(err));
  row.note = note;
  return row;
}

Row bench_ransac(const Options& opt, int n, double outlier_ratio) {
  std::vector<Scene> scenes;
  for (std::uint32_t k = 0; k < 10; ++k) scenes.push_back(make_scene(n, outlier_ratio, 200 + k));
  PnpRansac ransac;
  if (!ransac.configure(n).ok()) return {};
  Row row;
  row.name = "pnp ransac " + std::to_string(n) + " corr, " +
             std::to_string(static_cast<int>(outlier_ratio * 100)) + "% out";
  const int iterations = opt.iterations > 0 ? opt.iterations : 200;
  double samples = 0;
  std::vector<double> err;
  for (int it = 0; it < iterations; ++it) {
    const Scene& sc = scenes[static_cast<std::size_t>(it) % scenes.size()];
    SE3 T;
    PnpRansacSummary s;
    const double t0 = now_ms();
    ransac.solve(sc.view(), sc.K, &T, &s);
    row.samples_ms.push_back(now_ms() - t0);
    samples += s.iterations;
    err.push_back(centre_error_mm(T, sc.T_camera_model));
  }
  char note[160];
  std::snprintf(note, sizeof note, "mean RANSAC samples %.1f; median camera-centre error %.3f mm",
                samples / iterations, median(err));
  row.note = note;
  return row;
}

Row bench_p3p(const Options& opt) {
  const Scene sc = make_scene(3000, 0.0, 300);
  std::vector<std::array<Vec3, 3>> bearings, points;
  for (int i = 0; i + 2 < 3000; i += 3) {
    std::array<Vec3, 3> b, p;
    for (int k = 0; k < 3; ++k) {
      const Vec2& px = sc.px[i + k];
      b[k] = Vec3((px.x() - sc.K.cx) / sc.K.fx, (px.y() - sc.K.cy) / sc.K.fy, 1.0);
      p[k] = sc.p_model[i + k];
    }
    bearings.push_back(b);
    points.push_back(p);
  }
  Row row;
  row.name = "p3p x1000";
  const int iterations = opt.iterations > 0 ? opt.iterations : 200;
  long solutions = 0;
  for (int it = 0; it < iterations; ++it) {
    const double t0 = now_ms();
    for (std::size_t k = 0; k < 1000; ++k) {
      P3PSolutions s;
      solutions += solve_p3p(bearings[k], points[k], &s);
    }
    row.samples_ms.push_back(now_ms() - t0);
  }
  char note[120];
  std::snprintf(note, sizeof note, "1000 minimal solves per sample; mean %.2f solutions each",
                static_cast<double>(solutions) / (1000.0 * iterations));
  row.note = note;
  return row;
}

int run(const Options& opt) {
  info(opt, "pose: synthetic surface 60-140 mm, fx 1000, 1280x720, 1 px * 1.2^octave noise");
  report(opt, bench_lm(opt, 300, 0.2));
  report(opt, bench_lm(opt, 1200, 0.2));
  if (!opt.args.empty() && opt.args[0] == "variants") {  // option trade-offs for the tracker
    PoseSolverOptions tight;
    tight.function_tolerance = 1e-8;
    report(opt, bench_lm(opt, 1200, 0.2, tight, " ftol 1e-8"));
    for (int rounds : {3, 2}) {
      PoseSolverOptions o;
      o.rounds = rounds;
      report(opt, bench_lm(opt, 1200, 0.2, o, " rounds " + std::to_string(rounds)));
    }
  }
  report(opt, bench_ransac(opt, 500, 0.5));
  report(opt, bench_p3p(opt));
  return 0;
}

}  // namespace

SCOPETRACK_BENCH_STAGE(
    "pose", "pose LM (300 / 1200 inliers + 20% outliers), PnP RANSAC (500, 50% out), P3P", run);

}  // namespace st::bench
