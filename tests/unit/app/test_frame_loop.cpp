// The one frame loop (firmware_app/frame_loop.h) that replays and the live
// camera share: with a scripted source and processor, every frame is
// counted by state, the writer gets one row each, a source error ends the
// run with the frames before it intact, latency follows the source's pace,
// and the loop allocates nothing. And the Y4M source
// (hal/capture/y4m_capture.h): stop() ends a capture waiting for its ring.
#include <doctest/doctest.h>

#include <array>
#include <chrono>
#include <fstream>
#include <future>
#include <string>
#include <vector>

#include "firmware_app/frame_loop.h"
#include "hal/capture/y4m_capture.h"
#include "hal/storage/y4m_writer.h"
#include "platform/clock.h"
#include "support/support.h"

using namespace st;

namespace {

// frames frames of a 8x8 image, then kEnd or kError; t_ready_ns = now.
class ScriptedSource final : public FrameSource {
 public:
  ScriptedSource(int frames, bool error_at_end, bool paced)
      : frames_(frames), error_at_end_(error_at_end), paced_(paced) {}
  Status start() override { return Status::Ok(); }
  void next(SourceFrame* out) override {
    if (held_) ++misuse_;  // next() before release() of the last frame
    if (i_ >= frames_) {
      out->kind = error_at_end_ ? SourceFrame::Kind::kError : SourceFrame::Kind::kEnd;
      return;
    }
    out->kind = SourceFrame::Kind::kFrame;
    out->frame.index = i_;
    out->frame.y = pixels_.cview();
    out->timestamp_s = i_ * 0.25;
    out->t_ready_ns = platform::monotonic_ns() - (paced_ ? 5'000'000 : 0);  // paced: ready 5 ms ago
    ++i_;
    held_ = true;
  }
  void release() override { held_ = false; }
  void stop() override {}
  bool paced() const override { return paced_; }
  std::string error() const override { return "frame " + std::to_string(frames_) + ": cut short"; }
  int misuse() const { return misuse_; }

 private:
  int frames_, i_ = 0, misuse_ = 0;
  bool error_at_end_, paced_, held_ = false;
  Image<std::uint8_t> pixels_{8, 8};
};

// Frame i: initialised (0), lost every third frame, else tracking.
class ScriptedProcessor final : public FrameProcessor {
 public:
  void start() override { ++starts; }
  TrackResult step(const FrameRef& f) override {
    TrackResult r;
    r.state = f.index == 0 ? TrackState::kInitialised : f.index % 3 == 0 ? TrackState::kLost : TrackState::kTracking;
    r.pose_valid = r.state != TrackState::kLost;
    r.inliers = r.pose_valid ? 100 : 0;
    return r;
  }
  void stop() override { ++stops; }
  int starts = 0, stops = 0;
};

class CountingObserver final : public FrameObserver {
 public:
  void frame_done(const FrameRef&, const TrackResult&, double latency_ms) override {
    ++frames;
    min_latency_ms = std::min(min_latency_ms, latency_ms);
  }
  int frames = 0;
  double min_latency_ms = 1e9;
};

}  // namespace

TEST_CASE("frame loop: every frame counted by state and written, a source error keeps what came before") {
  const auto dir = test::scratch_dir("frame_loop");
  ScriptedSource source(10, true, true);
  ScriptedProcessor processor;
  CountingObserver observer;
  RunWriter writer;
  REQUIRE(writer.open(dir).ok());
  writer.start({});
  LoopStatus status;
  FrameLoop loop;
  loop.source = &source;
  loop.processor = &processor;
  loop.writer = &writer;
  loop.observer = &observer;
  loop.status = &status;
  loop.run();
  REQUIRE(writer.finish().ok());
  CHECK(processor.starts == 1);
  CHECK(processor.stops == 1);
  CHECK(source.misuse() == 0);
  CHECK(loop.source_error);
  CHECK(loop.stats.frames == 10);
  CHECK(loop.stats.initialised == 1);
  CHECK(loop.stats.lost == 3);  // frames 3, 6, 9
  CHECK(loop.stats.tracked == 7);
  CHECK(loop.stats.tracking_thread_allocations == 0);
  CHECK(loop.stats.wall_s > 0);
  CHECK(observer.frames == 10);
  CHECK(observer.min_latency_ms >= 5.0);  // paced: from when the frame was ready
  CHECK(status.frames.load() == 10);
  CHECK(status.lost.load() == 3);
  CHECK(status.done.load());
  // frames.csv: the header and one row a frame, timestamps from the source.
  std::ifstream csv(dir / "frames.csv");
  std::vector<std::string> lines;
  for (std::string line; std::getline(csv, line);) lines.push_back(line);
  REQUIRE(lines.size() == 11);
  CHECK(lines[4].rfind("3,0.75,lost,0,", 0) == 0);
  loop.fill_timing();
  loop.stats.error = source.error();
  const std::string json = format_run_summary(loop.stats, false, {{"width", 8}});
  CHECK(json.find("\"frames\": 10") != std::string::npos);
  CHECK(json.find("\"width\": 8") != std::string::npos);
  CHECK(json.find("\"error\": \"frame 10: cut short\"") != std::string::npos);
}

TEST_CASE("frame loop: a source read as fast as possible counts latency from when the tracker could take it") {
  ScriptedSource source(5, false, false);
  ScriptedProcessor processor;
  CountingObserver observer;
  FrameLoop loop;
  loop.source = &source;
  loop.processor = &processor;
  loop.observer = &observer;
  loop.run();
  CHECK_FALSE(loop.source_error);
  CHECK(loop.stats.frames == 5);
  CHECK(observer.min_latency_ms < 5.0);
}

TEST_CASE("y4m capture: stop() ends a capture that waits for its ring, and the stream ends cleanly") {
  const auto dir = test::scratch_dir("y4m_capture_stop");
  Y4mWriter w;
  Y4mHeader h;
  h.width = 16;
  h.height = 8;
  REQUIRE(w.open(dir / "v.y4m", h).ok());
  Image<std::uint8_t> Y(16, 8), U(8, 4), V(8, 4);
  for (int f = 0; f < 20; ++f) REQUIRE(w.write(Y.cview(), U.cview(), V.cview()).ok());
  REQUIRE(w.close().ok());

  Y4mCapture capture;
  REQUIRE(capture.open(dir / "v.y4m", 2, 25.0, 0.0).ok());
  CHECK_FALSE(capture.paced());
  REQUIRE(capture.start().ok());
  SourceFrame f;
  capture.next(&f);
  REQUIRE(f.kind == SourceFrame::Kind::kFrame);
  CHECK(f.frame.index == 0);
  capture.release();
  capture.next(&f);
  CHECK(f.frame.index == 1);
  CHECK(f.timestamp_s == doctest::Approx(0.04));
  // Frame 1 is held and the ring has two slots: the capture thread waits.
  auto stopped = std::async(std::launch::async, [&] { capture.stop(); });
  REQUIRE(stopped.wait_for(std::chrono::seconds(10)) == std::future_status::ready);
  CHECK(capture.frames_read() < 20);

  Y4mCapture whole;
  REQUIRE(whole.open(dir / "v.y4m", 4, 25.0, 0.0).ok());
  REQUIRE(whole.start().ok());
  int frames = 0;
  for (;;) {
    whole.next(&f);
    if (f.kind != SourceFrame::Kind::kFrame) break;
    ++frames;
    whole.release();
  }
  CHECK(f.kind == SourceFrame::Kind::kEnd);
  CHECK(frames == 20);
  whole.stop();
}
