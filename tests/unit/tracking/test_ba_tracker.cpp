// Bundle adjustment inside the tracker: the real mapping thread
// (firmware_app/mapping_worker.h) next to a tracker stepping a rendered
// liver sequence, with the tracking thread's allocations counted; and a
// synchronous channel (solve on submit) for a deterministic comparison of
// tracking with and without BA.
#include <doctest/doctest.h>

#include <algorithm>
#include <string>
#include <utility>
#include <vector>

#include "core/mapping/ba_channel.h"
#include "core/mapping/bundle_adjustment.h"
#include "core/mesh/closest_point.h"
#include "core/tracking/tracker.h"
#include "firmware_app/mapping_worker.h"
#include "platform/alloc_counter.h"
#include "support/alloc_guard.h"
#include "support/track_scene.h"

using namespace st;
using namespace st::test;

namespace {

// Solves each job as it is submitted, on the calling thread (tests only).
class InlineChannel final : public BaChannel {
 public:
  Status configure(const TrackerConfig& c, const Mesh& mesh, const Pinhole& K) {
    BundleAdjusterOptions o;
    o.w_shape = c.ba.w_shape;
    o.max_iterations = c.ba.max_iterations;
    o.max_time_s = 1.0;
    if (Status s = job_.configure(c.max_keyframes, c.max_map_points, c.ba_max_observations); !s.ok()) return s;
    return ba_.configure(o, mesh, K, c.max_keyframes, c.max_map_points, c.ba_max_observations);
  }
  BaJob* acquire_job() override { return state_ == 0 ? &job_ : nullptr; }
  void submit_job(BaJob*) override {
    ba_.solve(&job_);
    solves_ += 1;
    usable_ += job_.summary.usable ? 1 : 0;
    state_ = 1;
  }
  const BaJob* solved_job() override { return state_ == 1 ? &job_ : nullptr; }
  void release_job(const BaJob*) override { state_ = 0; }
  int solves_ = 0, usable_ = 0;

 private:
  BundleAdjuster ba_;
  BaJob job_;
  int state_ = 0;
};

struct RunResult {
  int posed = 0, applied = 0;
  double max_rot_deg = 0, max_centre_mm = 0, mean_surface_mm = 0;
};

RunResult run_orbit(const TrackerConfig& cfg, BaChannel* channel) {
  const RenderedOrbit& s = liver_orbit40();
  Tracker t;
  REQUIRE(t.configure(cfg, s.mesh, CameraModel(s.K, Distortion{}), s.T_camera_model[0]).ok());
  t.set_ba_channel(channel);
  t.start();
  RunResult out;
  for (int step = 0; step < 78; ++step) {  // there and back
    const int i = step < 40 ? step : 78 - step;
    const TrackResult r = t.step(s.frames[static_cast<std::size_t>(i)].view(), step);
    out.applied += r.ba_applied ? 1 : 0;
    if (!r.pose_valid) continue;
    ++out.posed;
    const PoseDelta d = pose_delta(r.T_camera_model, s.T_camera_model[static_cast<std::size_t>(i)]);
    out.max_rot_deg = std::max(out.max_rot_deg, d.angle_deg);
    out.max_centre_mm = std::max(out.max_centre_mm, (r.T_camera_model.inverse().translation() -
                                                     s.T_camera_model[static_cast<std::size_t>(i)].inverse().translation())
                                                        .norm());
  }
  std::vector<Vec3> points(static_cast<std::size_t>(cfg.max_map_points));
  const int n = t.map_points(points.data(), cfg.max_map_points);
  ClosestPointIndex surface;
  REQUIRE(surface.configure(s.mesh).ok());
  for (int i = 0; i < n; ++i) {
    SurfacePoint sp;
    REQUIRE(surface.closest(points[static_cast<std::size_t>(i)], &sp));
    out.mean_surface_mm += sp.distance_mm / n;
  }
  return out;
}

}  // namespace

TEST_CASE("ba tracker: neither the tracking nor the mapping thread allocates while BA runs") {
  REQUIRE(platform::allocation_counting_enabled());
  const RenderedOrbit& s = liver_orbit40();
  Image<std::uint8_t> black(s.K.width, s.K.height);
  const TrackerConfig cfg = small_tracker_config(s.K);
  Tracker t;
  REQUIRE(t.configure(cfg, s.mesh, CameraModel(s.K, Distortion{}), s.T_camera_model[0]).ok());
  app::MappingWorker worker;
  REQUIRE(worker.configure(cfg, s.mesh, s.K).ok());
  t.set_ba_channel(&worker);
  worker.start();
  t.start();
  int posed = 0, submitted = 0, applied = 0, relocalised = 0;
  const AllocationCounter counter;
  for (int step = 0; step < 220; ++step) {
    const int period = 2 * (static_cast<int>(s.T_camera_model.size()) - 1);
    const int k = step % period, i = k < static_cast<int>(s.T_camera_model.size()) ? k : period - k;
    const bool dark = step >= 100 && step < 105;  // lost, then relocalised: a global BA
    const TrackResult r = t.step(dark ? black.view() : s.frames[static_cast<std::size_t>(i)].view(), step);
    posed += r.pose_valid ? 1 : 0;
    submitted += r.ba_submitted ? 1 : 0;
    applied += r.ba_applied ? 1 : 0;
    relocalised += r.state == TrackState::kRelocalised ? 1 : 0;
  }
  const std::uint64_t allocations = counter.count();
  t.stop();
  worker.stop();
  const app::MappingStats m = worker.stats();
  MESSAGE("220 steps: " << posed << " poses, " << relocalised << " relocalisations, " << submitted
                        << " jobs submitted, " << applied << " applied; mapping thread: " << m.window_solves
                        << " window + " << m.global_solves << " global solves + " << m.focal_tests
                        << " focal tests, median " << m.solve_median_ms
                        << " ms, max " << m.solve_max_ms << " ms, <= " << m.max_allocations_per_solve
                        << " allocations per solve; " << m.mean_window_observations << " observations per window ("
                        << m.mean_window_fixed_observations << " from fixed keyframes)");
  CHECK(allocations == 0);
  CHECK(m.thread_allocations == 0);  // every solve: window, global, focal test
  CHECK(m.max_allocations_per_solve == 0);
  CHECK(m.focal_tests >= 1);
  CHECK(submitted >= 3);
  CHECK(applied >= 2);
  CHECK(m.window_solves >= 2);
  CHECK(m.global_solves >= 1);
  CHECK(relocalised >= 1);
  CHECK(posed >= 200);
}

TEST_CASE("ba tracker: BA keeps tracking accurate and map points on the mesh (synchronous channel)") {
  const RenderedOrbit& s = liver_orbit40();
  TrackerConfig cfg = small_tracker_config(s.K);
  const RunResult none = run_orbit(cfg, nullptr);
  InlineChannel shape;
  REQUIRE(shape.configure(cfg, s.mesh, s.K).ok());
  const RunResult with_shape = run_orbit(cfg, &shape);
  cfg.ba.w_shape = 0.0;
  InlineChannel plain;
  REQUIRE(plain.configure(cfg, s.mesh, s.K).ok());
  const RunResult no_shape = run_orbit(cfg, &plain);
  for (const auto& [name, r] : {std::pair{std::string("no BA"), none}, {std::string("BA w_shape 100"), with_shape},
                                {std::string("BA w_shape 0"), no_shape}})
    MESSAGE(name << ": " << r.posed << "/78 posed, max error " << r.max_rot_deg << " deg " << r.max_centre_mm
                 << " mm, map points to surface " << r.mean_surface_mm << " mm, " << r.applied << " BA applied");
  MESSAGE("solves: " << shape.solves_ << " (" << shape.usable_ << " usable) with shape, " << plain.solves_ << " ("
                     << plain.usable_ << ") without");
  CHECK(shape.usable_ >= 3);
  CHECK(with_shape.applied >= 3);
  CHECK(with_shape.posed == none.posed);
  CHECK(no_shape.posed == none.posed);
  CHECK(with_shape.max_rot_deg < 1.0);
  CHECK(with_shape.max_centre_mm < 3.0);
  CHECK(with_shape.mean_surface_mm <= no_shape.mean_surface_mm);
  CHECK(with_shape.mean_surface_mm < 0.5);
}

TEST_CASE("ba tracker: use_ba false hands out no job, bad BA settings are refused") {
  const RenderedOrbit& s = liver_orbit40();
  TrackerConfig cfg = small_tracker_config(s.K);
  cfg.use_ba = false;
  InlineChannel channel;
  REQUIRE(channel.configure(cfg, s.mesh, s.K).ok());
  const RunResult r = run_orbit(cfg, &channel);
  CHECK(channel.solves_ == 0);
  CHECK(r.applied == 0);
  Tracker t;
  for (const auto& bad : {+[](TrackerConfig* c) { c->ba.w_shape = -1; }, +[](TrackerConfig* c) { c->ba_window_keyframes = 1; },
                          +[](TrackerConfig* c) { c->ba.max_time_s = 0; }, +[](TrackerConfig* c) { c->ba_max_observations = 0; }}) {
    TrackerConfig c = small_tracker_config(s.K);
    bad(&c);
    CHECK_FALSE(t.configure(c, s.mesh, CameraModel(s.K, Distortion{}), s.T_camera_model[0]).ok());
  }
}
