// A tower's capture faults through the real frame loop and tracker
// (firmware_app/frame_loop.h, firmware_app/tracker_processor.h, with its
// mapping thread): a stall of 0.5 s, a burst of ten frames at once, a
// duplicated frame, dropped frames, a timestamp that goes backwards and a
// frame of another size. The defined outcome: every frame is processed,
// the frame of another size is lost without a pose, every pose reported is
// right (within a few pixels of the ground truth's projection), tracking
// goes on after each fault, the loop counts the dropped frames and the
// timestamp fault, and the tracking thread allocates nothing.
#include <doctest/doctest.h>

#include <algorithm>
#include <vector>

#include "firmware_app/frame_loop.h"
#include "firmware_app/tracker_processor.h"
#include "platform/alloc_counter.h"
#include "platform/clock.h"
#include "support/track_scene.h"

using namespace st;
using namespace st::test;

namespace {

// One delivery of the scripted capture.
struct Delivery {
  int orbit_frame = 0;     // the rendered frame shown; -1: a frame of another size
  int index = 0;           // the capture's frame number
  double timestamp_s = 0;  // the capture's time stamp
  double stall_s = 0;      // the capture delivers nothing for this long first
  bool burst = false;      // ready at the same moment as the delivery before it
};

class FaultySource final : public FrameSource {
 public:
  FaultySource(const RenderedOrbit& orbit, std::vector<Delivery> script)
      : orbit_(orbit), script_(std::move(script)), odd_(orbit.K.width / 2, orbit.K.height / 2) {
    for (int y = 0; y < odd_.height(); ++y)
      for (int x = 0; x < odd_.width(); ++x) odd_(x, y) = static_cast<std::uint8_t>((x * 7 + y * 3) & 0xff);
  }
  Status start() override { return Status::Ok(); }
  void next(SourceFrame* out) override {
    if (i_ >= script_.size()) {
      out->kind = SourceFrame::Kind::kEnd;
      return;
    }
    const Delivery& d = script_[i_++];
    if (d.stall_s > 0) platform::sleep_until_ns(platform::monotonic_ns() + static_cast<std::int64_t>(d.stall_s * 1e9));
    if (!d.burst) t_ready_ns_ = platform::monotonic_ns();
    out->kind = SourceFrame::Kind::kFrame;
    out->frame = FrameRef{};
    out->frame.index = d.index;
    out->frame.y = d.orbit_frame >= 0 ? orbit_.frames[static_cast<std::size_t>(d.orbit_frame)].cview() : odd_.cview();
    out->timestamp_s = d.timestamp_s;
    out->t_ready_ns = t_ready_ns_;
  }
  void release() override {}
  void stop() override {}
  bool paced() const override { return true; }
  std::string error() const override { return {}; }

 private:
  const RenderedOrbit& orbit_;
  std::vector<Delivery> script_;
  std::size_t i_ = 0;
  std::int64_t t_ready_ns_ = 0;
  Image<std::uint8_t> odd_;
};

// Keeps each frame's result (capacity reserved up front: no allocation).
class Recorder final : public FrameObserver {
 public:
  explicit Recorder(std::size_t n) { results.reserve(n); }
  void frame_done(const FrameRef&, const TrackResult& r, double) override { results.push_back(r); }
  std::vector<TrackResult> results;
};

}  // namespace

TEST_CASE("capture faults: stall, burst, duplicate, dropped and backward frames and a frame of another "
          "size: processed, honest, tracking goes on, nothing allocated" *
          doctest::timeout(120)) {
  REQUIRE(platform::allocation_counting_enabled());
  static const RenderedOrbit s = render_liver_orbit(60);
  const double dt = 1.0 / 30.0;
  // The script: frame k of the orbit is capture frame k at k * dt unless a fault says otherwise.
  std::vector<Delivery> script;
  std::vector<int> fault_frames;  // positions in the script of the faults
  int index = 0;
  for (int k = 0; k < 60; ++k) {
    Delivery d{k, index, index * dt};
    if (k == 12) d.stall_s = 0.5;                   // nothing for 0.5 s, then frames again
    if (k >= 21 && k <= 29) d.burst = true;         // 20..29: ten frames at once
    if (k == 40) {                                  // frames 37..39 never arrive
      index += 3;
      d.index = index;
      d.timestamp_s = index * dt;
    }
    if (k == 46) d.timestamp_s = (index - 2) * dt;  // a time stamp that goes backwards
    if (k == 12 || k == 20 || k == 40 || k == 46) fault_frames.push_back(static_cast<int>(script.size()));
    script.push_back(d);
    ++index;
    if (k == 33) {  // frame 33 delivered twice (the capture card repeats it)
      fault_frames.push_back(static_cast<int>(script.size()));
      script.push_back({33, index, index * dt});
      ++index;
    }
    if (k == 52) {  // a frame of another size between 52 and 53
      fault_frames.push_back(static_cast<int>(script.size()));
      script.push_back({-1, index, index * dt});
      ++index;
    }
  }

  const TrackerConfig cfg = small_tracker_config(s.K);
  app::TrackerProcessor processor;
  REQUIRE(processor.configure(cfg, s.mesh, CameraModel(s.K, Distortion{}), s.T_camera_model[0]).ok());
  FaultySource source(s, script);
  Recorder recorder(script.size());
  FrameLoop loop;
  loop.source = &source;
  loop.processor = &processor;
  loop.observer = &recorder;
  loop.run();

  REQUIRE(recorder.results.size() == script.size());
  CHECK(loop.stats.frames == static_cast<int>(script.size()));
  CHECK(loop.stats.tracking_thread_allocations == 0);
  CHECK(loop.stats.dropped_frames == 3);
  CHECK(loop.stats.timestamp_faults == 1);
  int posed = 0, wrong = 0;
  double worst_px = 0;
  for (std::size_t i = 0; i < script.size(); ++i) {
    const TrackResult& r = recorder.results[i];
    const int k = script[i].orbit_frame;
    if (k < 0) {
      CHECK(r.state == TrackState::kLost);  // the frame of another size: lost, no pose
      CHECK_FALSE(r.pose_valid);
      continue;
    }
    if (!r.pose_valid) continue;
    ++posed;
    const double gap = reprojection_gap_px(s, r.T_camera_model, s.T_camera_model[static_cast<std::size_t>(k)]);
    worst_px = std::max(worst_px, gap);
    if (gap > 5.0) {
      ++wrong;
      MESSAGE("delivery " << i << " (orbit frame " << k << "): reported " << gap << " px off");
    }
  }
  MESSAGE(posed << " of " << script.size() << " deliveries with a pose, worst " << worst_px << " px");
  CHECK(wrong == 0);
  // Tracking goes on after every fault: a pose within the five frames after it.
  for (const int f : fault_frames) {
    CAPTURE(f);
    bool resumed = false;
    for (int j = f + 1; j <= std::min<int>(f + 5, static_cast<int>(script.size()) - 1); ++j)
      resumed = resumed || recorder.results[static_cast<std::size_t>(j)].pose_valid;
    CHECK(resumed);
  }
  CHECK(posed >= static_cast<int>(script.size()) * 8 / 10);
}
