#include <doctest/doctest.h>

#include <cstdlib>

#include "core/formats/trajectory.h"
#include "eval_report.h"
#include "hal/storage/file_io.h"
#include "hal/storage/sequence_loader.h"
#include "support/support.h"
#include "support/tiny_sequence.h"

using namespace st;

namespace {

std::string trajectory_text(const std::vector<TimedPose>& poses) { return format_tum(poses); }

// A perturbed copy of the ground truth: frame i dropped when drop(i),
// translated by shift_mm(i) along x otherwise.
template <class Drop, class Shift>
std::vector<TimedPose> perturbed(const std::vector<TimedPose>& gt, Drop drop, Shift shift_mm) {
  std::vector<TimedPose> out;
  for (std::size_t i = 0; i < gt.size(); ++i) {
    if (drop(static_cast<int>(i))) continue;
    TimedPose p = gt[i];
    p.T_model_camera.translation() += Vec3(shift_mm(static_cast<int>(i)), 0, 0);
    out.push_back(p);
  }
  return out;
}

}  // namespace

TEST_CASE("scopetrack-eval: the ground truth itself gives TRE 0 and lost 0") {
  const auto seq = test::scratch_dir("eval_seq_gt");
  test::write_tiny_sequence(seq, 20);
  auto loaded = load_sequence(seq);
  REQUIRE(loaded.ok());
  const auto out = test::scratch_dir("eval_out_gt");
  REQUIRE(write_file(out / "trajectory.txt", trajectory_text(loaded->groundtruth)).ok());
  auto r = evaluate_run(seq, out);
  REQUIRE_MESSAGE(r.ok(), (r.ok() ? "" : r.message()));
  CHECK(r->result.frames == 20);
  CHECK(r->result.lost_pct == 0.0);
  CHECK(r->result.init_ok);
  CHECK(r->result.tre_samples == 40);
  CHECK(r->result.tre_max_px < 1e-6);
  CHECK(r->result.wrong_pct == 0.0);
}

TEST_CASE("scopetrack-eval: dropped and shifted frames give the independently computed figures") {
  const auto seq = test::scratch_dir("eval_seq_pert");
  const test::TinySequence tiny = test::write_tiny_sequence(seq, 20);
  auto loaded = load_sequence(seq);
  REQUIRE(loaded.ok());
  // Drop frames 5, 6, 7 and 15; shift frames 10-12 by 3 mm sideways.
  auto drop = [](int i) { return (i >= 5 && i <= 7) || i == 15; };
  auto shift = [](int i) { return (i >= 10 && i <= 12) ? 3.0 : 0.0; };
  const auto out = test::scratch_dir("eval_out_pert");
  REQUIRE(write_file(out / "trajectory.txt", trajectory_text(perturbed(loaded->groundtruth, drop, shift))).ok());
  REQUIRE(write_file(out / "summary.json", "{\n  \"fps\": 123.5,\n  \"p99_latency_ms\": 7.25\n}\n").ok());
  auto r = evaluate_run(seq, out);
  REQUIRE_MESSAGE(r.ok(), (r.ok() ? "" : r.message()));

  // Independent figures: 4 of 20 frames missing.
  CHECK(r->result.lost_pct == doctest::Approx(20.0));
  // Markers are 170 mm deep (camera 150 mm in front of the cube centre,
  // markers on the far face at z = +20): a 3 mm shift moves each projection
  // by f * 3 / 170 = 60 * 3 / 170 px (the distortion is zero).
  const double expected_px = 60.0 * 3.0 / 170.0;
  CHECK(r->result.tre_samples == 16 * 2);
  CHECK(r->result.tre_max_px == doctest::Approx(expected_px).epsilon(1e-6));
  // 6 of 32 samples are shifted: mean = 6 * e / 32, median 0.
  CHECK(r->result.tre_mean_px == doctest::Approx(6.0 * expected_px / 32.0).epsilon(1e-6));
  CHECK(r->result.tre_median_px < 1e-6);
  CHECK(r->result.trans_err_median_mm < 1e-6);
  CHECK(r->result.wrong_pct == 0.0);
  CHECK(r->fps == doctest::Approx(123.5));
  CHECK(r->p99_latency_ms == doctest::Approx(7.25));
  const std::string js = format_eval_json(r.value());
  CHECK(js.find("\"lost_pct\": 20") != std::string::npos);
  // The table rounds speed as people read it (no 17-digit doubles).
  EvalReport rounded = r.value();
  rounded.fps = 106.34495606484867;
  rounded.p99_latency_ms = 23.900000000000002;
  const std::string table = format_eval_table(rounded);
  CHECK(table.find("fps               106.3\n") != std::string::npos);
  CHECK(table.find("p99 latency       23.90 ms\n") != std::string::npos);
  (void)tiny;
}

TEST_CASE("scopetrack-eval: malformed input is a clear error and a non-zero exit" *
          doctest::test_suite(test::kProcessSuite)) {
  const auto seq = test::scratch_dir("eval_seq_bad");
  test::write_tiny_sequence(seq, 5);
  const auto out = test::scratch_dir("eval_out_bad");
  auto expect_error = [&](const char* needle) {
    auto r = evaluate_run(seq, out);
    REQUIRE_FALSE(r.ok());
    INFO(r.message());
    CHECK(r.message().find(needle) != std::string::npos);
  };
  expect_error("trajectory.txt");  // missing
  REQUIRE(write_file(out / "trajectory.txt", "0 0 0 nan 0 0 0 1\n").ok());
  expect_error("trajectory.txt");
  REQUIRE(write_file(out / "trajectory.txt", "99.0 0 0 0 0 0 0 1\n").ok());
  expect_error("matches no frame");
  REQUIRE(write_file(out / "trajectory.txt", "0 0 0 -150 0 0 0 1\n0 0 0 -150 0 0 0 1\n").ok());
  expect_error("two poses for frame 0");
  REQUIRE(write_file(out / "trajectory.txt", "0 0 0 -150 0 0 0 1\n").ok());
  REQUIRE(write_file(out / "frames.csv", "garbage\n").ok());
  expect_error("frames.csv");
  std::filesystem::remove(out / "frames.csv");
  REQUIRE(write_file(out / "summary.json", "{\"fps\": \"fast\"}").ok());
  expect_error("summary.json");

  const std::string cmd = (test::bin_dir() / "scopetrack-eval").string() + " " + seq.string() +
                          " " + out.string() + " > /dev/null 2>&1";
  CHECK(std::system(cmd.c_str()) != 0);
  std::filesystem::remove(out / "summary.json");
  CHECK(std::system(cmd.c_str()) == 0);
  CHECK(std::system(((test::bin_dir() / "scopetrack-eval").string() + " /nonexistent " +
                     out.string() + " > /dev/null 2>&1").c_str()) != 0);
}
