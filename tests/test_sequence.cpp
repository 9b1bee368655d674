#include <doctest/doctest.h>

#include <opencv2/core.hpp>

#include "core/sequence.h"

using namespace st;

namespace {
SequenceConfig example_config() {
  SequenceConfig c;
  c.width = 1280;
  c.height = 720;
  c.K = Pinhole{900, 905, 639.5, 359.5, 1280, 720};
  c.distortion.count = 5;
  c.distortion.k = {-0.1, 0.02, 0.001, -0.0005, 0.003, 0, 0, 0};
  c.fps = 30;
  c.T_camera_model_init = SE3::exp((Vec6() << 0.1, -0.2, 0.3, 5, -7, 180).finished());
  c.video = "video.y4m";
  c.mesh = "organ.ply";
  c.groundtruth = "groundtruth.txt";
  return c;
}
}  // namespace

TEST_CASE("sequence: yaml write/parse round trip, and OpenCV reads it") {
  const SequenceConfig c = example_config();
  const std::string text = format_sequence_yaml(c);
  auto r = parse_sequence_yaml(text);
  REQUIRE_MESSAGE(r.ok(), (r.ok() ? "" : r.message()));
  CHECK(r->width == 1280);
  CHECK(r->height == 720);
  CHECK(r->K.fx == 900);
  CHECK(r->K.cy == 359.5);
  CHECK(r->K.width == 1280);
  CHECK(r->distortion.count == 5);
  CHECK(r->distortion.k == c.distortion.k);
  CHECK(r->fps == 30);
  CHECK(pose_delta(r->T_camera_model_init, c.T_camera_model_init).angle_deg < 1e-9);
  CHECK(pose_delta(r->T_camera_model_init, c.T_camera_model_init).distance_mm < 1e-9);
  CHECK(r->video == "video.y4m");
  CHECK(r->mesh == "organ.ply");
  CHECK(r->groundtruth == "groundtruth.txt");
  CHECK(r->markers.empty());
  cv::FileStorage fs(text, cv::FileStorage::READ | cv::FileStorage::MEMORY);
  REQUIRE(fs.isOpened());
  cv::Mat K;
  fs["camera_matrix"] >> K;
  CHECK(K.at<double>(0, 2) == 639.5);
  CHECK(static_cast<int>(fs["image_width"]) == 1280);
}
