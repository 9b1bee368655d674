#include <doctest/doctest.h>

#include <cstdlib>
#include <sys/wait.h>

#include "hal/storage/file_io.h"
#include "hal/storage/sequence_loader.h"
#include "support/support.h"
#include "support/tiny_sequence.h"

using namespace st;

namespace {

struct CheckRun {
  int exit_status = -1;
  std::string output;
};

CheckRun run_check(const std::filesystem::path& dir) {
  const auto out = dir.parent_path() / (dir.filename().string() + "-check.txt");
  const std::string cmd = (test::bin_dir() / "scopetrack").string() + " --check '" + dir.string() +
                          "' > '" + out.string() + "' 2>&1";
  const int status = std::system(cmd.c_str());
  CheckRun r;
  r.exit_status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.output = test::read_file_bytes(out);
  return r;
}

}  // namespace

TEST_CASE("check: a good sequence is usable and the report says what a user needs") {
  const auto root = test::scratch_dir("check_good");
  test::write_tiny_sequence(root / "seq", 5);
  const CheckRun r = run_check(root / "seq");
  INFO(r.output);
  CHECK(r.exit_status == 0);
  CHECK(r.output.find("5 frames, 64x48, 4:2:0") != std::string::npos);
  CHECK(r.output.find("12 triangles, 8 vertices, extent 40.0 x 40.0 x 40.0 mm") != std::string::npos);
  CHECK(r.output.find("outward winding") != std::string::npos);
  CHECK(r.output.find("fx 60.00 fy 60.00") != std::string::npos);
  CHECK(r.output.find("field of view") != std::string::npos);
  CHECK(r.output.find("100.0% inside the image") != std::string::npos);
  // The cube's front face (40 mm at z = 130 mm, f = 60 px) spans 18.5 px: 18 x 18
  // pixel centres of 64 x 48 = 10.5%.
  CHECK(r.output.find("covers 10.5% of the image, visible depth 130.0..130.0 mm") != std::string::npos);
  CHECK(r.output.find("5 poses") != std::string::npos);
  CHECK(r.output.find("2 markers, 2 project into frame 0") != std::string::npos);
  CHECK(r.output.find("USABLE (0 warnings)") != std::string::npos);
}

TEST_CASE("check: an inward mesh is fixed and reported, still usable") {
  const auto root = test::scratch_dir("check_inward");
  test::TinySequence s = test::write_tiny_sequence(root / "seq", 2);
  for (int t = 0; t < s.mesh.triangle_count(); ++t) std::swap(s.mesh.tri[3 * t + 1], s.mesh.tri[3 * t + 2]);
  REQUIRE(write_file(root / "seq" / "organ.ply", format_ply_binary(s.mesh)).ok());
  const CheckRun r = run_check(root / "seq");
  INFO(r.output);
  CHECK(r.exit_status == 0);
  CHECK(r.output.find("wound inward") != std::string::npos);
}

TEST_CASE("check: bad sequences are not usable and say why") {
  const auto root = test::scratch_dir("check_bad");
  struct Case {
    const char* name;
    void (*breakit)(test::TinySequence&);
    const char* needle;
  };
  const Case cases[] = {
      {"behind", [](test::TinySequence& s) {
         s.config.T_camera_model_init = SE3(Mat3::Identity(), Vec3(0, 0, -150));
         REQUIRE(write_sequence_files(s.dir, s.config).ok());
       }, "behind the camera"},
      {"aside", [](test::TinySequence& s) {
         s.config.T_camera_model_init = SE3(Mat3::Identity(), Vec3(500, 0, 150));
         REQUIRE(write_sequence_files(s.dir, s.config).ok());
       }, "no part of the mesh projects"},
      {"truncated", [](test::TinySequence& s) {
         std::string v = read_file(s.dir / "video.y4m", 1 << 20).value();
         v.resize(v.size() - 100);
         REQUIRE(write_file(s.dir / "video.y4m", v).ok());
       }, "frame 1 is truncated"},
      {"nomesh", [](test::TinySequence& s) { std::filesystem::remove(s.dir / "organ.ply"); },
       "does not exist"},
      {"empty", [](test::TinySequence& s) {
         REQUIRE(write_file(s.dir / "video.y4m", format_y4m_header(64, 48, 25, 1)).ok());
       }, "has no frames"},
  };
  for (const Case& c : cases) {
    test::TinySequence s = test::write_tiny_sequence(root / c.name, 2);
    c.breakit(s);
    const CheckRun r = run_check(root / c.name);
    INFO(std::string(c.name));
    INFO(r.output);
    CHECK(r.exit_status == 1);
    CHECK(r.output.find(c.needle) != std::string::npos);
    CHECK(r.output.find("NOT USABLE") != std::string::npos);
  }
  const CheckRun none = run_check(root / "does-not-exist");
  CHECK(none.exit_status == 1);
  CHECK(none.output.find("sequence.yaml") != std::string::npos);
}
