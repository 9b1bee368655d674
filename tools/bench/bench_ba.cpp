// Stage "ba": window bundle adjustment (core/mapping/bundle_adjustment.h) on a
// simulated window of the CT liver (tests/support/ba_window.h): 8 keyframes
// (+2 older fixed ones), ~1000 points, 1280x720 pinhole fx = 1000, poses
// perturbed by 1 deg / 2 mm and points by 1 mm, default options (10
// iterations, w_shape 100), one thread. Rows: solve time with the shape
// residual and with w_shape = 0; allocations per solve and accuracy in the
// note; the closest-point query D(f) for points within 2 mm of the surface.
#include <time.h>

#include <algorithm>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "bench.h"
#include "bench_liver.h"
#include "core/mapping/bundle_adjustment.h"
#include "core/mesh/closest_point.h"
#include "platform/alloc_counter.h"
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

Row bench_window(const Options& opt, const Mesh& liver, double w_shape, int points, int max_obs_per_point = 0) {
  test::BaWindowSpec spec;
  spec.points = points;
  const Pinhole K = test::bench_pinhole();
  test::BaWindow w = test::make_ba_window(liver, K, spec);
  BundleAdjusterOptions o;
  o.w_shape = w_shape;
  o.max_observations_per_point = max_obs_per_point;
  BundleAdjuster ba;
  Row row;
  if (!ba.configure(o, liver, K, w.job.point_capacity(), w.job.observation_capacity()).ok()) return row;
  const BaJob pristine = w.job;
  const int n = opt.iterations > 0 ? opt.iterations : 30;
  std::uint64_t max_allocs = 0;
  std::vector<double> cpu_ms;
  double iters = 0, err_before = mean_point_error(w), err_after = 0, surface = 0;
  for (int i = 0; i < n; ++i) {
    w.job = pristine;
    ba.forget_planes();  // a fresh window: every plane queried (the tracker reuses most)
    const std::uint64_t a0 = platform::thread_allocation_count();
    const double t0 = now_ms(), c0 = thread_cpu_ms();
    ba.solve(&w.job);
    row.samples_ms.push_back(now_ms() - t0);
    cpu_ms.push_back(thread_cpu_ms() - c0);
    max_allocs = std::max(max_allocs, platform::thread_allocation_count() - a0);
    iters += w.job.summary.iterations;
    err_after = mean_point_error(w);
    surface = ba.mean_surface_distance(w.job);  // all points, exact, outside the timing
  }
  row.name = "ba window 8 kf " + std::to_string(w.job.point_count) + " pts w_shape " + std::to_string(static_cast<int>(w_shape));
  if (max_obs_per_point > 0) row.name += " <= " + std::to_string(max_obs_per_point) + " obs/pt";
  char note[260];
  std::snprintf(note, sizeof note,
                "cpu median %.2f min %.2f ms; %d obs; %.1f iterations; allocations/solve %llu; point error %.2f -> %.3f mm; to surface %.3f mm",
                median(cpu_ms), *std::min_element(cpu_ms.begin(), cpu_ms.end()), w.job.summary.observations, iters / n, static_cast<unsigned long long>(max_allocs), err_before,
                err_after, surface);
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
