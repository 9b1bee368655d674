// Live capture without a camera (this machine has none): the calibration /
// registration file, the camera listing's message, LibcameraCapture's
// refusal, and `scopetrack --camera / --list-cameras` exiting non-zero with
// a message that says what libcamera found. The capture loop itself has not
// run on hardware.
#include <doctest/doctest.h>

#include <cstdlib>

#include "core/formats/sequence.h"
#include "hal/storage/file_io.h"
#include "hal/capture/libcamera_capture.h"
#include "support/shell.h"
#include "support/support.h"

using namespace st;

namespace {

// The camera keys of sequence.yaml only: no fps, video or mesh.
constexpr const char* kCalibration = R"(%YAML:1.0
---
image_width: 640
image_height: 360
camera_matrix: !!opencv-matrix
   rows: 3
   cols: 3
   dt: d
   data: [ 460., 0., 322.5, 0., 461., 177.5, 0., 0., 1. ]
distortion_coefficients: !!opencv-matrix
   rows: 1
   cols: 5
   dt: d
   data: [ -0.1, 0.02, 0., 0., 0. ]
T_camera_model_init: !!opencv-matrix
   rows: 4
   cols: 4
   dt: d
   data: [ 1., 0., 0., 5., 0., 1., 0., -3., 0., 0., 1., 180., 0., 0., 0., 1. ]
)";

}  // namespace

TEST_CASE("libcamera calibration: the camera keys of sequence.yaml, no file names or fps needed") {
  auto c = parse_calibration_yaml(kCalibration);
  REQUIRE_MESSAGE(c.ok(), (c.ok() ? "" : c.message()));
  CHECK(c->width == 640);
  CHECK(c->K.fx == 460.0);
  CHECK(c->K.cy == 177.5);
  CHECK(c->distortion.count == 5);
  CHECK(c->distortion.k[0] == -0.1);
  CHECK(c->fps == 0.0);
  CHECK(c->T_camera_model_init.translation().z() == 180.0);
  // The same text is not a sequence (no video/mesh/fps) ...
  CHECK(!parse_sequence_yaml(kCalibration).ok());
  // ... but a sequence.yaml is a calibration file.
  SequenceConfig s = c.value();
  s.fps = 25;
  s.video = "video.y4m";
  s.mesh = "organ.ply";
  auto back = parse_calibration_yaml(format_sequence_yaml(s));
  REQUIRE(back.ok());
  CHECK(back->fps == 25);
}

TEST_CASE("libcamera calibration: bad files name the calibration file and the key") {
  std::string text = kCalibration;
  text.replace(text.find("460., 0., 322.5"), 15, "460., 1., 322.5");  // skew
  auto r = parse_calibration_yaml(text);
  REQUIRE(!r.ok());
  CHECK(r.message().find("calibration file: camera_matrix must be [fx 0 cx; 0 fy cy; 0 0 1]") !=
        std::string::npos);
  text = kCalibration;
  text.replace(text.find("1., 0., 0., 5."), 14, "2., 0., 0., 5.");  // scale in the rotation
  r = parse_calibration_yaml(text);
  REQUIRE(!r.ok());
  CHECK(r.message().find("calibration file: T_camera_model_init is not rigid") !=
        std::string::npos);
  CHECK(!parse_calibration_yaml("").ok());
  CHECK(!parse_calibration_yaml("image_width: 640\nimage_height: 360\n").ok());  // no camera_matrix
  CHECK(!parse_calibration_yaml("\x01\x02garbage").ok());
}

TEST_CASE("libcamera capture: the listing message says what was found") {
  CHECK(describe_cameras({"0.0.3", {}}) == "no camera found (libcamera 0.0.3 found 0 cameras)");
  CHECK(describe_cameras({"0.0.3", {"/base/i2c@1/imx219@10"}}) ==
        "libcamera 0.0.3 found 1 camera: '/base/i2c@1/imx219@10'");
  CHECK(describe_cameras({"0.0.3", {"a", "b"}}) == "libcamera 0.0.3 found 2 cameras: 'a' 'b'");
}

TEST_CASE("libcamera capture: no camera attached -> open() refuses and says what libcamera found") {
  auto listing = list_cameras();
  REQUIRE_MESSAGE(listing.ok(), (listing.ok() ? "" : listing.message()));
  CHECK(listing->libcamera_version == libcamera_version());
  CHECK(listing->libcamera_version.rfind("0.", 0) == 0);  // Debian 12: 0.0.3
  LibcameraCapture capture;
  const Status s = capture.open({"no-such-camera", 640, 360, 4});
  REQUIRE(!s.ok());
  if (listing->ids.empty())
    CHECK(s.message() ==
          "no camera found (libcamera " + listing->libcamera_version + " found 0 cameras)");
  else
    CHECK(s.message().find("camera 'no-such-camera' not found") != std::string::npos);
  CHECK(!capture.start().ok());  // not opened
  capture.stop();                // harmless
  // Bad options are refused before libcamera is asked.
  CHECK(!capture.open({"x", 0, 360, 4}).ok());
  CHECK(capture.open({"x", 640, 360, 1}).message().find("2..32 buffers") != std::string::npos);
}

TEST_CASE(
    "libcamera capture: scopetrack --camera / --list-cameras without a camera exit non-zero and "
    "say why" * doctest::test_suite(test::kProcessSuite)) {
  const auto dir = test::scratch_dir("libcamera_app");
  REQUIRE(write_file(dir / "calibration.yaml", kCalibration).ok());
  REQUIRE(write_file(dir / "bad.yaml", "image_width: 640\n").ok());
  const std::string app = test::shell_quoted(test::bin_dir() / "scopetrack");
  const std::string mesh = test::shell_quoted(test::shared_data("liver/liver.ply"));
  auto listing = list_cameras();
  REQUIRE(listing.ok());
  if (!listing->ids.empty()) {
    MESSAGE("a camera is attached: the no-camera checks are skipped");
    return;
  }
  const std::string no_camera =
      "no camera found (libcamera " + listing->libcamera_version + " found 0 cameras)";
  CHECK(test::run_shell(app + " --camera cam0 --mesh " + mesh + " --calibration " +
                        test::shell_quoted(dir / "calibration.yaml") + " --out " +
                        test::shell_quoted(dir / "out") + " > /dev/null 2> " +
                        test::shell_quoted(dir / "camera.err")) == 1);
  CHECK(test::read_file_bytes(dir / "camera.err").find(no_camera) != std::string::npos);
  CHECK(test::run_shell(app + " --list-cameras > " + test::shell_quoted(dir / "list.out") + " 2> " +
                        test::shell_quoted(dir / "list.err")) == 1);
  CHECK(test::read_file_bytes(dir / "list.err").find(no_camera) != std::string::npos);
  CHECK(test::read_file_bytes(dir / "list.out").empty());
  // Files are checked before the camera: their errors come first.
  CHECK(test::run_shell(app + " --camera cam0 --mesh " + mesh + " --calibration " +
                        test::shell_quoted(dir / "bad.yaml") + " > /dev/null 2> " +
                        test::shell_quoted(dir / "bad.err")) == 1);
  CHECK(test::read_file_bytes(dir / "bad.err").find("calibration file") != std::string::npos);
  CHECK(test::run_shell(app + " --camera cam0 --mesh " + test::shell_quoted(dir / "missing.ply") +
                        " --calibration " + test::shell_quoted(dir / "calibration.yaml") +
                        " > /dev/null 2>&1") == 1);
  // A bad command line: exit 2.
  CHECK(test::run_shell(app + " --camera cam0 --mesh " + mesh + " > /dev/null 2>&1") == 2);
  CHECK(test::run_shell(app + " --camera --mesh " + mesh + " --calibration x > /dev/null 2>&1") ==
        2);
  CHECK(test::run_shell(app + " --list-cameras extra > /dev/null 2>&1") == 2);
}
