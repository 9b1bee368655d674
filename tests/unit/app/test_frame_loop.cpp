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

#include "core/image/area_scale.h"
#include "firmware_app/frame_loop.h"
#include "hal/capture/y4m_capture.h"
#include "hal/storage/file_io.h"
#include "hal/storage/y4m_writer.h"
#include "platform/clock.h"
#include "support/alloc_guard.h"
#include "support/support.h"

using namespace st;

namespace {

// A 4:2:0 video of width x height at path, opened for writing.
void open_video(Y4mWriter* w, const std::filesystem::path& path, int width, int height) {
  Y4mHeader h;
  h.width = width;
  h.height = height;
  REQUIRE(w->open(path, h).ok());
}

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
  open_video(&w, dir / "v.y4m", 16, 8);
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

TEST_CASE("y4m capture: each frame at the tracker's working size, read in bands on the capture thread, the video's size never whole") {
  const auto dir = test::scratch_dir("y4m_capture_working");
  Y4mWriter w;
  open_video(&w, dir / "v.y4m", 96, 150);
  std::vector<Image<std::uint8_t>> Y, U, V;
  for (int f = 0; f < 6; ++f) {
    Y.emplace_back(96, 150);
    U.emplace_back(48, 75);
    V.emplace_back(48, 75);
    for (int y = 0; y < 150; ++y)
      for (int x = 0; x < 96; ++x) Y.back()(x, y) = static_cast<std::uint8_t>((x * 5 + y * 3 + f * 17) & 255);
    for (int y = 0; y < 75; ++y)
      for (int x = 0; x < 48; ++x) {
        U.back()(x, y) = static_cast<std::uint8_t>(100 + ((x + f) % 9) * 5);
        V.back()(x, y) = static_cast<std::uint8_t>(160 - ((y + f) % 7) * 6);
      }
    REQUIRE(w.write(Y.back().cview(), U.back().cview(), V.back().cview()).ok());
  }
  REQUIRE(w.close().ok());
  // What the capture must hand over: the area filter of each plane.
  AreaScaler luma, chroma;
  REQUIRE(luma.configure(96, 150, 64, 100).ok());
  REQUIRE(chroma.configure(48, 75, 32, 50).ok());
  const auto same = [](GrayView a, const Image<std::uint8_t>& b) {
    if (a.width != b.width() || a.height != b.height()) return false;
    for (int y = 0; y < a.height; ++y)
      for (int x = 0; x < a.width; ++x)
        if (a(x, y) != b(x, y)) return false;
    return true;
  };

  Y4mCapture capture;
  REQUIRE(capture.open(dir / "v.y4m", 3, 25.0, 0.0).ok());
  CHECK_FALSE(capture.set_working_size(128, 150).ok());  // larger than the video
  REQUIRE(capture.set_working_size(64, 100).ok());
  REQUIRE(capture.start().ok());
  CHECK_FALSE(capture.set_working_size(48, 27).ok());  // not while running
  SourceFrame f;
  int frames = 0;
  bool all_same = true, full_dropped = true;
  Image<std::uint8_t> y(64, 100), u(32, 50), v(32, 50);
  const auto matches = [&](const SourceFrame& g) {
    const auto k = static_cast<std::size_t>(g.frame.index);
    luma.scale(Y[k].cview(), y.view());
    chroma.scale(U[k].cview(), u.view());
    chroma.scale(V[k].cview(), v.view());
    return same(g.frame.y_work, y) && same(g.frame.u_work, u) && same(g.frame.v_work, v);
  };
  const test::AllocationCounter counter;
  // The ring's three frames held at once (the capture thread waits to read
  // on): each still its own frame. 150 rows come in five bands.
  SourceFrame held[3];
  for (SourceFrame& h : held) capture.next(&h);
  for (const SourceFrame& h : held) {
    REQUIRE(h.kind == SourceFrame::Kind::kFrame);
    all_same = all_same && matches(h);
    ++frames;
  }
  for (int i = 0; i < 3; ++i) capture.release();
  for (;;) {
    capture.next(&f);
    if (f.kind != SourceFrame::Kind::kFrame) break;
    all_same = all_same && matches(f);
    // Only the working size is handed on.
    full_dropped = full_dropped && f.frame.y.empty() && f.frame.u.empty() && f.frame.v.empty();
    ++frames;
    capture.release();
  }
  const std::uint64_t allocations = counter.count();
  capture.stop();
  CHECK(frames == 6);
  CHECK(all_same);
  CHECK(full_dropped);
  CHECK(allocations == 0);  // next() and release() on the tracking thread

  Y4mCapture own_size;  // the video's own size: nothing made
  REQUIRE(own_size.open(dir / "v.y4m", 2, 25.0, 0.0).ok());
  REQUIRE(own_size.set_working_size(96, 150).ok());
  REQUIRE(own_size.start().ok());
  own_size.next(&f);
  REQUIRE(f.kind == SourceFrame::Kind::kFrame);
  CHECK(f.frame.y_work.empty());
  CHECK(f.frame.y.width == 96);
  own_size.release();
  own_size.stop();

  // A video that ends inside a frame's chroma: the frames before it, then
  // the error with the bytes missing (nothing half-scaled handed on).
  std::string bytes = read_file(dir / "v.y4m", 1 << 20).value();
  bytes.resize(bytes.size() - 1000);
  REQUIRE(write_file(dir / "t.y4m", bytes).ok());
  Y4mCapture cut;
  REQUIRE(cut.open(dir / "t.y4m", 2, 25.0, 0.0).ok());
  REQUIRE(cut.set_working_size(64, 100).ok());
  REQUIRE(cut.start().ok());
  frames = 0;
  for (;;) {
    cut.next(&f);
    if (f.kind != SourceFrame::Kind::kFrame) break;
    ++frames;
    cut.release();
  }
  cut.stop();
  CHECK(frames == 5);
  REQUIRE(f.kind == SourceFrame::Kind::kError);
  INFO(cut.error());
  CHECK(cut.error().find("frame 5 is truncated") != std::string::npos);
  CHECK(cut.error().find("1000 missing") != std::string::npos);
}
