#include "support/tiny_sequence.h"

#include <doctest/doctest.h>

#include "core/image/image.h"
#include "core/formats/trajectory.h"
#include "hal/storage/mesh_file.h"
#include "hal/storage/sequence_loader.h"
#include "hal/storage/y4m_writer.h"

namespace st::test {

Mesh centred_cube(float s) {
  Mesh m;
  const float h = s / 2;
  for (int i = 0; i < 8; ++i) m.add_vertex((i & 1) ? h : -h, (i & 2) ? h : -h, (i & 4) ? h : -h);
  const int f[12][3] = {{0, 2, 1}, {1, 2, 3}, {4, 5, 6}, {5, 7, 6}, {0, 1, 4}, {1, 5, 4},
                        {2, 6, 3}, {3, 6, 7}, {0, 4, 2}, {2, 4, 6}, {1, 3, 5}, {3, 7, 5}};
  for (const auto& t : f) m.add_triangle(t[0], t[1], t[2]);
  return m;
}

TinySequence write_tiny_sequence(const std::filesystem::path& dir, int frames) {
  TinySequence s;
  s.dir = dir;
  SequenceConfig& c = s.config;
  c.width = 64;
  c.height = 48;
  c.K = Pinhole{60, 60, 31.5, 23.5, 64, 48};
  c.distortion.count = 5;
  c.fps = 25;
  c.T_camera_model_init = SE3(Mat3::Identity(), Vec3(0, 0, 150));
  c.video = "video.y4m";
  c.mesh = "organ.ply";
  c.groundtruth = "groundtruth.txt";
  c.markers = "markers.txt";
  s.mesh = centred_cube(40);
  std::vector<TimedPose> gt;
  for (int i = 0; i < frames; ++i) gt.push_back({i / c.fps, c.T_camera_model_init.inverse()});
  const std::vector<Marker> markers = {{1, Vec3(20, 20, 20)}, {2, Vec3(-20, 0, 20)}};
  REQUIRE(write_sequence_files(dir, c, &gt, &markers).ok());
  REQUIRE(save_mesh_ply(dir / c.mesh, s.mesh).ok());
  Y4mWriter writer;
  Y4mHeader h;
  h.width = c.width;
  h.height = c.height;
  REQUIRE(writer.open(dir / c.video, h).ok());
  Image<std::uint8_t> Y(64, 48), U(32, 24), V(32, 24);
  U.fill(128);
  V.fill(128);
  for (int f = 0; f < frames; ++f) {
    Y.fill(static_cast<std::uint8_t>(40 + f));
    REQUIRE(writer.write(Y.cview(), U.cview(), V.cview()).ok());
  }
  REQUIRE(writer.close().ok());
  return s;
}

}  // namespace st::test
