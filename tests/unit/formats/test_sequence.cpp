#include <doctest/doctest.h>

#include <opencv2/core.hpp>

#include "core/formats/sequence.h"

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

namespace {
// The example config's YAML with one key's text replaced (or removed).
std::string with_replaced(const std::string& key, const std::string& replacement) {
  std::string text = format_sequence_yaml(example_config());
  const std::size_t at = text.find(key + ":");
  REQUIRE(at != std::string::npos);
  std::size_t end = text.find('\n', at);
  // Matrices span several lines until the next top-level key.
  while (end + 1 < text.size() && (text[end + 1] == ' ')) end = text.find('\n', end + 1);
  text.replace(at, end - at, replacement);
  return text;
}
std::string matrix(int rows, int cols, const std::string& data) {
  return "!!opencv-matrix\n   rows: " + std::to_string(rows) + "\n   cols: " + std::to_string(cols) +
         "\n   dt: d\n   data: [ " + data + " ]";
}
}  // namespace

TEST_CASE("sequence: OpenCV calibration output pasted in, 4 and 8 coefficients, tiny rotation error") {
  for (const char* d : {"0.1, 0.01, 0, 0", "0.1, 0.01, 0, 0, 0.001, 0, 0, 0"}) {
    auto r = parse_sequence_yaml(with_replaced(
        "distortion_coefficients",
        "distortion_coefficients: " + matrix(1, std::string(d).size() > 20 ? 8 : 4, d)));
    REQUIRE_MESSAGE(r.ok(), (r.ok() ? "" : r.message()));
    CHECK((r->distortion.count == 4 || r->distortion.count == 8));
  }
  // A rotation written with 6 decimals: off by ~1e-6, re-orthonormalised.
  auto r = parse_sequence_yaml(with_replaced(
      "T_camera_model_init", "T_camera_model_init: " +
                                 matrix(4, 4, "0.999999, 0.001, 0, 1, -0.001, 0.999999, 0, 2, 0, 0, 1.000001, 150, 0, 0, 0, 1")));
  REQUIRE_MESSAGE(r.ok(), (r.ok() ? "" : r.message()));
  CHECK(r->T_init_reorthonormalised);
  const Mat3 R = r->T_camera_model_init.rotation();
  CHECK((R.transpose() * R - Mat3::Identity()).norm() < 1e-12);
  CHECK(r->T_camera_model_init.translation().z() == 150);
}

TEST_CASE("sequence: bad sequence.yaml gives clear errors, never throws") {
  struct Case { std::string text; const char* needle; };
  const std::string K_ok = "640, 0, 320, 0, 640, 240, 0, 0, 1";
  const Case cases[] = {
      {"", "empty"},
      {"%YAML:1.0\n---\nimage_width: [1, 2\n", "YAML"},                             // broken YAML
      {"\x01\x02\x03 garbage {{{", "control characters"},
      {"<?xml version=\"1.0\"?>\n<opencv_storage><x>1</x>", "expected 'key: value'"},
      {"{\"image_width\": 64}", "expected 'key: value'"},
      {"%YAML:1.0\n---\nfoo: 1\n", "image_width"},
      {with_replaced("image_width", "image_width: 0"), "image size"},
      {with_replaced("image_width", "image_width: 100000"), "image size"},
      {with_replaced("image_width", "image_width: abc"), "integers"},
      {with_replaced("camera_matrix", "camera_matrix: " + matrix(2, 2, "1, 0, 0, 1")), "3x3"},
      {with_replaced("camera_matrix", "camera_matrix: " + matrix(3, 3, "-640, 0, 320, 0, 640, 240, 0, 0, 1")), "focal"},
      {with_replaced("camera_matrix", "camera_matrix: " + matrix(3, 3, "640, 0, 5000, 0, 640, 240, 0, 0, 1")), "principal point"},
      {with_replaced("camera_matrix", "camera_matrix: " + matrix(3, 3, "640, 0, .nan, 0, 640, 240, 0, 0, 1")), "principal point"},
      {with_replaced("camera_matrix", "camera_matrix: " + matrix(3, 3, "640, 3, 320, 0, 640, 240, 0, 0, 1")), "skew"},
      {with_replaced("distortion_coefficients", "distortion_coefficients: " + matrix(1, 3, "0, 0, 0")), "4, 5 or 8"},
      {with_replaced("distortion_coefficients", "x: 1"), "distortion_coefficients missing"},
      {with_replaced("fps", "fps: -3"), "fps"},
      {with_replaced("video", "video: \"\""), "required"},
      {with_replaced("T_camera_model_init", "T_camera_model_init: " + matrix(3, 3, K_ok)), "4x4"},
      {with_replaced("T_camera_model_init", "T_camera_model_init: " + matrix(4, 4, "2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 1")), "not rigid"},
      {with_replaced("T_camera_model_init", "T_camera_model_init: " + matrix(4, 4, "1, 0, 0, 0, 0, 1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1")), "not rigid"},
      {with_replaced("T_camera_model_init", "T_camera_model_init: " + matrix(4, 4, "1, 0.01, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1")), "not rigid"},
      {with_replaced("T_camera_model_init", "T_camera_model_init: " + matrix(4, 4, "1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 1, 1")), "last row"},
      // Found by fuzz_sequence_yaml: OpenCV 4.6's YAML reader never returns on these.
      {"%YAML:1.0\n---x: 1\n-]--/y: 64\nz", "line 2"},
      {std::string("%YAML:1.0\n---/im\xda" "age_width: AML:1.0\n-]--/image_width: 64\nimage_height: 48\na: [ 0., 0., "), "line 2"},
      {"%YAML:1.0\n---\nimage_width: 64\n\x01\x02\n", "control characters"},
      // Found by fuzz_sequence_yaml: cv::Mat reading allocated rows x cols as written.
      {with_replaced("camera_matrix", "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: \xbb\n   dt: d\n   data: [ 60., 0., 31.5, 01, 60., 23.5, 0., 0., 1. ]"), "3x3"},
      {with_replaced("camera_matrix", "camera_matrix: !!opencv-matrix\n   rows: 3\n   cols: 2000000000\n   dt: d\n   data: [ 1 ]"), "3x3"},
      {with_replaced("camera_matrix", "camera_matrix: " + matrix(3, 3, "640, 0, 320, 0, 640, 240, 0, 0")), "3x3"},
      {with_replaced("camera_matrix", "camera_matrix: " + matrix(3, 3, "640, 0, 320, 0, abc, 240, 0, 0, 1")), "3x3"},
      {with_replaced("T_camera_model_init", "T_camera_model_init: " + matrix(4, 4, "1, 0, 0, .inf, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1")), "non-finite"},
      // Found by fuzz_sequence_yaml: fy = 6e13 px made the lens check step
      // ~1e14 times along one ray (a hang); now refused at once.
      {with_replaced("camera_matrix", "camera_matrix: " + matrix(3, 3, "640, 0, 320, 0, 60000000000000., 240, 0, 0, 1")), "field of view"},
      {with_replaced("camera_matrix", "camera_matrix: " + matrix(3, 3, "640, 0, 320, 0, 3000, 240, 0, 0, 1")), "not one camera"},
      // Found by fuzz_sequence_yaml: a name cv::FileStorage writes back as
      // structure made format_sequence_yaml throw (a crash in
      // scopetrack-register --write); now refused when read.
      {with_replaced("video", "video: \"}ideo.y4m\""), "not a usable file name"},
      {with_replaced("mesh", "mesh: \"[organ.ply\""), "not a usable file name"},
      {with_replaced("video", "video: \"vi\\tdeo.y4m\""), "not a usable file name"},
  };
  for (const Case& c : cases) {
    Result<SequenceConfig> r = make_error("not run");
    CHECK_NOTHROW(r = parse_sequence_yaml(c.text));
    REQUIRE_FALSE(r.ok());
    INFO(c.text);
    INFO(r.message());
    CHECK(r.message().find(c.needle) != std::string::npos);
  }
}

TEST_CASE("sequence: a file in the shape of OpenCV's calibration sample output is accepted") {
  // What opencv's calibration sample writes (extra keys, strings, matrices,
  // an nd-matrix), with the sequence keys added.
  cv::FileStorage fs(".yaml", cv::FileStorage::WRITE | cv::FileStorage::MEMORY);
  fs << "calibration_time" << "Sat Nov 21 08:00:00 2026";
  fs << "nr_of_frames" << 25 << "image_width" << 1920 << "image_height" << 1080;
  fs << "board_width" << 9 << "board_height" << 6 << "square_size" << 25.0;
  fs << "flags" << 0 << "fisheye_model" << 0;
  fs << "camera_matrix" << (cv::Mat_<double>(3, 3) << 1400, 0, 959.5, 0, 1400, 539.5, 0, 0, 1);
  fs << "distortion_coefficients" << (cv::Mat_<double>(5, 1) << -0.2, 0.05, 0, 0, 0);
  fs << "avg_reprojection_error" << 0.31;
  fs << "per_view_reprojection_errors" << cv::Mat(25, 1, CV_32F, cv::Scalar(0.3f));
  const int sizes[3] = {2, 3, 2};
  fs << "image_points" << cv::Mat(3, sizes, CV_32F, cv::Scalar(1.0f));
  fs << "fps" << 30 << "video" << "video.y4m" << "mesh" << "liver.stl";
  fs << "T_camera_model_init" << cv::Mat(cv::Mat::eye(4, 4, CV_64F));
  const std::string text = fs.releaseAndGetString();
  auto r = parse_sequence_yaml(text);
  REQUIRE_MESSAGE(r.ok(), (r.ok() ? "" : r.message()));
  CHECK(r->width == 1920);
  CHECK(r->K.cx == 959.5);
  CHECK(r->distortion.count == 5);
  CHECK(r->distortion.k[0] == -0.2);
  CHECK(r->fps == 30);
  CHECK(r->mesh == "liver.stl");
}
