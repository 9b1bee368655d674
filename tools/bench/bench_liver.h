// The real CT liver (../shared/data/liver/liver.ply) for bench stages.
#pragma once

#include <cstdio>
#include <fstream>
#include <sstream>
#include <string>

#include "bench.h"
#include "core/raster/rasterizer.h"
#include "tests/support/raster_scene.h"
#include "tests/support/test_ply.h"

namespace st::bench {

// The liver mesh, or an Error naming the file (the stage prints it).
inline Result<Mesh> load_bench_liver(const Options& opt) {
  const std::string path = opt.shared_dir + "/data/liver/liver.ply";
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  auto mesh = test::read_binary_ply_for_tests(ss.str());
  if (!mesh.ok()) return make_error("cannot load " + path + ": " + mesh.message());
  return mesh;
}

// A fixed oblique view of the mesh at the distance where it covers the
// given share of a 1280x720 image (bench_pinhole), searched at 1/4 raster.
inline SE3 liver_view_filling(const Mesh& liver, double coverage) {
  MeshRasterizer r;
  RasterConfig cfg;
  cfg.width = 1280;
  cfg.height = 720;
  cfg.downscale = 4;
  if (!r.configure(liver, cfg).ok()) return SE3();
  SE3 T;
  for (double d = 900.0; d > 100.0; d *= 0.98) {
    T = test::look_at(test::bbox_centre(liver), Vec3(0.25, -0.35, 1.0), d, 0.3);
    r.render(T, test::bench_pinhole());
    if (r.covered_pixels() >= coverage * 320 * 180) break;
  }
  return T;
}

}  // namespace st::bench
