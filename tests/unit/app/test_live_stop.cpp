// scopetrack --camera's run (firmware_app/camera_command.h, run_live) with
// a scripted live source in place of the camera: a SIGINT or SIGTERM sent
// to the process mid-run stops it after the current frame, with every
// frame's row and summary.json written (stop_signal, no error), exit 0 and
// no allocation on the tracking thread; a source that ends by itself gives
// stop_signal 0; a source that fails gives exit 1 with its error.
#include <doctest/doctest.h>

#include <pthread.h>
#include <unistd.h>

#include <atomic>
#include <csignal>
#include <fstream>
#include <string>
#include <thread>

#include "firmware_app/camera_command.h"
#include "platform/clock.h"
#include "support/support.h"
#include "support/track_scene.h"

using namespace st;
using namespace st::test;
using st::app::LiveRun;
using st::app::run_live;

namespace {

// The orbit back and forth, one frame every 5 ms, like a camera: until
// stop(), or for `frames` frames when that is not negative, or failing at
// frame `fail_at`.
class ScriptedCamera final : public FrameSource {
 public:
  ScriptedCamera(const RenderedOrbit& orbit, int frames, int fail_at)
      : orbit_(orbit), frames_(frames), fail_at_(fail_at) {}
  Status start() override {
    t_next_ns_ = platform::monotonic_ns();
    return Status::Ok();
  }
  void next(SourceFrame* out) override {
    const int i = delivered_.load();
    if (stopped_.load() || (frames_ >= 0 && i >= frames_)) {
      out->kind = SourceFrame::Kind::kEnd;
      return;
    }
    if (i == fail_at_) {
      out->kind = SourceFrame::Kind::kError;
      return;
    }
    t_next_ns_ += 5'000'000;
    platform::sleep_until_ns(t_next_ns_);
    const int n = static_cast<int>(orbit_.frames.size()), period = 2 * (n - 1), k = i % period;
    out->kind = SourceFrame::Kind::kFrame;
    out->frame = FrameRef{};
    out->frame.index = i;
    out->frame.y = orbit_.frames[static_cast<std::size_t>(k < n ? k : period - k)].cview();
    out->timestamp_s = i * 0.005;
    out->t_ready_ns = t_next_ns_;
    delivered_.store(i + 1);
  }
  void release() override {}
  void stop() override { stopped_.store(true); }
  bool paced() const override { return true; }
  std::string error() const override { return "frame " + std::to_string(fail_at_) + ": the capture failed"; }
  int delivered() const { return delivered_.load(); }

 private:
  const RenderedOrbit& orbit_;
  int frames_, fail_at_;
  std::int64_t t_next_ns_ = 0;
  std::atomic<int> delivered_{0};
  std::atomic<bool> stopped_{false};
};

// SIGINT and SIGTERM blocked in this thread (and the threads it starts)
// for the scope, as scopetrack's main thread blocks them.
class BlockedStopSignals {
 public:
  BlockedStopSignals() {
    sigemptyset(&set);
    sigaddset(&set, SIGINT);
    sigaddset(&set, SIGTERM);
    pthread_sigmask(SIG_BLOCK, &set, &old_);
  }
  ~BlockedStopSignals() {
    sigset_t pending;
    sigpending(&pending);
    CHECK_FALSE(sigismember(&pending, SIGINT));
    CHECK_FALSE(sigismember(&pending, SIGTERM));
    pthread_sigmask(SIG_SETMASK, &old_, nullptr);
  }
  sigset_t set;

 private:
  sigset_t old_;
};

LiveRun live_run(const RenderedOrbit& orbit, FrameSource* source, const std::filesystem::path& out) {
  LiveRun run;
  run.config = small_tracker_config(orbit.K);
  run.calibration.width = orbit.K.width;
  run.calibration.height = orbit.K.height;
  run.calibration.K = orbit.K;
  run.calibration.T_camera_model_init = orbit.T_camera_model[0];
  run.mesh = &orbit.mesh;
  run.calibration_path = "scripted.yaml";
  run.out_dir = out.string();
  run.source_label = "a scripted camera";
  run.source = source;
  run.print_status = false;
  return run;
}

int csv_rows(const std::filesystem::path& file) {
  std::ifstream f(file);
  int rows = -1;  // the header
  for (std::string line; std::getline(f, line);) rows += line.empty() ? 0 : 1;
  return rows;
}

}  // namespace

TEST_CASE("live run: SIGINT or SIGTERM mid-run stops after the frame, rows and summary written, exit 0" *
          doctest::timeout(120)) {
  const RenderedOrbit& orbit = liver_orbit40();
  for (const int sig : {SIGINT, SIGTERM}) {
    CAPTURE(sig);
    const auto out = scratch_dir("live-stop-" + std::to_string(sig));
    BlockedStopSignals blocked;
    ScriptedCamera camera(orbit, -1, -1);
    // The signal is sent to the process, as a shell's Ctrl-C or a `kill`
    // is, once 60 frames were delivered.
    std::thread sender([&camera, sig] {
      while (camera.delivered() < 60) platform::sleep_until_ns(platform::monotonic_ns() + 1'000'000);
      ::kill(::getpid(), sig);
    });
    const int exit_code = run_live(live_run(orbit, &camera, out), blocked.set);
    sender.join();
    CHECK(exit_code == 0);
    const int delivered = camera.delivered();
    CHECK(delivered >= 60);
    CHECK(delivered < 60 + 200);  // stopped within a second of the signal
    CHECK(summary_number(out, "stop_signal") == sig);
    CHECK(summary_number(out, "frames") == delivered);
    CHECK(summary_number(out, "tracking_thread_allocations") == 0);
    CHECK(summary_number(out, "lost_frames") == 0);
    CHECK(csv_rows(out / "frames.csv") == delivered);
    CHECK(read_file_bytes(out / "summary.json").find("\"error\"") == std::string::npos);
  }
}

TEST_CASE("live run: a source that ends gives stop_signal 0, one that fails gives exit 1 and its error" *
          doctest::timeout(120)) {
  const RenderedOrbit& orbit = liver_orbit40();
  BlockedStopSignals blocked;
  {
    const auto out = scratch_dir("live-end");
    ScriptedCamera camera(orbit, 50, -1);
    CHECK(run_live(live_run(orbit, &camera, out), blocked.set) == 0);
    CHECK(summary_number(out, "stop_signal") == 0);
    CHECK(summary_number(out, "frames") == 50);
    CHECK(csv_rows(out / "frames.csv") == 50);
  }
  {
    const auto out = scratch_dir("live-fail");
    ScriptedCamera camera(orbit, -1, 30);
    CHECK(run_live(live_run(orbit, &camera, out), blocked.set) == 1);
    CHECK(summary_number(out, "frames") == 30);
    const std::string summary = read_file_bytes(out / "summary.json");
    CHECK(summary.find("frame 30: the capture failed") != std::string::npos);
  }
}
