#include <doctest/doctest.h>

#include <cmath>
#include <random>

#include "core/formats/trajectory.h"

using namespace st;

TEST_CASE("trajectory: TUM format/parse round trip is exact") {
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<TimedPose> poses;
  for (int i = 0; i < 50; ++i) {
    Vec6 xi;
    for (int k = 0; k < 6; ++k) xi[k] = u(rng) * (k < 3 ? 1.5 : 150.0);
    poses.push_back({i / 30.0, SE3::exp(xi)});
  }
  const std::string text = format_tum(poses);
  auto back = parse_tum(text);
  REQUIRE(back.ok());
  REQUIRE(back->size() == poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) {
    CHECK(back.value()[i].timestamp_s == poses[i].timestamp_s);
    const PoseDelta d = pose_delta(back.value()[i].T_model_camera, poses[i].T_model_camera);
    CHECK(d.angle_deg < 1e-9);
    CHECK(d.distance_mm < 1e-9);
  }
}

TEST_CASE("trajectory: TUM comments, blank lines, CRLF and normalisation") {
  auto r = parse_tum("# comment\n\n  1.5 1 2 3 0 0 0 1.01\r\n# end\n2 0 0 0 0 0 0 1");
  REQUIRE(r.ok());
  REQUIRE(r->size() == 2);
  CHECK(r.value()[0].timestamp_s == 1.5);
  CHECK(r.value()[0].T_model_camera.translation().isApprox(Vec3(1, 2, 3)));
  CHECK(std::abs(r.value()[0].T_model_camera.rotation().determinant() - 1.0) < 1e-12);
  CHECK(parse_tum("").ok());
}

TEST_CASE("trajectory: bad TUM lines are rejected with their line number") {
  struct Case { const char* text; const char* needle; };
  const Case cases[] = {
      {"0 0 0 0 0 0 0 1\n1 2 3\n", "line 2"},
      {"0 0 0 nan 0 0 0 1\n", "line 1"},
      {"0 0 0 0 0 0 0 inf\n", "finite"},
      {"0 0 0 0 0 0 0 1 9\n", "more than 8"},
      {"0 0 0 0 0 0 0 0\n", "quaternion"},
      {"0 0 0 0 0 0 0 5\n", "quaternion"},
      {"#\n#\nabc 0 0 0 0 0 0 1\n", "line 3"},
      {"0 0 0 0x10 0 0 0 1\n", "finite number"},
      {"\x01\x02\xff\xfe garbage", "line 1"},
  };
  for (const Case& c : cases) {
    auto r = parse_tum(c.text);
    REQUIRE_FALSE(r.ok());
    INFO(r.message());
    CHECK(r.message().find(c.needle) != std::string::npos);
  }
}

TEST_CASE("trajectory: markers round trip and bad input") {
  std::vector<Marker> m = {{1, Vec3(10.5, -2, 3)}, {7, Vec3(0.125, 1e3, -44)}};
  auto back = parse_markers(format_markers(m));
  REQUIRE(back.ok());
  REQUIRE(back->size() == 2);
  CHECK(back.value()[1].id == 7);
  CHECK(back.value()[1].p_model == m[1].p_model);
  CHECK_FALSE(parse_markers("1 0 0 0\n1 1 1 1\n").ok());   // duplicate id
  CHECK_FALSE(parse_markers("1.5 0 0 0\n").ok());          // fractional id
  CHECK_FALSE(parse_markers("-1 0 0 0\n").ok());
  CHECK_FALSE(parse_markers("1 0 nan 0\n").ok());
  CHECK_FALSE(parse_markers("1 0 0\n").ok());
  std::string many;
  for (int i = 0; i < 100; ++i) many += std::to_string(i) + " 0 0 0\n";
  auto r = parse_markers(many);
  REQUIRE_FALSE(r.ok());
  CHECK(r.message().find("more than") != std::string::npos);
}

TEST_CASE("trajectory: frames.csv and summary.json formatting") {
  CHECK(frames_csv_header() == "frame,timestamp,state,inliers,latency_ms,map_points,keyframes\n");
  CHECK(is_frames_csv_header("frame,timestamp,state,inliers,latency_ms"));  // an earlier build's
  CHECK(is_frames_csv_header("frame,timestamp,state,inliers,latency_ms,map_points,keyframes,later"));
  CHECK_FALSE(is_frames_csv_header("frame,timestamp,state,inliers,latency"));
  CHECK_FALSE(is_frames_csv_header("frame,timestamp,state,inliers,latency_msx"));
  CHECK(format_frames_csv_row({12, 0.48, FrameState::kTracking, 311, 6.25, 2403, 14}) ==
        "12,0.48,tracking,311,6.25,2403,14\n");
  CHECK(format_frames_csv_row({0, 0, FrameState::kInitialised, 0, 1.5}) == "0,0,initialised,0,1.5,0,0\n");
  CHECK(std::string(to_string(FrameState::kRelocalised)) == "relocalised");
  RunSummary s;
  s.frames = 10;
  s.tracked_frames = 9;
  s.lost_frames = 1;
  s.mean_latency_ms = 5.5;
  s.p99_latency_ms = std::nan("");
  s.fps = 120;
  s.peak_rss_mb = 80.25;
  s.extra = {{"tre_px_mean", 2.5}};
  const std::string j = format_summary_json(s);
  CHECK(j.find("\"frames\": 10,") != std::string::npos);
  CHECK(j.find("\"p99_latency_ms\": null,") != std::string::npos);
  CHECK(j.find("\"tre_px_mean\": 2.5\n}") != std::string::npos);
}
