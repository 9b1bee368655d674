// The console link end to end through the executables: scopetrack replays a
// simulated sequence with --stream, scopetrack-console receives it. Every
// reported pose arrives in order; the coloured PLY matches the simulator's
// own frames (the true appearance of each triangle: mean RGB of its pixels
// at the true pose, organ pixels only, before the Y'CbCr conversion). And a
// console that connects and never reads does not slow the tracker.
#include <doctest/doctest.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "core/raster/rasterizer.h"
#include "core/formats/trajectory.h"
#include "hal/storage/mesh_file.h"
#include "hal/storage/sequence_loader.h"
#include "platform/clock.h"
#include "platform/realtime.h"
#include "platform/socket.h"
#include "support/shell.h"
#include "support/support.h"
#include "tools/sim/renderer.h"
#include "tools/sim/sim_run.h"

using namespace st;
using st::test::summary_number;

namespace {

int run(const std::string& cmd) { return test::run_shell(cmd); }
std::string q(const std::filesystem::path& p) { return test::shell_quoted(p); }
std::string bin(const std::string& name) { return test::bin_command(name); }
std::string socket_path(const char* name) {
  return "/tmp/st-e2e-" + std::to_string(::getpid()) + "-" + name + ".sock";
}

std::vector<TimedPose> read_tum(const std::filesystem::path& p) {
  auto t = parse_tum(test::read_file_bytes(p));
  REQUIRE_MESSAGE(t.ok(), (p.string() + ": " + (t.ok() ? std::string() : t.message())));
  return t.value();
}

// Face colours of a binary PLY written by format_ply_binary with face_rgb.
std::vector<std::uint8_t> ply_face_rgb(const std::string& bytes, const Mesh& mesh) {
  const std::size_t end = bytes.find("end_header\n");
  REQUIRE(end != std::string::npos);
  REQUIRE(bytes.find("property uchar red") < end);
  std::size_t off = end + 11 + 12 * static_cast<std::size_t>(mesh.vertex_count());
  const auto n = static_cast<std::size_t>(mesh.triangle_count());
  REQUIRE(bytes.size() == off + 16 * n);
  std::vector<std::uint8_t> rgb(3 * n);
  for (std::size_t t = 0; t < n; ++t, off += 16)
    for (int c = 0; c < 3; ++c)
      rgb[3 * t + static_cast<std::size_t>(c)] =
          static_cast<std::uint8_t>(bytes[off + 13 + static_cast<std::size_t>(c)]);
  return rgb;
}

// The true appearance: per triangle, mean RGB over every organ pixel of
// every frame at the true pose, and the frames that saw it (>= 3 pixels).
struct Reference {
  std::vector<double> sum;
  std::vector<std::int64_t> pixels;
  std::vector<int> frames;
};
Reference reference_texture(const Mesh& mesh, const Pinhole& K, const std::vector<cv::Mat>& rgb,
                            const std::vector<cv::Mat>& labels, const std::vector<TimedPose>& gt) {
  MeshRasterizer r;
  RasterConfig rc;
  rc.width = K.width;
  rc.height = K.height;
  REQUIRE(r.configure(mesh, rc).ok());
  const auto n = static_cast<std::size_t>(mesh.triangle_count());
  Reference ref{std::vector<double>(3 * n, 0.0), std::vector<std::int64_t>(n, 0),
                std::vector<int>(n, 0)};
  std::vector<int> count(n);
  for (std::size_t f = 0; f < rgb.size(); ++f) {
    r.render(gt[f].T_model_camera.inverse(), K);
    std::fill(count.begin(), count.end(), 0);
    for (int y = 0; y < K.height; ++y)
      for (int x = 0; x < K.width; ++x) {
        const std::int32_t t = r.triangle_id()(x, y);
        if (t < 0 || labels[f].at<std::uint8_t>(y, x) != sim::kLabelOrgan) continue;
        const cv::Vec3b c = rgb[f].at<cv::Vec3b>(y, x);  // R, G, B
        const auto ti = static_cast<std::size_t>(t);
        for (int k = 0; k < 3; ++k) ref.sum[3 * ti + static_cast<std::size_t>(k)] += c[k];
        ++ref.pixels[ti];
        ++count[ti];
      }
    for (std::size_t t = 0; t < n; ++t) ref.frames[t] += count[t] >= 3 ? 1 : 0;
  }
  return ref;
}

}  // namespace

TEST_CASE(
    "console_e2e: scopetrack streams a simulated sequence, the console gets every pose in order "
    "and the "
    "simulator's texture" *
    doctest::timeout(test::budget_s(400))) {
  const auto dir = test::scratch_dir("console_e2e");
  sim::SimOptions so;
  so.scenario = sim::ScenarioKind::Orbit;
  so.out_dir = dir / "seq";
  so.frames = 120;
  so.width = 480;
  so.height = 270;
  so.seed = 2;
  std::vector<cv::Mat> rgb, labels;
  auto sim_report = sim::run_simulation(so, [&](int, const cv::Mat& r, const cv::Mat& l) {
    rgb.push_back(r.clone());
    labels.push_back(l.clone());
  });
  REQUIRE_MESSAGE(sim_report.ok(), (sim_report.ok() ? std::string() : sim_report.message()));

  const std::string sock = socket_path("loop");
  // Built by appends (GCC 12 warns falsely on "(" + std::string).
  std::string cmd = "(";
  cmd += bin("scopetrack") + " --sequence " + q(dir / "seq") + " --out " + q(dir / "out");
  cmd += " --stream unix:" + sock + " --stream-wait 1 --texture-every 1 > " + q(dir / "track.log");
  cmd += " 2>&1; echo $? > " + q(dir / "track.code") + ") & ";
  cmd += bin("scopetrack-console") + " unix:" + sock + " --record " + q(dir / "rec");
  cmd += " --mesh " + q(dir / "seq/organ.ply") + " > " + q(dir / "console.log") +
         " 2>&1; c=$?; wait; exit $c";
  const int console_code = run(cmd);
  const std::string track_log = test::read_file_bytes(dir / "track.log");
  const std::string console_log = test::read_file_bytes(dir / "console.log");
  INFO("scopetrack: " << track_log);
  INFO("console: " << console_log);
  REQUIRE(console_code == 0);
  REQUIRE(std::atoi(test::read_file_bytes(dir / "track.code").c_str()) == 0);

  // Every reported pose, in order: the console's TUM equals the tracker's.
  const std::vector<TimedPose> tracked = read_tum(dir / "out/trajectory.txt");
  const std::vector<TimedPose> received = read_tum(dir / "rec/trajectory.txt");
  CHECK(tracked.size() == static_cast<std::size_t>(summary_number(dir / "out", "tracked_frames")));
  REQUIRE(received.size() == tracked.size());
  for (std::size_t i = 0; i < tracked.size(); ++i) {
    CAPTURE(i);
    CHECK(received[i].timestamp_s == doctest::Approx(tracked[i].timestamp_s).epsilon(1e-9));
    CHECK((received[i].T_model_camera.matrix() - tracked[i].T_model_camera.matrix()).norm() < 1e-6);
  }
  CHECK(console_log.find("120 poses (0 out of order)") != std::string::npos);  // lost frames too
  // Nothing allocates per frame on any of the three threads after start.
  CHECK(summary_number(dir / "out", "tracking_thread_allocations") == 0);
  CHECK(summary_number(dir / "out", "texture_thread_allocations") == 0);
  CHECK(summary_number(dir / "out", "texture_thread_nice") >= platform::kBackgroundWorkerNice);
  CHECK(summary_number(dir / "out", "stream_sink_thread_allocations") == 0);
  CHECK(summary_number(dir / "out", "stream_dropped_messages") == 0);
  CHECK(console_log.find("0 buffers rejected") != std::string::npos);

  // The texture against the simulator's frames.
  auto seq = load_sequence(dir / "seq");
  REQUIRE(seq.ok());
  const std::vector<std::uint8_t> ply =
      ply_face_rgb(test::read_file_bytes(dir / "rec/textured_mesh.ply"), seq->mesh);
  const Reference ref =
      reference_texture(seq->mesh, seq->config.K, rgb, labels, sim_report->groundtruth);
  double abs_err = 0;
  std::int64_t compared = 0, coloured = 0, seen3 = 0;
  for (std::size_t t = 0; t < ref.frames.size(); ++t) {
    const bool has_colour = !(ply[3 * t] == 128 && ply[3 * t + 1] == 128 && ply[3 * t + 2] == 128);
    coloured += has_colour ? 1 : 0;
    if (ref.frames[t] < 3) continue;
    ++seen3;
    if (!has_colour) continue;
    ++compared;
    for (int c = 0; c < 3; ++c) {
      const double want =
          ref.sum[3 * t + static_cast<std::size_t>(c)] / static_cast<double>(ref.pixels[t]);
      abs_err += std::abs(want - ply[3 * t + static_cast<std::size_t>(c)]);
    }
  }
  const double mae = compared ? abs_err / (3.0 * static_cast<double>(compared)) : 1e9;
  MESSAGE("texture: " << compared << " triangles seen >= 3 times compared (of " << seen3 << "), "
                      << coloured << " coloured, mean abs error " << mae << " / 255");
  CHECK(compared >= 0.9 * static_cast<double>(seen3));
  CHECK(compared > 1000);
  CHECK(mae < 20.0);
}

TEST_CASE(
    "console_e2e: a console that connects and never reads does not slow tracking or grow memory" *
    doctest::timeout(test::budget_s(300)) * doctest::test_suite("serial")) {
  const auto dir = test::scratch_dir("console_slow");
  REQUIRE(run(bin("scopetrack-sim") +
              " --scenario orbit --frames 100 --size 480x270 --seed 3 --out " + q(dir / "seq") +
              " > /dev/null") == 0);
  // Without a console (the link runs, nobody listens).
  // Default texturing (keyframes).
  const std::string base = bin("scopetrack") + " --sequence " + q(dir / "seq") + " --stream unix:";
  // Twice: the larger p99 of the two is the noise floor of this machine.
  for (const char* out : {"none", "none2"})
    REQUIRE(run(base + socket_path(out) + " --out " + q(dir / out) + " > /dev/null 2>&1") == 0);
  // With a console that connects and never reads.
  const std::string sock = socket_path("slow");
  std::string slow_cmd = "(";
  slow_cmd +=
      base + sock + " --stream-wait 1 --out " + q(dir / "slow") + " > " + q(dir / "slow.log");
  slow_cmd += " 2>&1; echo $? > " + q(dir / "slow.code") + ") &";
  REQUIRE(run(slow_cmd) == 0);
  platform::Endpoint ep;
  REQUIRE(platform::parse_endpoint("unix:" + sock, &ep, nullptr));
  platform::Fd fd;
  std::string err;
  const std::int64_t deadline = platform::monotonic_ns() + 30'000'000'000ll;
  while (!fd.valid() && platform::monotonic_ns() < deadline) {
    fd = platform::connect_to(ep, &err);
    if (!fd.valid()) platform::sleep_until_ns(platform::monotonic_ns() + 50'000'000);
  }
  REQUIRE_MESSAGE(fd.valid(), err);
  while (!std::filesystem::exists(dir / "slow.code") &&
         platform::monotonic_ns() < deadline + 60'000'000'000ll)
    platform::sleep_until_ns(platform::monotonic_ns() + 50'000'000);
  INFO(test::read_file_bytes(dir / "slow.log"));
  REQUIRE(std::filesystem::exists(dir / "slow.code"));
  platform::sleep_until_ns(platform::monotonic_ns() +
                           50'000'000);  // the code file is written before it is closed
  CHECK(std::atoi(test::read_file_bytes(dir / "slow.code").c_str()) == 0);

  const double p99_none = std::max(summary_number(dir / "none", "p99_latency_ms"),
                                   summary_number(dir / "none2", "p99_latency_ms"));
  const double p99_slow = summary_number(dir / "slow", "p99_latency_ms");
  const double rss_none = summary_number(dir / "none", "peak_rss_mb");
  const double rss_slow = summary_number(dir / "slow", "peak_rss_mb");
  const double dropped = summary_number(dir / "slow", "stream_dropped_messages");
  MESSAGE("p99 latency: no console " << p99_none << " ms, console never reading " << p99_slow
                                     << " ms; peak RSS " << rss_none << " / " << rss_slow
                                     << " MB; messages dropped for it " << dropped);
  CHECK(summary_number(dir / "slow", "frames") == 100);
  CHECK(summary_number(dir / "slow", "tracking_thread_allocations") == 0);
  CHECK(summary_number(dir / "slow", "stream_consoles_accepted") == 1);
  const double textured = summary_number(dir / "slow", "texture_frames");
  CHECK(textured >= 1);  // frame 0 and the keyframes
  CHECK(textured < 100);
  // 100 poses fit in the console's buffer: drops under a real backlog are
  // proven in test_console_sink.cpp (40,000 poses); here: no effect on tracking.
  // Judged on the mean latency: the p99 of 100 frames is their second
  // slowest, one preemption on a shared machine (a clean-clone CI run gave
  // 32.6 against 21.4 ms with a mean of 13.6 ms). A console that held up
  // the tracking thread would raise every frame's latency, and the mean.
  const double mean_none = std::max(summary_number(dir / "none", "mean_latency_ms"),
                                    summary_number(dir / "none2", "mean_latency_ms"));
  const double mean_slow = summary_number(dir / "slow", "mean_latency_ms");
  MESSAGE("mean latency: no console " << mean_none << " ms, console never reading " << mean_slow << " ms");
  CHECK(mean_slow <= std::max(1.5 * mean_none, mean_none + 3.0));  // noise of a shared machine
  CHECK(p99_slow <= std::max(3.0 * p99_none, p99_none + 30.0));    // no frame held up for long
  // Memory stays flat. Under AddressSanitizer peak RSS also holds its
  // quarantine of freed blocks and shadow memory, which vary by tens of MB
  // between identical runs: there the bound is wider (the Release build
  // keeps 16 MB).
#if defined(__SANITIZE_ADDRESS__)
  constexpr double kRssMarginMb = 64.0;
#else
  constexpr double kRssMarginMb = 16.0;
#endif
  CHECK(rss_slow - rss_none < kRssMarginMb);
}

TEST_CASE(
    "console_e2e: scopetrack-console refuses an oversized or garbage stream with a clear error" *
    doctest::timeout(test::budget_s(60))) {
  const auto dir = test::scratch_dir("console_bad_stream");
  struct Case {
    const char* name;
    std::vector<std::uint8_t> bytes;
    const char* expect;
  };
  const std::vector<Case> cases = {
      {"oversized", {0xff, 0xff, 0xff, 0x7f, 1, 2, 3, 4}, "oversized"},
      {"garbage",
       {12, 0, 0, 0, 'n', 'o', 't', ' ', 'a', ' ', 's', 't', 'r', 'e', 'a', 'm'},
       "rejected a buffer"},
  };
  for (const Case& c : cases) {
    CAPTURE(c.name);
    platform::Endpoint ep;
    REQUIRE(platform::parse_endpoint("unix:" + socket_path(c.name), &ep, nullptr));
    std::string err;
    platform::Fd server = platform::listen_on(ep, 1, nullptr, &err);
    REQUIRE_MESSAGE(server.valid(), err);
    const auto log = dir / (std::string(c.name) + ".log");
    std::string cmd = "(";
    cmd += bin("scopetrack-console") + " unix:" + ep.path + " > " + q(log) + " 2>&1; echo $? > " +
           q(dir / (std::string(c.name) + ".code")) + ") &";
    REQUIRE(run(cmd) == 0);
    platform::Fd con;
    const std::int64_t deadline = platform::monotonic_ns() + 20'000'000'000ll;
    while (!con.valid() && platform::monotonic_ns() < deadline) {
      con = platform::accept_client(server.get());
      if (!con.valid()) platform::sleep_until_ns(platform::monotonic_ns() + 10'000'000);
    }
    REQUIRE(con.valid());
    REQUIRE(::send(con.get(), c.bytes.data(), c.bytes.size(), MSG_NOSIGNAL) ==
            static_cast<ssize_t>(c.bytes.size()));
    con.reset();  // end of stream
    const auto code = dir / (std::string(c.name) + ".code");
    while (!std::filesystem::exists(code) && platform::monotonic_ns() < deadline)
      platform::sleep_until_ns(platform::monotonic_ns() + 20'000'000);
    platform::sleep_until_ns(platform::monotonic_ns() + 50'000'000);
    const std::string out = test::read_file_bytes(log);
    INFO(out);
    CHECK(out.find(c.expect) != std::string::npos);
    CHECK(out.find("0 poses") != std::string::npos);
    if (std::string(c.name) == "oversized")
      CHECK(std::atoi(test::read_file_bytes(code).c_str()) == 1);
    ::unlink(ep.path.c_str());
  }
}
