// Stage "ba": window bundle adjustment (core/mapping/bundle_adjustment.h) on a
// simulated window of the CT liver (tests/support/ba_window.h): 8 keyframes
// (+2 older fixed ones), ~1000 points, 1280x720 pinhole fx = 1000, poses
// perturbed by 1 deg / 2 mm and points by 1 mm, default options (10
// iterations, w_shape 100), one thread. Rows: solve time of the Schur
// solver with the Ceres form as the baseline (same run, alternating), with
// the shape residual and with w_shape = 0; allocations per solve, accuracy
// and the two solutions' largest differences in the note; the closest-point
// query D(f) for points within 2 mm of the surface.
#include <time.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "bench.h"
#include "bench_liver.h"
#include "core/mapping/bundle_adjustment.h"
#include "core/mapping_ceres/ceres_form.h"
#include "core/mesh/closest_point.h"
#include "platform/alloc_counter.h"
#include "platform/clock.h"
#include "tests/support/ba_window.h"

namespace st::bench {
namespace {

// CPU time of this thread (ms): the machine is shared, so wall time alone
// mixes in the other processes' load.
double thread_cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

double mean_point_error(const test::BaWindow& w) {
  double e = 0;
  for (int i = 0; i < w.job.point_count; ++i) e += (w.job.point(i) - w.p_true[static_cast<std::size_t>(i)]).norm();
  return e / w.job.point_count;
}

// One form's solves of the same window: times, allocations, accuracy.
struct FormRun {
  std::vector<double> wall_ms, cpu_ms;
  std::uint64_t max_allocs = 0;
  double iterations = 0, point_error = 0, surface = 0;
  BaJob solved;
};

void solve_once(BundleAdjuster& ba, const BaJob& pristine, test::BaWindow& w, FormRun* run) {
  w.job = pristine;
  ba.forget_planes();  // a fresh window: every plane queried (the tracker reuses most)
  const std::uint64_t a0 = platform::thread_allocation_count();
  const double t0 = now_ms(), c0 = thread_cpu_ms();
  ba.solve(&w.job);
  const double wall = now_ms() - t0, cpu = thread_cpu_ms() - c0;
  run->max_allocs = std::max(run->max_allocs, platform::thread_allocation_count() - a0);
  run->wall_ms.push_back(wall);  // (after the count: the vectors grow)
  run->cpu_ms.push_back(cpu);
  run->iterations += w.job.summary.iterations;
  run->point_error = mean_point_error(w);
  run->surface = ba.mean_surface_distance(w.job);  // all points, exact, outside the timing
  run->solved = w.job;
}

// Largest differences between two solutions of one window: rotation (deg),
// camera centre (mm), point (mm).
std::string agreement(const BaJob& a, const BaJob& b) {
  double rot = 0, centre = 0, point = 0;
  for (int k = 0; k < a.keyframe_count; ++k) {
    rot = std::max(rot, pose_delta(a.pose(k), b.pose(k)).angle_deg);
    centre = std::max(centre, (a.pose(k).inverse().translation() - b.pose(k).inverse().translation()).norm());
  }
  for (int i = 0; i < a.point_count; ++i) point = std::max(point, (a.point(i) - b.point(i)).norm());
  char s[120];
  std::snprintf(s, sizeof s, "vs ceres max %.1e deg %.1e mm, points %.1e mm", rot, centre, point);
  return s;
}

// The Schur solver (the product path) with the Ceres form as the baseline,
// alternating on the same window so that both see the same machine load.
Row bench_window(const Options& opt, const Mesh& liver, double w_shape, int points, int max_obs_per_point = 0) {
  test::BaWindowSpec spec;
  spec.points = points;
  const Pinhole K = test::bench_pinhole();
  test::BaWindow w = test::make_ba_window(liver, K, spec);
  BundleAdjusterOptions o;
  o.w_shape = w_shape;
  o.max_observations_per_point = max_obs_per_point;
  o.now_ns = platform::monotonic_ns;
  BundleAdjuster schur, ceres;
  Row row;
  const int nk = w.job.keyframe_capacity(), np = w.job.point_capacity(), no = w.job.observation_capacity();
  if (!schur.configure(o, liver, K, nk, np, no).ok() || !configure_ceres_form(&ceres, o, liver, K, nk, np, no).ok())
    return row;
  const BaJob pristine = w.job;
  const double err_before = mean_point_error(w);
  const int n = opt.iterations > 0 ? opt.iterations : 30;
  FormRun fs, fc;
  for (int i = 0; i < n; ++i) {
    solve_once(ceres, pristine, w, &fc);
    solve_once(schur, pristine, w, &fs);
  }
  row.samples_ms = fs.wall_ms;
  row.baseline = "ceres";
  row.baseline_ms = fc.wall_ms;
  row.name = "ba window 8 kf " + std::to_string(w.job.point_count) + " pts w_shape " + std::to_string(static_cast<int>(w_shape));
  if (max_obs_per_point > 0) row.name += " <= " + std::to_string(max_obs_per_point) + " obs/pt";
  char note[480];
  std::snprintf(note, sizeof note,
                "schur: cpu median %.2f ms, %.1f iterations, allocations/solve %llu, point error %.2f -> %.3f mm, "
                "to surface %.3f mm; ceres: cpu median %.2f ms, %.1f iterations, allocations/solve %llu, point error "
                "-> %.3f mm, to surface %.3f mm; %d obs; %s",
                median(fs.cpu_ms), fs.iterations / n, static_cast<unsigned long long>(fs.max_allocs), err_before,
                fs.point_error, fs.surface, median(fc.cpu_ms), fc.iterations / n,
                static_cast<unsigned long long>(fc.max_allocs), fc.point_error, fc.surface,
                fs.solved.summary.observations, agreement(fs.solved, fc.solved).c_str());
  row.note = note;
  return row;
}

Row bench_closest(const Options& opt, const Mesh& liver) {
  ClosestPointIndex index;
  Row row;
  if (!index.configure(liver).ok()) return row;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<Vec3> q;
  for (int i = 0; i < 10000; ++i) {
    const int v = static_cast<int>(u(rng) * (liver.vertex_count() - 1));
    const double reach = 2.0 * u(rng);
    q.push_back(liver.vertex(v) + reach * test::random_unit(rng));
  }
  const int n = opt.iterations > 0 ? opt.iterations : 30;
  double sink = 0;
  for (int i = 0; i < n; ++i) {
    const double t0 = now_ms();
    SurfacePoint s;
    for (const Vec3& p : q)
      if (index.closest(p, &s)) sink += s.distance_mm;
    row.samples_ms.push_back(now_ms() - t0);
  }
  row.name = "closest point 10k queries (<= 2 mm off)";
  char note[160];
  std::snprintf(note, sizeof note, "BVH %d nodes depth %d, %zu KiB for %d triangles (mean dist %.2f mm)",
                index.node_count(), index.depth(), index.memory_bytes() / 1024, index.triangle_count(),
                sink / (static_cast<double>(n) * 10000.0));
  row.note = note;
  return row;
}

int run(const Options& opt) {
  auto mesh = load_bench_liver(opt);
  if (!mesh.ok()) {
    std::fprintf(stderr, "ba: %s\n", mesh.message().c_str());
    return 1;
  }
  report(opt, bench_window(opt, mesh.value(), 100.0, 1000));
  report(opt, bench_window(opt, mesh.value(), 0.0, 1000));
  report(opt, bench_window(opt, mesh.value(), 100.0, 1000, 6));
  report(opt, bench_closest(opt, mesh.value()));
  return 0;
}

}  // namespace

SCOPETRACK_BENCH_STAGE("ba", "window BA (8 keyframes, ~1000 points, w_shape 100 / 0), closest-point queries", run);

}  // namespace st::bench
