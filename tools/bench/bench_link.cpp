// scopetrack-bench link: the console link's costs. Texturing one frame
// (core/texture/mesh_texture.h: render the id buffer + mean colour per visible
// triangle + Algorithm 1's update) of the CT liver filling most of a
// 1280x720 view, on the texture thread; and what the tracking thread pays
// per frame for the stream: push_pose() into a running sink.
#include <cstdio>
#include <string>
#include <vector>

#include "bench.h"
#include "bench_liver.h"
#include "core/texture/mesh_texture.h"
#include "hal/stream/stream_sink.h"

namespace st::bench {
namespace {

Row time_texture(const Mesh& liver, const SE3& T, int downscale, int n) {
  Row row;
  row.name = "texture add_frame 1280x720 id 1/" + std::to_string(downscale);
  Image<std::uint8_t> y(1280, 720), u(640, 360), v(640, 360);
  for (int r = 0; r < 720; ++r)
    for (int c = 0; c < 1280; ++c) y(c, r) = static_cast<std::uint8_t>((c * 7 + r * 3) & 255);
  u.fill(110);
  v.fill(170);
  MeshTexture tex;
  TextureConfig cfg;
  cfg.width = 1280;
  cfg.height = 720;
  cfg.downscale = downscale;
  if (!tex.configure(liver, CameraModel(test::bench_pinhole(), Distortion{}), cfg).ok()) return row;
  const YuvFrameView f{y.cview(), u.cview(), v.cview()};
  int changed = 0;
  for (int i = 0; i < 5; ++i) tex.add_frame(f, T);
  for (int i = 0; i < n; ++i) {
    const double t0 = now_ms();
    changed = tex.add_frame(f, T);
    row.samples_ms.push_back(now_ms() - t0);
  }
  int coloured = 0;
  for (int t = 0; t < tex.triangle_count(); ++t) coloured += tex.weight(t) > 0 ? 1 : 0;
  row.note = std::to_string(coloured) + " triangles coloured, " + std::to_string(changed) +
             " changed in the last frame";
  return row;
}

Row time_push_pose(const Mesh& liver, int n) {
  Row row;
  row.name = "stream push_pose (tracking thread)";
  StreamSink sink;
  StreamSinkConfig cfg;
  cfg.endpoint.kind = platform::Endpoint::Kind::kUnix;
  cfg.endpoint.path =
      "/tmp/scopetrack-bench-" + std::to_string(static_cast<long>(now_ms())) + ".sock";
  StreamHello hello;
  hello.mesh_triangle_count = static_cast<std::uint32_t>(liver.triangle_count());
  if (!sink.configure(cfg, hello).ok()) return row;
  sink.start();
  PoseSample p;
  for (int i = 0; i < n; ++i) {
    p.frame = static_cast<std::uint32_t>(i);
    const double t0 = now_ms();
    sink.push_pose(p);
    row.samples_ms.push_back(now_ms() - t0);
    const double until = now_ms() + 1.0;  // ~1000 frames/s: let the sink drain as it would
    while (now_ms() < until) {
    }
  }
  sink.stop(0.1);
  row.note =
      "SPSC copy + eventfd poke; sink thread took " + std::to_string(sink.stats().poses) + " poses";
  return row;
}

int run(const Options& opt) {
  auto mesh = load_bench_liver(opt);
  if (!mesh.ok()) {
    std::fprintf(stderr, "link: %s\n", mesh.message().c_str());
    return 1;
  }
  const int n = opt.iterations > 0 ? opt.iterations : 100;
  const SE3 T = liver_view_filling(mesh.value(), 0.6);
  for (int ds : {1, 2}) report(opt, time_texture(mesh.value(), T, ds, n));
  report(opt, time_push_pose(mesh.value(), 10 * n));
  return 0;
}

}  // namespace

SCOPETRACK_BENCH_STAGE("link", "console link: texturing one frame, the tracking thread's push_pose",
                       run);

}  // namespace st::bench
