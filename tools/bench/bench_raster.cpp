// scopetrack-bench raster: mask + depth + triangle id of the CT liver filling
// most of a 1280x720 view, against what most people would write instead
// (cv::fillConvexPoly of every projected front-facing triangle into a mask,
// no depth, no ids), timed in the same run.
#include <cstdio>
#include <cstdlib>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "bench.h"
#include "bench_liver.h"
#include "core/formats/text_scan.h"
#include "core/image/image.h"
#include "core/raster/rasterizer.h"
#include "tests/support/raster_scene.h"

namespace st::bench {
namespace {

constexpr double kTargetCoverage = 0.6;  // "filling most of the view"

// The bench view (bench_liver.h) and the share of the image the organ
// covers there (setup, untimed).
SE3 bench_pose(const Mesh& liver, double* coverage) {
  const SE3 T = liver_view_filling(liver, kTargetCoverage);
  MeshRasterizer r;
  RasterConfig cfg;
  cfg.width = 1280;
  cfg.height = 720;
  cfg.downscale = 4;
  if (!r.configure(liver, cfg).ok()) return T;
  r.render(T, test::bench_pinhole());
  *coverage = double(r.covered_pixels()) / (320.0 * 180.0);
  return T;
}

std::vector<double> time_ours(const Mesh& liver, const SE3& T, int downscale, bool simd, int n,
                              RasterStats* stats, double* coverage, bool allow_avx512 = true) {
  MeshRasterizer r;
  RasterConfig cfg;
  cfg.width = 1280;
  cfg.height = 720;
  cfg.downscale = downscale;
  cfg.use_simd = simd;
  cfg.allow_avx512 = allow_avx512;
  std::vector<double> ms;
  if (!r.configure(liver, cfg).ok()) return ms;
  const Pinhole K = test::bench_pinhole();
  for (int i = 0; i < 10; ++i) r.render(T, K);
  ms.reserve(n);
  for (int i = 0; i < n; ++i) {
    const double t0 = now_ms();
    r.render(T, K);
    ms.push_back(now_ms() - t0);
  }
  *stats = r.stats();
  *coverage = double(r.covered_pixels()) / (double(r.mask().width) * r.mask().height);
  return ms;
}

// The usual alternative: project, clear, fillConvexPoly each front face.
void fill_convex_poly_mask(const Mesh& m, const SE3& T, const Pinhole& K, cv::Mat* mask,
                           std::vector<cv::Point>* px) {
  const Eigen::Matrix3f R = T.rotation().cast<float>();
  const Eigen::Vector3f t = T.translation().cast<float>();
  const float fx = float(K.fx), fy = float(K.fy), cx = float(K.cx), cy = float(K.cy);
  for (int i = 0; i < m.vertex_count(); ++i) {
    const Eigen::Vector3f p = R * Eigen::Vector3f(m.x[i], m.y[i], m.z[i]) + t;
    (*px)[i] = cv::Point(cvRound(fx * p.x() / p.z() + cx), cvRound(fy * p.y() / p.z() + cy));
  }
  mask->setTo(0);
  for (int f = 0; f < m.triangle_count(); ++f) {
    const cv::Point tri[3] = {(*px)[m.tri[3 * f]], (*px)[m.tri[3 * f + 1]],
                              (*px)[m.tri[3 * f + 2]]};
    const long area = long(tri[1].x - tri[0].x) * (tri[2].y - tri[0].y) -
                      long(tri[1].y - tri[0].y) * (tri[2].x - tri[0].x);
    if (area < 0) cv::fillConvexPoly(*mask, tri, 3, cv::Scalar(255));  // faces the camera
  }
}

std::vector<double> time_baseline(const Mesh& m, const SE3& T, int n, double* coverage) {
  const Pinhole K = test::bench_pinhole();
  cv::Mat mask(720, 1280, CV_8U);
  std::vector<cv::Point> px(m.vertex_count());
  for (int i = 0; i < 5; ++i) fill_convex_poly_mask(m, T, K, &mask, &px);
  std::vector<double> ms;
  for (int i = 0; i < n; ++i) {
    const double t0 = now_ms();
    fill_convex_poly_mask(m, T, K, &mask, &px);
    ms.push_back(now_ms() - t0);
  }
  *coverage = cv::countNonZero(mask) / (1280.0 * 720.0);
  return ms;
}

// Ours at full size and the baseline, one after the other in every
// iteration. Back to back (the row above), each finds its buffers warm in
// the cache; in the tracker the render runs between other stages and finds
// them cold, as here. Load that comes and goes on a shared machine also
// weighs on both alike, so their ratio holds where the figures drift.
void time_interleaved(const Mesh& m, const SE3& T, int n, Row* row) {
  const Pinhole K = test::bench_pinhole();
  MeshRasterizer r;
  RasterConfig cfg;
  cfg.width = 1280;
  cfg.height = 720;
  if (!r.configure(m, cfg).ok()) return;
  cv::Mat mask(720, 1280, CV_8U);
  std::vector<cv::Point> px(m.vertex_count());
  for (int i = 0; i < 10; ++i) {
    r.render(T, K);
    fill_convex_poly_mask(m, T, K, &mask, &px);
  }
  row->samples_ms.reserve(n);
  row->baseline_ms.reserve(n);
  for (int i = 0; i < n; ++i) {
    double t0 = now_ms();
    r.render(T, K);
    row->samples_ms.push_back(now_ms() - t0);
    t0 = now_ms();
    fill_convex_poly_mask(m, T, K, &mask, &px);
    row->baseline_ms.push_back(now_ms() - t0);
  }
}

std::string describe(const RasterStats& s, double coverage) {
  char buf[200];
  std::snprintf(buf, sizeof buf, "coverage %.1f%%, %d triangles drawn, %lld fragments",
                100.0 * coverage, s.triangles_drawn, static_cast<long long>(s.fragments));
  return buf;
}

// The tracker's per-frame helpers on the full-resolution render.
void report_helpers(const Options& opt, const Mesh& liver, const SE3& T, int n) {
  MeshRasterizer r;
  RasterConfig cfg;
  cfg.width = 1280;
  cfg.height = 720;
  if (!r.configure(liver, cfg).ok()) return;
  r.render(T, test::bench_pinhole());
  Image<std::uint8_t> eroded(1280, 720);
  std::vector<std::int32_t> visible(liver.triangle_count());
  Row morph, vis;
  morph.name = "raster morph_mask(-3) 1280x720";
  vis.name = "raster visible_triangles 1280x720";
  int count = 0;
  for (int i = 0; i < n; ++i) {
    double t0 = now_ms();
    r.morph_mask(-3, eroded.view());
    morph.samples_ms.push_back(now_ms() - t0);
    t0 = now_ms();
    count = r.visible_triangles(visible.data(), static_cast<int>(visible.size()));
    vis.samples_ms.push_back(now_ms() - t0);
  }
  vis.note = std::to_string(count) + " visible triangles";
  report(opt, morph);
  report(opt, vis);
}

int run(const Options& opt) {
  auto mesh = load_bench_liver(opt);
  if (!mesh.ok()) {
    std::fprintf(stderr, "raster: %s\n", mesh.message().c_str());
    return 1;
  }
  const Mesh& liver = mesh.value();
  const int n = opt.iterations > 0 ? opt.iterations : 300;
  double coverage = 0, base_coverage = 0;
  const SE3 T = bench_pose(liver, &coverage);
  RasterStats stats;
  const auto report_downscaled = [&](int ds) {
    Row r;
    r.name = "raster 1/" + std::to_string(ds) + " mask+depth+id";
    r.samples_ms = time_ours(liver, T, ds, true, n, &stats, &coverage);
    r.note = describe(stats, coverage);
    report(opt, r);
  };
  // "raster only DS": just our render at 1/DS (for profilers), no baseline.
  if (opt.args.size() == 2 && opt.args[0] == "only") {
    long long ds = 0;
    if (!parse_int64_in(opt.args[1], 1, 4, &ds) || ds == 3) {
      std::fprintf(stderr, "bench raster: only takes a downscale of 1, 2 or 4\n");
      return 2;
    }
    report_downscaled(static_cast<int>(ds));
    return 0;
  }
  Row row;
  row.name = "raster 1280x720 mask+depth+id";
  row.samples_ms = time_ours(liver, T, 1, true, n, &stats, &coverage);
  row.baseline = "cv::fillConvexPoly mask only";
  row.baseline_ms = time_baseline(liver, T, n, &base_coverage);
  row.note = describe(stats, coverage) + "; baseline coverage " +
             std::to_string(int(100.0 * base_coverage + 0.5)) + "%" +
             (MeshRasterizer::avx512_available() ? "; AVX-512 kernels (chosen at run time)"
              : MeshRasterizer::simd_available() ? "; SIMD kernels"
                                                 : "; portable kernels");
  report(opt, row);
  Row cold;
  cold.name = "raster 1280x720 interleaved";
  cold.baseline = "cv::fillConvexPoly mask only";
  time_interleaved(liver, T, n, &cold);
  cold.note = "ours and the baseline alternate: buffers cold, as between the tracker's stages";
  report(opt, cold);
  if (MeshRasterizer::avx512_available()) {
    // The kernels a CPU without AVX-512 runs (SSE2 here), for comparison.
    Row sse;
    sse.name = "raster 1280x720 SSE2 kernels";
    sse.samples_ms = time_ours(liver, T, 1, true, n, &stats, &coverage, false);
    report(opt, sse);
  }
  Row portable;
  portable.name = "raster 1280x720 portable kernel";
  portable.samples_ms = time_ours(liver, T, 1, false, n, &stats, &coverage);
  report(opt, portable);
  report_helpers(opt, liver, T, n);
  for (int ds : {2, 4}) report_downscaled(ds);
  return 0;
}

}  // namespace

SCOPETRACK_BENCH_STAGE("raster", "mesh rasteriser: liver mask+depth+id vs cv::fillConvexPoly", run);

}  // namespace st::bench
