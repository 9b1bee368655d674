// The tracking thread allocates nothing after start(): 200+ steps over a
// rendered liver sequence (forwards and backwards, with lost frames and
// relocalisation in between) under the allocation counter, with chroma
// (the occluder mask runs on every frame and finds a grey corner).
#include <doctest/doctest.h>

#include <vector>

#include "core/tracking/tracker.h"
#include "platform/alloc_counter.h"
#include "support/alloc_guard.h"
#include "support/track_scene.h"

using namespace st;
using namespace st::test;

TEST_CASE("tracker: zero heap allocations over 220 steps after start") {
  REQUIRE(platform::allocation_counting_enabled());
  const Mesh mesh = load_liver_for_tracking();
  const Pinhole K = track_test_pinhole();
  const std::vector<SE3> poses = liver_orbit(mesh, 40);
  TrackSceneRenderer renderer;
  renderer.configure(mesh, K);
  std::vector<Image<std::uint8_t>> frames(poses.size());
  for (std::size_t i = 0; i < poses.size(); ++i) renderer.render(poses[i], &frames[i]);
  Image<std::uint8_t> black(K.width, K.height);
  // Chroma: red-brown everywhere but a neutral top-left corner (an
  // "instrument" wherever the luma there is bright enough).
  Image<std::uint8_t> u((K.width + 1) / 2, (K.height + 1) / 2), v(u.width(), u.height());
  u.fill(110);
  v.fill(160);
  for (int y = 0; y < u.height() / 3; ++y)
    for (int x = 0; x < u.width() / 3; ++x) u(x, y) = v(x, y) = 128;
  const ChromaView chroma{u.cview(), v.cview()};

  TrackerConfig cfg;
  cfg.width = K.width;
  cfg.height = K.height;
  cfg.features.n_features = 1000;
  cfg.max_map_points = 2000;  // small pools: culling runs during the test
  cfg.max_keyframes = 4;
  Tracker t;
  REQUIRE(t.configure(cfg, mesh, CameraModel(K, Distortion{}), poses[0]).ok());
  t.start();
  int posed = 0, lost = 0, keyframes = 0, relocalised = 0, masked = 0;
  const AllocationCounter counter;
  for (int step = 0; step < 220; ++step) {
    // Ping-pong along the orbit; steps 100-104 see a black frame.
    const int period = 2 * (static_cast<int>(poses.size()) - 1);
    const int k = step % period, i = k < static_cast<int>(poses.size()) ? k : period - k;
    const bool dark = step >= 100 && step < 105;
    const TrackResult r = t.step(dark ? black.view() : frames[static_cast<std::size_t>(i)].view(), step, chroma);
    REQUIRE(r.occluder_pixels >= 0);  // the mask ran
    masked += r.occluder_pixels > 0 ? 1 : 0;
    posed += r.pose_valid ? 1 : 0;
    lost += r.pose_valid ? 0 : 1;
    keyframes += r.keyframe ? 1 : 0;
    relocalised += r.state == TrackState::kRelocalised ? 1 : 0;
  }
  const std::uint64_t allocations = counter.count();
  MESSAGE("220 steps: " << posed << " poses, " << lost << " lost, " << keyframes << " keyframes, " << relocalised
                        << " relocalisations");
  CHECK(allocations == 0);
  CHECK(masked > 100);  // the grey corner was removed from the valid mask (cleaning and margin ran)
  CHECK(keyframes > 4);  // the keyframe pool (4) was recycled
  CHECK(relocalised >= 1);
  CHECK(posed >= 200);
}
