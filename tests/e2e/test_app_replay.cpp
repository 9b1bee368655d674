// The replay pipeline (firmware_app/replay.h) with stand-in processors: what the
// application writes, that the pipeline itself allocates nothing on the
// tracking thread, and what happens when the video breaks off.
#include <doctest/doctest.h>

#include <sys/resource.h>

#include <atomic>
#include <csignal>
#include <fstream>
#include <sstream>

#include "hal/storage/file_io.h"
#include "firmware_app/replay.h"
#include "platform/clock.h"
#include "support/shell.h"
#include "support/support.h"
#include "support/tiny_sequence.h"
#include "tools/eval/eval_report.h"

using namespace st;
using st::test::summary_number;

namespace {

// Reports the ground-truth pose: what a perfect tracker would do. Lost every
// lost_every-th frame (0: never). Allocates nothing per frame.
class OracleProcessor : public FrameProcessor {
 public:
  OracleProcessor(const std::vector<TimedPose>& gt, int lost_every) : gt_(gt), lost_every_(lost_every) {}
  void start() override { started_ = true; }
  TrackResult step(const FrameRef& f) override {
    TrackResult r;
    const int frame = f.index;
    luma_sum_ += f.y(0, 0);
    chroma_frames_ += f.u.empty() || f.v.empty() ? 0 : 1;
    const bool lost = lost_every_ > 0 && frame % lost_every_ == lost_every_ - 1;
    r.state = frame == 0 ? TrackState::kInitialised : lost ? TrackState::kLost : TrackState::kTracking;
    r.pose_valid = !lost;
    r.T_camera_model = gt_[static_cast<std::size_t>(frame)].T_model_camera.inverse();
    r.inliers = 100 + frame;
    ++steps_;
    return r;
  }
  void stop() override { stopped_ = true; }
  bool started_ = false, stopped_ = false;
  int steps_ = 0;
  long luma_sum_ = 0;
  int chroma_frames_ = 0;  // frames handed over with both chroma planes

 private:
  const std::vector<TimedPose>& gt_;
  int lost_every_;
};

// Allocates once per frame: the count must see it.
class LeakyProcessor : public OracleProcessor {
 public:
  using OracleProcessor::OracleProcessor;
  TrackResult step(const FrameRef& f) override {
    kept_.push_back(std::make_unique<int>(f.index));
    return OracleProcessor::step(f);
  }
  std::vector<std::unique_ptr<int>> kept_{};
};

// Counts the frames it sees; at frame stop_at (if >= 0) asks the loop to
// stop as a signal would.
class StopObserver final : public FrameObserver {
 public:
  void frame_done(const FrameRef& f, const TrackResult&, double) override {
    ++frames;
    if (f.index == stop_at) stop.store(SIGTERM);
  }
  int frames = 0, stop_at = -1;
  std::atomic<int> stop{0};
};

template <class R>
std::string why(const R& r) {
  return r.ok() ? std::string() : r.message();
}

std::vector<std::string> lines_of(const std::filesystem::path& p) {
  std::ifstream f(p);
  std::vector<std::string> out;
  for (std::string line; std::getline(f, line);)
    if (!line.empty() && line[0] != '#') out.push_back(line);
  return out;
}

LoadedSequence load(const std::filesystem::path& dir) {
  auto s = load_sequence(dir);
  REQUIRE_MESSAGE(s.ok(), why(s));
  return std::move(s.value());
}

}  // namespace

TEST_CASE("app_replay: 200 frames, every row written, zero allocations on the tracking thread") {
  const auto dir = test::scratch_dir("app_replay_200");
  test::write_tiny_sequence(dir / "seq", 200);
  const LoadedSequence seq = load(dir / "seq");
  OracleProcessor oracle(seq.groundtruth, 10);
  ReplayOptions opt;
  opt.out_dir = dir / "out";
  opt.summary_extra = {{"use_mask", 1}};
  auto stats = run_replay(seq, oracle, opt);
  REQUIRE_MESSAGE(stats.ok(), why(stats));
  CHECK(stats->error.empty());
  CHECK(oracle.started_);
  CHECK(oracle.stopped_);
  CHECK(oracle.steps_ == 200);
  CHECK(oracle.luma_sum_ > 0);  // the pixels reached the processor
  CHECK(oracle.chroma_frames_ == 200);  // with their chroma (4:2:0 video)
  CHECK(stats->frames == 200);
  CHECK(stats->lost == 20);
  CHECK(stats->tracked == 180);
  CHECK(stats->initialised == 1);
  CHECK(stats->tracking_thread_allocations == 0);
  CHECK(stats->fps > 0);

  const auto csv = lines_of(opt.out_dir / "frames.csv");
  REQUIRE(csv.size() == 201);
  CHECK(csv[0] == "frame,timestamp,state,inliers,latency_ms,map_points,keyframes");
  CHECK(csv[1].rfind("0,0,initialised,100,", 0) == 0);
  CHECK(csv[10].rfind("9,0.36,lost,109,", 0) == 0);
  CHECK(lines_of(opt.out_dir / "trajectory.txt").size() == 180);
  CHECK(summary_number(opt.out_dir, "frames") == 200);
  CHECK(summary_number(opt.out_dir, "lost_frames") == 20);
  CHECK(summary_number(opt.out_dir, "tracking_thread_allocations") == 0);
  CHECK(summary_number(opt.out_dir, "use_mask") == 1);
  CHECK(summary_number(opt.out_dir, "mean_latency_ms") > 0);
  CHECK(summary_number(opt.out_dir, "p99_latency_ms") > 0);
  CHECK(summary_number(opt.out_dir, "p99_latency_ms") <= summary_number(opt.out_dir, "max_latency_ms"));
  CHECK(summary_number(opt.out_dir, "peak_rss_mb") > 0);

  // The evaluator reads the output: the oracle's poses are exact.
  auto report = evaluate_run(dir / "seq", opt.out_dir);
  REQUIRE_MESSAGE(report.ok(), why(report));
  CHECK(report->result.init_ok);
  CHECK(report->result.reported_frames == 180);
  CHECK(report->result.tre_median_px < 1e-6);
  CHECK(report->frames_in_csv == 200);
}

TEST_CASE("app_replay: a processor that allocates per frame is counted") {
  const auto dir = test::scratch_dir("app_replay_leaky");
  test::write_tiny_sequence(dir / "seq", 30);
  const LoadedSequence seq = load(dir / "seq");
  LeakyProcessor leaky(seq.groundtruth, 0);
  ReplayOptions opt;
  opt.out_dir = dir / "out";
  auto stats = run_replay(seq, leaky, opt);
  REQUIRE(stats.ok());
  CHECK(stats->tracking_thread_allocations >= 30);
  CHECK(summary_number(opt.out_dir, "tracking_thread_allocations") >= 30);
}

TEST_CASE("app_replay: a video cut mid-frame ends with an error naming the frame, rows intact") {
  const auto dir = test::scratch_dir("app_replay_cut");
  test::write_tiny_sequence(dir / "seq", 40);
  const auto video = dir / "seq" / "video.y4m";
  const LoadedSequence seq = load(dir / "seq");
  // Cut in the middle of frame 25's pixels.
  const std::size_t record = seq.video_header.frame_bytes() + 6;
  std::filesystem::resize_file(video, seq.video_header.header_bytes + 25 * record + 6 + 1000);
  OracleProcessor oracle(seq.groundtruth, 0);
  ReplayOptions opt;
  opt.out_dir = dir / "out";
  auto stats = run_replay(seq, oracle, opt);
  REQUIRE(stats.ok());
  CHECK(stats->frames == 25);
  CHECK(stats->error.find("frame 25 is truncated") != std::string::npos);
  CHECK(lines_of(opt.out_dir / "frames.csv").size() == 26);
  CHECK(lines_of(opt.out_dir / "trajectory.txt").size() == 25);
  const std::string summary = test::read_file_bytes(opt.out_dir / "summary.json");
  CHECK(summary.find("\"error\": \"") != std::string::npos);
  CHECK(summary.find("frame 25 is truncated") != std::string::npos);
  CHECK(summary_number(opt.out_dir, "frames") == 25);
  // What was written still evaluates.
  auto report = evaluate_run(dir / "seq", opt.out_dir);
  REQUIRE_MESSAGE(report.ok(), why(report));
  CHECK(report->result.reported_frames == 25);
}

TEST_CASE("app_replay: --realtime paces frames to the sequence fps") {
  const auto dir = test::scratch_dir("app_replay_rt");
  test::write_tiny_sequence(dir / "seq", 12);  // 25 fps: frame 11 at 0.44 s
  const LoadedSequence seq = load(dir / "seq");
  OracleProcessor oracle(seq.groundtruth, 0);
  ReplayOptions opt;
  opt.out_dir = dir / "out";
  opt.realtime = true;
  const std::int64_t t0 = platform::monotonic_ns();
  auto stats = run_replay(seq, oracle, opt);
  const double secs = static_cast<double>(platform::monotonic_ns() - t0) * 1e-9;
  REQUIRE(stats.ok());
  CHECK(stats->frames == 12);
  CHECK(secs >= 0.43);
  CHECK(stats->fps < 30.0);
  CHECK(summary_number(opt.out_dir, "realtime") == 1);
}

TEST_CASE("app_replay: an unreadable output folder or video fails before tracking") {
  const auto dir = test::scratch_dir("app_replay_bad");
  test::write_tiny_sequence(dir / "seq", 3);
  const LoadedSequence seq = load(dir / "seq");
  OracleProcessor oracle(seq.groundtruth, 0);
  ReplayOptions opt;
  REQUIRE(write_file(dir / "plainfile", "x").ok());
  opt.out_dir = dir / "plainfile" / "out";  // below a regular file
  auto stats = run_replay(seq, oracle, opt);
  REQUIRE_FALSE(stats.ok());
  CHECK(stats.message().find("cannot create output folder") != std::string::npos);
  CHECK_FALSE(oracle.started_);

  LoadedSequence broken = seq;
  broken.video_path = dir / "seq" / "missing.y4m";
  opt.out_dir = dir / "out";
  auto stats2 = run_replay(broken, oracle, opt);
  REQUIRE_FALSE(stats2.ok());
  CHECK(stats2.message().find("missing.y4m") != std::string::npos);
}

TEST_CASE("app_replay: a disk that fills mid-run: every frame tracked and observed, the error kept for "
          "summary.json") {
  const auto dir = test::scratch_dir("app_replay_full");
  test::write_tiny_sequence(dir / "seq", 400);
  const LoadedSequence seq = load(dir / "seq");
  OracleProcessor oracle(seq.groundtruth, 0);
  StopObserver observer;
  ReplayOptions opt;
  opt.out_dir = dir / "out";
  opt.observer = &observer;
  // A file-size limit of 4 KB for this process: trajectory.txt and
  // frames.csv (about 10 and 13 KB for 400 rows) reach it mid-run, as a
  // filling disk would; summary.json stays below it.
  rlimit old{};
  REQUIRE(::getrlimit(RLIMIT_FSIZE, &old) == 0);
  rlimit small = old;
  small.rlim_cur = 4 * 1024;
  const auto old_handler = std::signal(SIGXFSZ, SIG_IGN);
  REQUIRE(::setrlimit(RLIMIT_FSIZE, &small) == 0);
  auto stats = run_replay(seq, oracle, opt);
  ::setrlimit(RLIMIT_FSIZE, &old);
  std::signal(SIGXFSZ, old_handler);
  REQUIRE_MESSAGE(stats.ok(), why(stats));
  CHECK(stats->frames == 400);  // tracking went on
  CHECK(observer.frames == 400);  // and so did the console link's side
  CHECK(stats->tracking_thread_allocations == 0);
  CHECK(stats->error.find("writing the tracker output") != std::string::npos);
  CHECK(std::filesystem::file_size(opt.out_dir / "trajectory.txt") <= 4 * 1024);
  CHECK(std::filesystem::file_size(opt.out_dir / "frames.csv") <= 4 * 1024);
  CHECK(lines_of(opt.out_dir / "frames.csv").size() > 10);  // the rows before the limit
  const std::string summary = test::read_file_bytes(opt.out_dir / "summary.json");
  CHECK(summary.find("writing the tracker output") != std::string::npos);
}

TEST_CASE("app_replay: a stop request ends the replay after the current frame, its output whole") {
  const auto dir = test::scratch_dir("app_replay_stop");
  test::write_tiny_sequence(dir / "seq", 200);
  const LoadedSequence seq = load(dir / "seq");
  OracleProcessor oracle(seq.groundtruth, 0);
  StopObserver observer;
  observer.stop_at = 49;
  ReplayOptions opt;
  opt.out_dir = dir / "out";
  opt.observer = &observer;
  opt.stop_signal = &observer.stop;
  auto stats = run_replay(seq, oracle, opt);
  REQUIRE_MESSAGE(stats.ok(), why(stats));
  CHECK(stats->frames == 50);
  CHECK(stats->stop_signal == SIGTERM);
  CHECK(stats->error.empty());
  CHECK(oracle.stopped_);
  CHECK(lines_of(opt.out_dir / "frames.csv").size() == 51);
  CHECK(lines_of(opt.out_dir / "trajectory.txt").size() == 50);
  CHECK(summary_number(opt.out_dir, "frames") == 50);
  CHECK(summary_number(opt.out_dir, "stop_signal") == SIGTERM);
}

TEST_CASE("app_replay: SIGINT and SIGTERM mid-replay: exit 130 and 143, the frames so far written whole" *
          doctest::timeout(test::budget_s(120)) * doctest::test_suite(test::kProcessSuite)) {
  const auto dir = test::scratch_dir("app_replay_signal");
  // 200 frames: about 7 s paced at 30 frames/s (--realtime).
  REQUIRE(test::run_shell(test::bin_command("scopetrack-sim") + " --scenario orbit --frames 200 --size 480x270 --out " +
                          test::shell_quoted(dir / "seq") + " > /dev/null") == 0);
  for (const auto& [name, number] : {std::pair{"INT", SIGINT}, std::pair{"TERM", SIGTERM}}) {
    CAPTURE(name);
    const auto out = dir / (std::string("out-") + name);
    // Starts the paced replay, waits for 10 rows of frames.csv, signals it,
    // writes its exit status.
    const std::string script =
        "app=" + test::bin_command("scopetrack") + "\n"
        "\"$app\" --sequence " + test::shell_quoted(dir / "seq") + " --out " + test::shell_quoted(out) +
        " --realtime > /dev/null 2> " + test::shell_quoted(dir / "err") + " &\n"
        "pid=$!\n"
        "for i in $(seq 600); do\n"
        "  [ \"$(cat " + test::shell_quoted(out / "frames.csv") + " 2>/dev/null | wc -l)\" -gt 10 ] && break\n"
        "  sleep 0.05\n"
        "done\n"
        "kill -" + name + " $pid\n"
        "wait $pid\n"
        "echo $? > " + test::shell_quoted(dir / "code") + "\n";
    REQUIRE(write_file(dir / "run.sh", script).ok());
    REQUIRE(test::run_shell("bash " + test::shell_quoted(dir / "run.sh")) == 0);
    CHECK(std::stoi(test::read_file_bytes(dir / "code")) == 128 + number);
    CHECK(test::read_file_bytes(dir / "err").find(std::string("stopped by SIG") + name) != std::string::npos);
    const double frames = summary_number(out, "frames");
    CHECK(frames >= 10);
    CHECK(frames < 200);
    CHECK(summary_number(out, "stop_signal") == number);
    CHECK(static_cast<double>(lines_of(out / "frames.csv").size()) == frames + 1);
  }
}
