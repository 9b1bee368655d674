#include <doctest/doctest.h>

#include "hal/storage/file_io.h"
#include "hal/storage/sequence_loader.h"
#include "support/support.h"
#include "support/tiny_sequence.h"

using namespace st;

TEST_CASE("sequence_loader: a sequence written by our writers loads completely") {
  const auto dir = test::scratch_dir("seq_ok");
  const test::TinySequence tiny = test::write_tiny_sequence(dir, 4);
  auto s = load_sequence(dir);
  REQUIRE_MESSAGE(s.ok(), (s.ok() ? "" : s.message()));
  CHECK(s->config.width == 64);
  CHECK(s->mesh.triangle_count() == 12);
  CHECK_FALSE(s->mesh_report.flipped);
  CHECK(s->video_header.width == 64);
  CHECK(s->groundtruth.size() == 4);
  CHECK(s->markers.size() == 2);
  CHECK(s->markers[1].id == 2);
}

TEST_CASE("sequence_loader: missing files, size mismatch and bad parts are named") {
  const auto dir = test::scratch_dir("seq_bad");
  auto expect_error = [&](const char* needle) {
    auto s = load_sequence(dir);
    REQUIRE_FALSE(s.ok());
    INFO(s.message());
    CHECK(s.message().find(needle) != std::string::npos);
  };
  test::TinySequence tiny = test::write_tiny_sequence(dir);
  std::filesystem::remove(dir / "organ.ply");
  expect_error("mesh 'organ.ply' does not exist");
  tiny = test::write_tiny_sequence(dir);
  std::filesystem::remove(dir / "markers.txt");
  expect_error("markers 'markers.txt' does not exist");
  tiny = test::write_tiny_sequence(dir);
  std::filesystem::remove(dir / "video.y4m");
  expect_error("video 'video.y4m' does not exist");
  tiny = test::write_tiny_sequence(dir);
  REQUIRE(write_file(dir / "video.y4m", format_y4m_header(320, 240, 25, 1)).ok());
  expect_error("is 320x240 but sequence.yaml calibrates 64x48");
  tiny = test::write_tiny_sequence(dir);
  REQUIRE(write_file(dir / "groundtruth.txt", "0 0 0 0 0 0 0 1\n0.04 0 0 x 0 0 0 1\n").ok());
  expect_error("groundtruth.txt: TUM line 2");
  tiny = test::write_tiny_sequence(dir);
  REQUIRE(write_file(dir / "organ.ply", "ply\nformat ascii 1.0\n").ok());
  expect_error("organ.ply");
  tiny = test::write_tiny_sequence(dir);
  REQUIRE(write_file(dir / "sequence.yaml", "%YAML:1.0\n---\nimage_width: 64\n").ok());
  expect_error("sequence.yaml");
  std::filesystem::remove(dir / "sequence.yaml");
  expect_error("sequence.yaml");
}
