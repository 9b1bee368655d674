// The tracker's parts on their own (core/tracking/): the quality gates, the
// FAST threshold scaling, the local map's search, the relocaliser's
// keyframe candidates and the bundle-adjustment hand-off with the
// calibration test.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>
#include <random>
#include <vector>

#include "core/base/capacity.h"
#include "core/tracking/ba_handoff.h"
#include "core/tracking/fast_threshold_scaler.h"
#include "core/tracking/keyframe_relocaliser.h"
#include "core/tracking/local_map_search.h"
#include "core/tracking/pose_gates.h"

using namespace st;

namespace {

PoseEstimate good_estimate() {
  PoseEstimate e;
  e.solved = true;
  e.matches = 200;
  e.inliers = 150;
  e.whitened_rms = 1.0;
  e.mask_agreement = 0.97;
  e.spread_cells = 8;
  return e;
}

Pinhole test_pinhole() {
  Pinhole K;
  K.fx = K.fy = 500;
  K.cx = 320;
  K.cy = 240;
  K.width = 640;
  K.height = 480;
  return K;
}

// A descriptor that differs from every other index's in many bits.
Descriptor descriptor_of(int i) {
  Descriptor d{};
  std::uint32_t x = 2654435761u * static_cast<std::uint32_t>(i + 1);
  for (auto& b : d) {
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    b = static_cast<std::uint8_t>(x);
  }
  return d;
}

// A map of points on the plane z = 200 mm in front of the identity camera,
// made from there (view direction +z, 200 mm away, octave 0), and one
// keyframe at the identity linking them all.
struct PlaneMap {
  TrackingMap map;
  std::vector<Vec2> px;  // each point's pixel at the identity pose
  std::vector<int> ids;  // each point's map slot
  int keyframe = -1;
  explicit PlaneMap(int n) {
    REQUIRE(map.configure(256, 8, kMaxKeypoints).ok());
    keyframe = map.add_keyframe(SE3(), 0, -1);
    const Pinhole K = test_pinhole();
    for (int i = 0; i < n; ++i) {
      const Vec2 pixel(60.0 + 37.0 * (i % 14), 50.0 + 41.0 * (i / 14));
      MapPoint p;
      p.p_model = K.unproject(pixel, 200.0);
      p.view_dir_model = p.p_model.normalized();
      p.ref_distance_mm = static_cast<float>(p.p_model.norm());
      p.descriptor = descriptor_of(i);
      p.alive = true;
      p.created_frame = 0;
      const int id = map.add_point(p, 0);
      REQUIRE(id >= 0);
      KeyframeLink l;
      l.point = id;
      l.point_created_frame = 0;
      l.x = l.x_ideal = static_cast<float>(pixel.x());
      l.y = l.y_ideal = static_cast<float>(pixel.y());
      REQUIRE(map.add_link(keyframe, l));
      px.push_back(pixel);
      ids.push_back(id);
    }
  }
};

// The frame's keypoints: point i's pixel moved by shift, its descriptor.
std::unique_ptr<FeatureSet> frame_of(const PlaneMap& m, const Vec2& shift) {
  auto f = std::make_unique<FeatureSet>();
  f->width = 640;
  f->height = 480;
  for (std::size_t i = 0; i < m.px.size(); ++i) {
    const Vec2 p = m.px[i] + shift;
    f->keypoints[i] = Keypoint{static_cast<float>(p.x()), static_cast<float>(p.y()), 0.f, 1.f, 0};
    f->descriptors[i] = descriptor_of(static_cast<int>(i));
  }
  f->count = static_cast<int>(m.px.size());
  return f;
}

}  // namespace

TEST_CASE("pose gates: each gate refuses alone, strict is stricter, confirm relaxes the ratio only") {
  TrackerConfig c;
  PoseGates gates;
  gates.configure(c);
  const PoseEstimate good = good_estimate();
  CHECK(PoseGates::passes(good, gates.normal()));
  CHECK(PoseGates::passes(good, gates.strict()));
  const auto fails_with = [&](auto change) {
    PoseEstimate e = good;
    change(&e);
    return !PoseGates::passes(e, gates.normal());
  };
  CHECK(fails_with([](PoseEstimate* e) { e->solved = false; }));
  CHECK(fails_with([](PoseEstimate* e) { e->inliers = 29; }));
  CHECK(fails_with([](PoseEstimate* e) { e->matches = 1000; }));  // ratio 0.15
  CHECK(fails_with([](PoseEstimate* e) { e->whitened_rms = 2.6; }));
  CHECK(fails_with([](PoseEstimate* e) { e->mask_agreement = 0.85; }));
  CHECK(fails_with([](PoseEstimate* e) {
    e->T_camera_model = SE3(Mat3::Identity(), Vec3(std::numeric_limits<double>::quiet_NaN(), 0, 0));
  }));
  // Strict: 1.5 x the inliers, 0.8 x the RMS, agreement 0.95, spread.
  const QualityGates s = gates.strict();
  CHECK(s.min_inliers == 45);
  CHECK(s.max_rms_px == doctest::Approx(2.0));
  CHECK(s.min_mask_agreement == doctest::Approx(0.95));
  CHECK(s.min_spread_cells == c.min_spread_cells);
  PoseEstimate clustered = good;
  clustered.spread_cells = 1;
  CHECK(PoseGates::passes(clustered, gates.normal()));
  CHECK_FALSE(PoseGates::passes(clustered, gates.strict()));
  // Confirm: only the ratio changes.
  PoseEstimate weak = good;
  weak.matches = 500;  // ratio 0.3: below 0.35, above 0.2
  CHECK_FALSE(PoseGates::passes(weak, gates.normal()));
  CHECK(PoseGates::passes(weak, gates.confirm()));
  CHECK(gates.confirm().min_inliers == gates.normal().min_inliers);
  CHECK(gates.confirm().max_rms_px == gates.normal().max_rms_px);
}

TEST_CASE("FAST threshold scaler: dim and flat frames scale the thresholds down, bright textured ones do not") {
  constexpr int W = 320, H = 240;
  Image<std::uint8_t> valid(W / 2, H / 2), luma(W, H);
  valid.fill(255);
  ValidMaskBuilder builder;
  REQUIRE(builder.configure(ValidMaskConfig{}, W, H).ok());
  // 4x4 blocks alternating between base and base + step: block differences
  // of 2 x step a place (horizontal and vertical neighbours both differ).
  const auto checker = [&](int base, int step) {
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) luma(x, y) = static_cast<std::uint8_t>(base + (((x / 4) + (y / 4)) % 2) * step);
  };
  // The valid mask's block means are the luma rule's measure: built per frame.
  const auto measure = [&](const FastThresholdScaler& sc) {
    REQUIRE_FALSE(builder.build(luma.cview()).empty());
    return sc.measure(luma.cview(), {}, valid.cview(), builder);
  };
  checker(120, 20);
  CHECK(FastThresholdScaler::organ_contrast(luma.cview(), {}, valid.cview()) == doctest::Approx(40.0));
  FastThresholdScaler scaler;
  scaler.configure(80.0, 5.0);
  FastThresholdScale s = measure(scaler);
  CHECK(s.scale == 1.f);
  CHECK_FALSE(s.low_contrast);
  // A veil: contrast 2 against the reference 5.
  checker(120, 1);
  s = measure(scaler);
  CHECK(s.low_contrast);
  CHECK(s.scale == doctest::Approx(0.4f));
  // Dim: luma 40-48, 24-32 above black against the reference's 64.
  checker(40, 8);
  s = measure(scaler);
  CHECK_FALSE(s.low_contrast);
  CHECK(s.scale >= 0.37f);
  CHECK(s.scale <= 0.51f);
  // Both rules off, or nothing valid to measure: 1.
  scaler.configure(0.0, 0.0);
  CHECK(measure(scaler).scale == 1.f);
  scaler.configure(80.0, 5.0);
  CHECK(scaler.measure(luma.cview(), {}, GrayView{}, builder).scale == 1.f);
  valid.fill(0);
  CHECK(FastThresholdScaler::organ_contrast(luma.cview(), {}, valid.cview()) == -1.0);
}

TEST_CASE("noise ratio: white noise about 4, texture about 1 or less, the organ mask and nothing to measure") {
  constexpr int W = 320, H = 240;
  Image<std::uint8_t> valid(W / 2, H / 2), luma(W, H), organ(W / 2, H / 2);
  valid.fill(255);
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, 6.0);
  const auto clamp8 = [](double v) { return static_cast<std::uint8_t>(std::clamp(std::lround(v), 0L, 255L)); };
  // White noise (sigma 6 on grey 128): pixel differences 2 x 6.8 a place,
  // differences of 4x4 block means 2 x 1.7: about 4.
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) luma(x, y) = clamp8(128.0 + noise(rng));
  const double white = FastThresholdScaler::organ_noise_ratio(luma.cview(), {}, valid.cview());
  CHECK(white > 3.3);
  CHECK(white < 4.7);
  // Texture slower than a pixel (a sine of 24 px period, amplitude 20):
  // neighbouring pixels differ by about a quarter of what 4 px apart do.
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      luma(x, y) = clamp8(128.0 + 20.0 * std::sin(2 * 3.14159265 * x / 24.0) * std::cos(2 * 3.14159265 * y / 24.0));
  const double texture = FastThresholdScaler::organ_noise_ratio(luma.cview(), {}, valid.cview());
  CHECK(texture < 0.6);
  // The same texture under the noise: between the two.
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) luma(x, y) = clamp8(luma(x, y) + noise(rng));
  const double both = FastThresholdScaler::organ_noise_ratio(luma.cview(), {}, valid.cview());
  CHECK(both > texture);
  CHECK(both < white);
  // Only the organ counts: noise on the left half, texture-only on the right, organ on the left.
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x)
      luma(x, y) = x < W / 2 ? clamp8(128.0 + noise(rng)) : clamp8(128.0 + 20.0 * std::sin(2 * 3.14159265 * x / 24.0));
  organ.fill(0);
  for (int y = 0; y < H / 2; ++y)
    for (int x = 0; x < W / 4; ++x) organ(x, y) = 255;
  CHECK(FastThresholdScaler::organ_noise_ratio(luma.cview(), organ.cview(), valid.cview()) > 3.3);
  // Flat: no block differs and no pixel either (0); pixels that differ
  // over blocks that do not are all noise (1e3): a 2x2 checker.
  luma.fill(90);
  CHECK(FastThresholdScaler::organ_noise_ratio(luma.cview(), {}, valid.cview()) == 0.0);
  for (int y = 0; y < H; ++y)
    for (int x = 0; x < W; ++x) luma(x, y) = static_cast<std::uint8_t>(90 + ((x + y) % 2) * 10);
  CHECK(FastThresholdScaler::organ_noise_ratio(luma.cview(), {}, valid.cview()) == 1e3);
  valid.fill(0);
  CHECK(FastThresholdScaler::organ_noise_ratio(luma.cview(), {}, valid.cview()) == -1.0);
}

TEST_CASE("local map search: selects what the camera sees and finds each point's keypoint after a shift") {
  PlaneMap m(140);
  LocalMapSearch search;
  const Pinhole K = test_pinhole();
  REQUIRE(search.configure(256, CameraModel(K, Distortion{}), 1.2f, 8).ok());
  CHECK(search.select(m.map, SE3(), nullptr) == 140);
  // Turned away: nothing in view; from behind the plane: nothing either.
  CHECK(search.select(m.map, SE3(so3_exp(Vec3(0, 1.2, 0)), Vec3::Zero()), nullptr) == 0);
  CHECK(search.select(m.map, SE3(Mat3::Identity(), Vec3(0, 0, -400)), nullptr) == 0);
  // Every point matches its own keypoint, moved 6 px, within a 10 px radius
  // and not within 3 px.
  REQUIRE(search.select(m.map, SE3(), nullptr) == 140);
  OrbMatcher matcher;
  REQUIRE(matcher.configure(MatchConfig{}).ok());
  FeatureGrid grid;
  REQUIRE(grid.configure(640, 480).ok());
  const auto frame = frame_of(m, Vec2(6, 0));
  grid.build(*frame);
  search.search(3.f, *frame, grid, &matcher);
  int matched = 0;
  for (int i = 0; i < search.size(); ++i) matched += search.match(i) >= 0;
  CHECK(matched == 0);
  search.search(10.f, *frame, grid, &matcher);
  for (int i = 0; i < search.size(); ++i) {
    CAPTURE(i);
    REQUIRE(search.match(i) >= 0);
    CHECK(m.ids[static_cast<std::size_t>(search.match(i))] == search.point_id(i));  // its own keypoint
  }
  // The camera moved 6 px worth to the left: reprojected, 3 px suffice.
  search.reproject(m.map, SE3(Mat3::Identity(), Vec3(6.0 * 200.0 / 500.0, 0, 0)));
  search.search(3.f, *frame, grid, &matcher);
  matched = 0;
  for (int i = 0; i < search.size(); ++i)
    matched += search.match(i) >= 0 && m.ids[static_cast<std::size_t>(search.match(i))] == search.point_id(i);
  CHECK(matched == 140);
}

TEST_CASE("keyframe relocaliser: nearest keyframe first, cycling past culled ones, brute-force matches") {
  PlaneMap m(60);
  // Two more keyframes: 50 mm and 10 mm to the side of the first.
  const int far = m.map.add_keyframe(SE3(Mat3::Identity(), Vec3(-50, 0, 0)), 5, -1);
  const int near = m.map.add_keyframe(SE3(Mat3::Identity(), Vec3(-10, 0, 0)), 6, -1);
  KeyframeRelocaliser reloc;
  REQUIRE(reloc.configure(640, 480).ok());
  CHECK_FALSE(reloc.ranked());
  reloc.rank(m.map, SE3(Mat3::Identity(), Vec3(-12, 0, 0)), 200.0);
  CHECK(reloc.ranked());
  CHECK(reloc.next(m.map) == near);
  CHECK(reloc.next(m.map) == m.keyframe);
  CHECK(reloc.next(m.map) == far);
  CHECK(reloc.next(m.map) == near);  // cycles
  m.map.keyframe(m.keyframe).alive = false;
  CHECK(reloc.next(m.map) == far);   // skips the culled one
  reloc.forget_ranking();
  CHECK_FALSE(reloc.ranked());
  // The first keyframe's 60 points against a frame holding them all.
  m.map.keyframe(m.keyframe).alive = true;
  OrbMatcher matcher;
  REQUIRE(matcher.configure(MatchConfig{}).ok());
  const auto frame = frame_of(m, Vec2(40, -25));
  CHECK(reloc.match(m.map, m.keyframe, *frame, 100, &matcher) == 60);  // too few: no matching
  CHECK(reloc.match(m.map, m.keyframe, *frame, 30, &matcher) == 60);
  int right = 0;
  for (int q = 0; q < frame->count; ++q) right += reloc.matched_point(q) == m.ids[static_cast<std::size_t>(q)];
  CHECK(right == 60);
}

namespace {

// A channel that keeps one job and hands it back solved as given (or with
// a focal test's summary), as the mapping thread would.
class EchoChannel final : public BaChannel {
 public:
  EchoChannel() { REQUIRE(job_.configure(kMaxKeyframes, 256, 4096).ok()); }
  BaJob* acquire_job() override { return out_ ? nullptr : &job_; }
  void submit_job(BaJob* job) override {
    out_ = true;
    ++submitted;
    job->summary = BaSummary{};
    job->summary.usable = true;
    job->summary.focal_tested = job->test_focal;
    job->summary.focal_scale = focal_scale;
    job->summary.focal_f = focal_f;
    for (int i = 0; i < job->keyframe_count; ++i)
      if (!job->keyframes[static_cast<std::size_t>(i)].fixed) pose_to_params(moved, job->keyframes[static_cast<std::size_t>(i)].pose);
  }
  const BaJob* solved_job() override { return out_ ? &job_ : nullptr; }
  void release_job(const BaJob*) override { out_ = false; }
  BaJob job_;
  bool out_ = false;
  int submitted = 0;
  double focal_scale = 1, focal_f = 0;
  SE3 moved = SE3(Mat3::Identity(), Vec3(1, 2, 3));
};

}  // namespace

TEST_CASE("BA hand-off: a window job after a keyframe, newest keyframes free, applied back, old jobs dropped") {
  PlaneMap m(40);
  TrackerConfig c;
  c.max_map_points = 256;
  c.max_keyframes = 8;
  c.ba_window_keyframes = 2;
  c.check_calibration = false;
  BaHandoff ba;
  REQUIRE(ba.configure(c, SE3()).ok());
  EchoChannel channel;
  ba.set_channel(&channel);
  // Two newer keyframes linking the same points.
  for (int f = 1; f <= 2; ++f) {
    const int k = m.map.add_keyframe(SE3(Mat3::Identity(), Vec3(f, 0, 0)), f * 10, -1);
    for (int i = 0; i < m.map.keyframe(m.keyframe).link_count; ++i) REQUIRE(m.map.add_link(k, m.map.keyframe(m.keyframe).links[i]));
  }
  ba.map_initialised(m.map, m.keyframe);
  TrackResult r;
  CHECK_FALSE(ba.submit(m.map, true));  // nothing pending
  r.keyframe = true;
  r.state = TrackState::kTracking;
  ba.frame_done(m.map, r);
  CHECK_FALSE(ba.submit(m.map, false));  // not initialised
  REQUIRE(ba.submit(m.map, true));
  const BaJob& job = channel.job_;
  CHECK(job.kind == BaKind::kWindow);
  REQUIRE(job.keyframe_count == 3);
  int free_keyframes = 0;
  for (int i = 0; i < job.keyframe_count; ++i) free_keyframes += !job.keyframes[static_cast<std::size_t>(i)].fixed;
  CHECK(free_keyframes == 2);  // the window: frames 20 and 10; frame 0's keyframe held
  CHECK(job.point_count == 40);
  CHECK(job.observation_count == 120);
  CHECK_FALSE(ba.submit(m.map, true));  // one job out at a time (and nothing pending)
  // Applied at the next frame: the two free keyframes moved, the held one not.
  CHECK(ba.apply(&m.map));
  CHECK(m.map.keyframe(m.keyframe).T_camera_model.translation().norm() == 0.0);
  int moved = 0;
  for (int k = 0; k < m.map.keyframe_capacity(); ++k)
    moved += m.map.keyframe(k).alive && m.map.keyframe(k).T_camera_model.translation().isApprox(Vec3(1, 2, 3));
  CHECK(moved == 2);
  // A relocalisation asks for a global job; a job from before reset() is not applied.
  r.keyframe = false;
  r.state = TrackState::kRelocalised;
  ba.frame_done(m.map, r);
  REQUIRE(ba.submit(m.map, true));
  CHECK(channel.job_.kind == BaKind::kGlobal);
  ba.reset();
  CHECK_FALSE(ba.apply(&m.map));
  CHECK_FALSE(channel.out_);  // released all the same
}

namespace {

// A hand-off over a 20-point map with the echo channel, and a tracked
// keyframe's result to hand it frame by frame.
struct HandoffScene {
  explicit HandoffScene(int calibration_test_jobs) {
    TrackerConfig c;
    c.max_map_points = 256;
    c.max_keyframes = 8;
    c.calibration_test_jobs = calibration_test_jobs;
    REQUIRE(ba.configure(c, SE3()).ok());
    ba.set_channel(&channel);
    ba.map_initialised(m.map, m.keyframe);
    r.keyframe = true;
    r.state = TrackState::kTracking;
  }
  PlaneMap m{20};
  BaHandoff ba;
  EchoChannel channel;
  TrackResult r;
};

}  // namespace

TEST_CASE("BA hand-off: a focal test follows each of the first window jobs, writes nothing, and votes") {
  HandoffScene scene(10);
  PlaneMap& m = scene.m;
  BaHandoff& ba = scene.ba;
  EchoChannel& channel = scene.channel;
  TrackResult& r = scene.r;
  const SE3 window_pose(Mat3::Identity(), Vec3(1, 2, 3)), test_pose(Mat3::Identity(), Vec3(7, 7, 7));
  const auto window_job = [&] {
    channel.moved = window_pose;
    ba.frame_done(m.map, r);
    REQUIRE(ba.submit(m.map, true));
    CHECK(channel.job_.kind == BaKind::kWindow);
    CHECK_FALSE(channel.job_.test_focal);
    REQUIRE(ba.apply(&m.map));
  };
  const auto test_job = [&](double scale, double f, int frame) {
    channel.focal_scale = scale;
    channel.focal_f = f;
    channel.moved = test_pose;
    REQUIRE(ba.submit(m.map, true));
    CHECK(channel.job_.kind == BaKind::kFocalTest);
    CHECK(channel.job_.test_focal);
    CHECK(channel.job_.prior.keyframe < 0);
    CHECK_FALSE(ba.apply(&m.map));  // nothing written into the map
    CHECK_FALSE(channel.out_);
    for (int k = 0; k < m.map.keyframe_capacity(); ++k)
      if (m.map.keyframe(k).alive) CHECK_FALSE(m.map.keyframe(k).T_camera_model.translation().isApprox(Vec3(7, 7, 7)));
    ba.note_frame(frame);
  };
  const auto one_job = [&](double scale, double f, int frame) {
    window_job();
    test_job(scale, f, frame);
  };
  CHECK_FALSE(ba.submit(m.map, true));  // nothing pending before a window
  // A keyframe's window goes before a pending test.
  window_job();
  window_job();
  test_job(1.12, 500, 1);  // a vote
  CHECK_FALSE(ba.submit(m.map, true));  // one test per applied window
  one_job(1.01, 500, 2);   // within 5 %: the count restarts
  one_job(1.12, 500, 3);
  CHECK_FALSE(ba.calibration().suspect);
  one_job(1.10, 50, 4);    // F too small: restarts
  one_job(1.12, 500, 5);
  one_job(0.88, 500, 6);   // the other side: restarts at 1
  CHECK_FALSE(ba.calibration().suspect);
  one_job(0.88, 500, 7);
  CHECK(ba.calibration().suspect);
  CHECK(ba.calibration().suspect_frame == 7);
  CHECK(ba.calibration().focal_scale == doctest::Approx(0.88));
  CHECK(ba.calibration().tests == 7);
  // Only the first calibration_test_jobs windows are followed by a test.
  for (int k = 0; k < 3; ++k) one_job(1.0, 0, 8 + k);
  window_job();
  CHECK_FALSE(ba.submit(m.map, true));
}

TEST_CASE("BA hand-off: a focal test that three window jobs went before goes first") {
  HandoffScene scene(TrackerConfig{}.calibration_test_jobs);
  PlaneMap& m = scene.m;
  BaHandoff& ba = scene.ba;
  EchoChannel& channel = scene.channel;
  TrackResult& r = scene.r;
  // A keyframe every frame: a window job is always pending when the
  // channel is free, as on a mapping thread that never catches up.
  const auto next_kind = [&] {
    ba.frame_done(m.map, r);
    REQUIRE(ba.submit(m.map, true));
    const BaKind kind = channel.job_.kind;
    ba.apply(&m.map);
    REQUIRE_FALSE(channel.out_);
    return kind;
  };
  CHECK(next_kind() == BaKind::kWindow);  // the test is pending from here
  for (int k = 0; k < 3; ++k) CHECK(next_kind() == BaKind::kWindow);
  CHECK(next_kind() == BaKind::kFocalTest);
  CHECK(next_kind() == BaKind::kWindow);
  // A relocalisation's global job never waits for the test.
  for (int k = 0; k < 3; ++k) CHECK(next_kind() == BaKind::kWindow);
  r.state = TrackState::kRelocalised;
  CHECK(next_kind() == BaKind::kGlobal);
}
