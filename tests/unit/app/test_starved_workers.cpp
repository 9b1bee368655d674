// The tracker's helpers starved of time: a mapping side that holds its
// bundle-adjustment job far longer than a frame (then returns it, late),
// and a texture thread far slower than the frames. The defined outcome: tracking
// goes on with the map it has, every pose reported stays right, the
// tracker waits for nothing and allocates nothing; the texture hand-over
// skips frames once its slots are full and takes frames again when the
// thread catches up.
#include <doctest/doctest.h>

#include <algorithm>
#include <vector>

#include "core/mapping/ba_channel.h"
#include "core/mapping/bundle_adjustment.h"
#include "core/tracking/tracker.h"
#include "firmware_app/texture_worker.h"
#include "platform/alloc_counter.h"
#include "platform/clock.h"
#include "support/alloc_guard.h"
#include "support/track_scene.h"

using namespace st;
using namespace st::test;

namespace {

// Takes one job and holds it until release_at(): the mapping thread
// starved. Then solves it (on the test thread, between frames) and hands
// it back, far later than any window job would come.
class StarvedChannel final : public BaChannel {
 public:
  Status configure(const TrackerConfig& c, const Mesh& mesh, const Pinhole& K) {
    BundleAdjusterOptions o;
    o.w_shape = c.ba.w_shape;
    o.max_iterations = c.ba.max_iterations;
    if (Status s = job_.configure(c.max_keyframes, c.max_map_points, c.ba_max_observations); !s.ok()) return s;
    return ba_.configure(o, mesh, K, c.max_keyframes, c.max_map_points, c.ba_max_observations);
  }
  BaJob* acquire_job() override {
    ++asked;
    return state_ == kFree ? &job_ : nullptr;
  }
  void submit_job(BaJob*) override {
    ++submitted;
    state_ = kHeld;
  }
  const BaJob* solved_job() override { return state_ == kSolved ? &job_ : nullptr; }
  void release_job(const BaJob*) override {
    ++applied;
    state_ = kFree;
  }
  // The starved side finally runs: the held job is solved and waits to be applied.
  void solve_held() {
    if (state_ != kHeld) return;
    ba_.solve(&job_);
    state_ = kSolved;
  }
  bool holding() const { return state_ == kHeld; }
  int asked = 0, submitted = 0, applied = 0;

 private:
  enum State { kFree, kHeld, kSolved };
  BundleAdjuster ba_;
  BaJob job_;
  State state_ = kFree;
};

}  // namespace

TEST_CASE("starved workers: a BA job held for 150 frames, then applied late: tracking goes on, poses stay "
          "right, nothing waits or allocates" *
          doctest::timeout(120)) {
  REQUIRE(platform::allocation_counting_enabled());
  const RenderedOrbit& s = liver_orbit40();
  const TrackerConfig cfg = small_tracker_config(s.K);  // keyframes every few frames: jobs wanted all along
  Tracker t;
  REQUIRE(t.configure(cfg, s.mesh, CameraModel(s.K, Distortion{}), s.T_camera_model[0]).ok());
  StarvedChannel channel;
  REQUIRE(channel.configure(cfg, s.mesh, s.K).ok());
  t.set_ba_channel(&channel);
  t.start();
  constexpr int kSteps = 220, kRelease = 150;
  const int period = 2 * (static_cast<int>(s.T_camera_model.size()) - 1);
  int posed = 0, wrong = 0, asked_while_held = 0;
  double worst_px = 0, worst_step_ms = 0;
  std::uint64_t allocations = 0;
  for (int step = 0; step < kSteps; ++step) {
    if (step == kRelease) {
      asked_while_held = channel.asked;
      REQUIRE(channel.holding());  // held since its submission, 100+ frames ago
      channel.solve_held();
    }
    const int k = step % period, i = k < static_cast<int>(s.T_camera_model.size()) ? k : period - k;
    const AllocationCounter counter;
    const std::int64_t t0 = platform::monotonic_ns();
    const TrackResult r = t.step(s.frames[static_cast<std::size_t>(i)].view(), step);
    worst_step_ms = std::max(worst_step_ms, static_cast<double>(platform::monotonic_ns() - t0) * 1e-6);
    allocations += counter.count();
    if (!r.pose_valid) continue;
    ++posed;
    const double gap = reprojection_gap_px(s, r.T_camera_model, s.T_camera_model[static_cast<std::size_t>(i)]);
    worst_px = std::max(worst_px, gap);
    wrong += gap > 5.0 ? 1 : 0;
  }
  t.stop();
  MESSAGE(posed << " of " << kSteps << " steps with a pose, worst " << worst_px << " px, slowest step "
                << worst_step_ms << " ms; BA jobs: " << channel.submitted << " submitted, " << channel.applied
                << " applied, the channel asked " << asked_while_held << " times while it held the first");
  CHECK(allocations == 0);
  CHECK(wrong == 0);
  CHECK(posed >= kSteps * 9 / 10);
  // While the job was held the tracker asked again (it wanted more jobs)
  // and went on without them; the late job was applied and jobs flowed again.
  CHECK(asked_while_held > 1);
  CHECK(channel.applied >= 1);
  CHECK(channel.submitted >= 2);
}

TEST_CASE("starved workers: a texture thread far slower than the frames: skipped once the slots are full, "
          "never a wait or an allocation, taken again when it catches up" *
          doctest::timeout(60)) {
  REQUIRE(platform::allocation_counting_enabled());
  const RenderedOrbit& s = liver_orbit40();
  app::TextureWorker worker;
  TextureConfig tc;
  tc.width = s.K.width;
  tc.height = s.K.height;
  REQUIRE(worker.configure(s.mesh, CameraModel(s.K, Distortion{}), tc, 3, nullptr).ok());
  const auto frame = [&](int i) {
    FrameRef f;
    f.index = i;
    f.y = s.frames[static_cast<std::size_t>(i)].cview();
    return f;
  };
  // Twenty frames back to back, far faster than the (background) thread
  // textures one: it is starved. Three slots take the first frames, the
  // rest are skipped, without a wait.
  worker.start();
  int taken = 0, skipped = 0;
  std::int64_t worst_ns = 0;
  std::uint64_t allocations = 0;
  for (int i = 0; i < 20; ++i) {
    const AllocationCounter counter;
    const std::int64_t t0 = platform::monotonic_ns();
    const bool ok = worker.try_submit(frame(i), s.T_camera_model[static_cast<std::size_t>(i)]);
    worst_ns = std::max(worst_ns, platform::monotonic_ns() - t0);
    allocations += counter.count();
    (ok ? taken : skipped) += 1;
  }
  MESSAGE(taken << " frames taken, " << skipped << " skipped, slowest hand-over " << worst_ns * 1e-6 << " ms");
  CHECK(taken >= 3);
  CHECK(skipped >= 10);
  CHECK(allocations == 0);
  CHECK(worst_ns < 50'000'000);  // a copy of the planes, never a wait (generous: shared machine)
  // The thread catches up: the frames taken are textured and the slots come back.
  const std::int64_t deadline = platform::monotonic_ns() + 20'000'000'000ll;
  while (worker.frames_textured() < taken && platform::monotonic_ns() < deadline)
    platform::sleep_until_ns(platform::monotonic_ns() + 5'000'000);
  CHECK(worker.frames_textured() == taken);
  CHECK(worker.try_submit(frame(20), s.T_camera_model[20]));
  worker.stop();
  CHECK(worker.frames_textured() == taken + 1);
  CHECK(worker.worker_allocations() == 0);
}
