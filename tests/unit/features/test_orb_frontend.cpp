// ORB frontend: masks on the real frame, zero allocations per frame, FAST
// against cv::FAST, steering, grid, matcher and bad input.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/features/fast9.h"
#include "core/features/feature_grid.h"
#include "core/features/orb_extractor.h"
#include "core/features/orb_matcher.h"
#include "core/image/valid_mask.h"
#include "support/alloc_guard.h"
#include "support/morph_reference.h"
#include "support/orb_fixtures.h"

using namespace st;
using namespace st::test;

namespace {

// Independent ground truth for the real frame: border = black pixels
// connected to the image corners (flood fill over luma <= 24);
// highlight = luma >= 225 (the frame's maximum is 235, limited range).
cv::Mat border_truth(const cv::Mat& luma) {
  cv::Mat dark = (luma <= 24) / 255;  // 1 where dark
  cv::Mat region = cv::Mat::zeros(luma.rows + 2, luma.cols + 2, CV_8UC1);
  for (const cv::Point seed : {cv::Point(0, 0), cv::Point(luma.cols - 1, 0), cv::Point(0, luma.rows - 1),
                               cv::Point(luma.cols - 1, luma.rows - 1)})
    if (dark.at<std::uint8_t>(seed)) cv::floodFill(dark, region, seed, cv::Scalar(2), nullptr, 0, 0, 4 | cv::FLOODFILL_MASK_ONLY | (255 << 8));
  return region(cv::Rect(1, 1, luma.cols, luma.rows)).clone();
}

// Keypoints whose FAST circle (radius 3 at their level) + 1 px touches a
// border or highlight pixel.
int keypoints_touching(const FeatureSet& f, const OrbExtractor& orb, const cv::Mat& bad) {
  int n = 0;
  for (int i = 0; i < f.count; ++i) {
    const Keypoint& k = f.keypoints[static_cast<std::size_t>(i)];
    const int r = static_cast<int>(std::ceil(3.f * orb.scale(k.octave))) + 1;
    bool touch = false;
    for (int dy = -r; dy <= r && !touch; ++dy)
      for (int dx = -r; dx <= r && !touch; ++dx) {
        const int x = static_cast<int>(std::lround(k.x)) + dx, y = static_cast<int>(std::lround(k.y)) + dy;
        if (dx * dx + dy * dy > r * r || x < 0 || y < 0 || x >= bad.cols || y >= bad.rows) continue;
        touch = bad.at<std::uint8_t>(y, x) != 0;
      }
    n += touch ? 1 : 0;
  }
  return n;
}

}  // namespace

TEST_CASE("orb masks: no keypoint on the black border or saturated highlights of the real frame") {
  const cv::Mat luma = real_frame_luma();
  REQUIRE(!luma.empty());
  const cv::Mat bad = border_truth(luma) | (luma >= 225);
  REQUIRE(cv::countNonZero(luma >= 225) > 100);  // the frame has highlights
  ValidMaskBuilder vmb;
  REQUIRE(vmb.configure(ValidMaskConfig{}, luma.cols, luma.rows));
  const GrayView valid = vmb.build(view_of(luma));
  REQUIRE(!valid.empty());
  MESSAGE("black level " << vmb.black_level() << ", highlight threshold " << vmb.highlight_threshold()
                         << ", highlight pixels " << vmb.highlight_pixels());
  const double valid_share = cv::countNonZero(mat_of(valid)) / static_cast<double>(valid.width * valid.height);
  CHECK(valid_share > 0.5);   // the scope's disc covers most of the frame
  CHECK(valid_share < 0.85);  // the border and highlights are gone
  OrbExtractor orb;
  REQUIRE(orb.configure(OrbConfig{}, luma.cols, luma.rows));
  auto f = std::make_unique<FeatureSet>();
  REQUIRE(orb.extract(view_of(luma), GrayView(), valid, *f));
  CHECK(f->count > 1000);
  CHECK(keypoints_touching(*f, orb, bad) == 0);
  // Control: without the valid mask the same frame does give such keypoints,
  // so the check above can fail.
  REQUIRE(orb.extract(view_of(luma), GrayView(), GrayView(), *f));
  const int unmasked_bad = keypoints_touching(*f, orb, bad);
  MESSAGE("keypoints on border/highlights without the valid mask: " << unmasked_bad);
  CHECK(unmasked_bad > 20);
}

TEST_CASE("orb masks: organ mask at 1/4 resolution restricts keypoints (with margin)") {
  const cv::Mat luma = real_frame_luma(1280, 720);
  REQUIRE(!luma.empty());
  cv::Mat organ = cv::Mat::zeros(180, 320, CV_8UC1);
  cv::rectangle(organ, cv::Rect(80, 40, 120, 90), cv::Scalar(255), cv::FILLED);  // x 320..800, y 160..520 full-res
  OrbConfig cfg;
  cfg.organ_margin_px = 8;
  OrbExtractor orb;
  REQUIRE(orb.configure(cfg, 1280, 720));
  auto f = std::make_unique<FeatureSet>();
  REQUIRE(orb.extract(view_of(luma), view_of(organ), GrayView(), *f));
  CHECK(f->count > 100);
  int outside = 0;
  for (int i = 0; i < f->count; ++i) {
    const Keypoint& k = f->keypoints[static_cast<std::size_t>(i)];
    if (k.x < 320 - 8 - 4 || k.x > 800 + 8 + 4 || k.y < 160 - 8 - 4 || k.y > 520 + 8 + 4) ++outside;
  }
  CHECK(outside == 0);
}

namespace {

// Extracts the real frame with the organ a rectangle (x 320..800, y 160..520
// full-res, given at 1/4 resolution) and counts the keypoints k closer than
// reach(k) to its outline; *total gets the keypoint count.
template <class Reach>
int near_rectangle_outline(const OrbConfig& cfg, Reach reach, int* total) {
  const cv::Mat luma = real_frame_luma(1280, 720);
  REQUIRE(!luma.empty());
  cv::Mat organ = cv::Mat::zeros(180, 320, CV_8UC1);
  cv::rectangle(organ, cv::Rect(80, 40, 120, 90), cv::Scalar(255), cv::FILLED);
  OrbExtractor orb;
  REQUIRE(orb.configure(cfg, 1280, 720));
  auto f = std::make_unique<FeatureSet>();
  REQUIRE(orb.extract(view_of(luma), view_of(organ), GrayView(), *f));
  int near = 0;
  for (int i = 0; i < f->count; ++i) {
    const Keypoint& k = f->keypoints[static_cast<std::size_t>(i)];
    const float r = reach(k);
    if (k.x - r < 320 || k.x + r > 800 || k.y - r < 160 || k.y + r > 520) ++near;
  }
  *total = f->count;
  return near;
}

}  // namespace

TEST_CASE("orb masks: a negative organ margin keeps keypoints that far inside the organ's outline") {
  // Within 28 px of the outline: 32 less one 1/4-resolution mask pixel.
  const auto band = [](const Keypoint&) { return 28.f; };
  OrbConfig cfg;
  cfg.organ_margin_px = -32;
  int total_eroded = 0, total_plain = 0;
  CHECK(near_rectangle_outline(cfg, band, &total_eroded) == 0);
  CHECK(total_eroded > 100);
  // Control: without the margin the band along the outline has keypoints.
  cfg.organ_margin_px = 0;
  CHECK(near_rectangle_outline(cfg, band, &total_plain) > 20);
  // Out of range either way is refused.
  OrbConfig bad;
  bad.organ_margin_px = -300;
  OrbExtractor orb;
  CHECK_FALSE(orb.configure(bad, 1280, 720));
}

TEST_CASE("orb masks: with organ_patch_inside every keypoint's descriptor patch lies on the organ") {
  // The patch circle (radius 16 px x 1.2^octave) less one mask pixel (4 px).
  const auto patch = [](const Keypoint& k) { return 16.f * std::pow(1.2f, static_cast<float>(k.octave)) - 4.f; };
  OrbConfig cfg;
  cfg.organ_margin_px = 0;
  cfg.organ_patch_inside = true;
  int with = 0, without = 0;
  CHECK(near_rectangle_outline(cfg, patch, &with) == 0);
  CHECK(with > 100);
  // Control: the centre alone lets such keypoints through.
  cfg.organ_patch_inside = false;
  CHECK(near_rectangle_outline(cfg, patch, &without) > 20);
  CHECK(without > with);
}

TEST_CASE("orb extract, valid mask, grid and matching allocate nothing per frame after warm-up") {
  const cv::Mat base = real_frame_luma(1280, 720);
  REQUIRE(!base.empty());
  std::vector<cv::Mat> frames;
  for (int i = 0; i < 4; ++i)
    frames.push_back(warp(base, centred_homography(1280, 720, 3.0 * i, 1.0 + 0.03 * i, 0, 0)));
  cv::Mat organ = cv::Mat::zeros(360, 640, CV_8UC1);
  cv::circle(organ, cv::Point(320, 180), 150, cv::Scalar(255), cv::FILLED);
  ValidMaskBuilder vmb;
  OrbExtractor orb;
  FeatureGrid grid;
  OrbMatcher matcher;
  REQUIRE(vmb.configure(ValidMaskConfig{}, 1280, 720));
  REQUIRE(orb.configure(OrbConfig{}, 1280, 720));
  REQUIRE(grid.configure(1280, 720));
  REQUIRE(matcher.configure(MatchConfig{}));
  auto prev = std::make_unique<FeatureSet>(), cur = std::make_unique<FeatureSet>();
  auto points = std::make_unique<std::array<ProjectedPoint, kMaxKeypoints>>();
  auto match = std::make_unique<std::array<int, kMaxMapPoints>>();
  auto step = [&](int i) {
    const GrayView frame = view_of(frames[static_cast<std::size_t>(i % 4)]);
    const GrayView valid = vmb.build(frame);
    orb.extract(frame, view_of(organ), valid, *cur);
    grid.build(*cur);
    for (int j = 0; j < prev->count; ++j) {
      const Keypoint& k = prev->keypoints[static_cast<std::size_t>(j)];
      (*points)[static_cast<std::size_t>(j)] = ProjectedPoint{k.x, k.y, 15.f, k.octave, k.angle_deg,
                                                              prev->descriptors[static_cast<std::size_t>(j)]};
    }
    matcher.search_by_projection(points->data(), prev->count, *cur, grid, match->data(), nullptr);
    matcher.match_brute_force(*cur, *prev, match->data(), nullptr);
    std::swap(prev, cur);
  };
  for (int i = 0; i < 3; ++i) step(i);  // warm-up
  AllocationCounter counter;
  for (int i = 0; i < 40; ++i) step(i);
  CHECK(counter.count() == 0);
  CHECK(prev->count > 500);
}

TEST_CASE("orb extract: never more keypoints than n_features (the map sizes a keyframe's links by it)") {
  const cv::Mat real = real_frame_luma(1280, 720);
  REQUIRE(!real.empty());
  cv::Mat noise_img(720, 1280, CV_8UC1);
  cv::randu(noise_img, cv::Scalar(0), cv::Scalar(256));  // a corner nearly everywhere, on every level
  const cv::Mat& noise = noise_img;
  auto out = std::make_unique<FeatureSet>();
  for (const int n : {50, 300, 1500, kMaxKeypoints}) {
    OrbConfig c;
    c.n_features = n;
    OrbExtractor orb;
    REQUIRE(orb.configure(c, 1280, 720));
    for (const cv::Mat* img : {&real, &noise}) {
      REQUIRE(orb.extract(view_of(*img), GrayView(), GrayView(), *out));
      CAPTURE(n);
      CHECK(out->count <= n);
      CHECK(out->count >= std::min(n, 40));
    }
  }
}

// A level's FAST scan holds at most OrbExtractor::kMaxLevelCorners corners;
// noise fills it and the scan is redone at a higher threshold, without
// allocating, and the keypoints still cover the whole frame (not only the
// rows scanned before the array was full).
TEST_CASE("orb extract: a scan that fills the corner arrays is redone at a higher threshold") {
  const cv::Mat real = real_frame_luma(1280, 720);
  REQUIRE(!real.empty());
  cv::Mat noise(720, 1280, CV_8UC1);
  cv::randu(noise, cv::Scalar(0), cv::Scalar(256));
  auto out = std::make_unique<FeatureSet>();
  OrbExtractor orb;
  REQUIRE(orb.configure(OrbConfig{}, 1280, 720));
  REQUIRE(orb.extract(view_of(real), GrayView(), GrayView(), *out));
  CHECK(orb.stats().threshold_raises == 0);  // a real frame never comes near it
  CHECK(orb.stats().fast_corners < OrbExtractor::kMaxLevelCorners);
  AllocationCounter counter;
  REQUIRE(orb.extract(view_of(noise), GrayView(), GrayView(), *out));
  CHECK(counter.count() == 0);
  MESSAGE("noise: " << orb.stats().threshold_raises << " scans redone, " << out->count << " keypoints");
  CHECK(orb.stats().threshold_raises >= 1);
  CHECK(out->count == 1500);
  int level0 = 0, bottom = 0;  // level-0 keypoints, and those in the frame's lowest quarter
  for (int i = 0; i < out->count; ++i) {
    const Keypoint& k = out->keypoints[static_cast<std::size_t>(i)];
    if (k.octave != 0) continue;
    ++level0;
    bottom += k.y > 540.f ? 1 : 0;
  }
  CHECK(level0 > 200);
  CHECK(bottom > level0 / 8);
}

TEST_CASE("orb fast9: corners agree with cv::FAST (TYPE_9_16, non-max suppression)") {
  const cv::Mat img = real_frame_luma(1280, 720);
  REQUIRE(!img.empty());
  for (int threshold : {7, 20}) {
    Fast9Detector fast;
    REQUIRE(fast.configure(1280));
    std::vector<FastCorner> ours(1280 * 720 / 4);
    const int n = fast.detect(view_of(img), threshold, 16, nullptr, 0, ours.data(), static_cast<int>(ours.size()));
    std::vector<cv::KeyPoint> ref;
    cv::FAST(img, ref, threshold, true, cv::FastFeatureDetector::TYPE_9_16);
    std::set<std::pair<int, int>> ref_set;
    for (const cv::KeyPoint& k : ref) {
      const int x = static_cast<int>(k.pt.x), y = static_cast<int>(k.pt.y);
      if (x >= 16 && y >= 16 && x < 1280 - 16 && y < 720 - 16) ref_set.insert({x, y});
    }
    int common = 0;
    for (int i = 0; i < n; ++i)
      common += ref_set.count({ours[static_cast<std::size_t>(i)].x, ours[static_cast<std::size_t>(i)].y}) ? 1 : 0;
    MESSAGE("threshold " << threshold << ": ours " << n << ", cv::FAST " << ref_set.size() << ", common " << common);
    CHECK(n > 100);
    // cv's suppression drops both pixels of a tied plateau, ours keeps one:
    // every cv corner must be ours, and ours has a few more.
    CHECK(common >= 0.97 * static_cast<double>(ref_set.size()));
    CHECK(n <= 1.2 * static_cast<double>(ref_set.size()));  // ours keeps one pixel of each plateau
    // Every corner we report passes the segment test at the threshold.
    for (int i = 0; i < n; i += 7)
      CHECK(fast9_score(view_of(img), ours[static_cast<std::size_t>(i)].x, ours[static_cast<std::size_t>(i)].y) > threshold);
  }
}

TEST_CASE("orb descriptor: steering follows a 90-degree rotation of the image") {
  const cv::Mat img = synthetic_texture(200, 200, 5);
  cv::Mat rot;
  cv::rotate(img, rot, cv::ROTATE_90_CLOCKWISE);  // (x, y) -> (199 - y, x)
  cv::Mat s0, s1;
  cv::GaussianBlur(img, s0, cv::Size(7, 7), 2.0);
  cv::GaussianBlur(rot, s1, cv::Size(7, 7), 2.0);
  OrbDescriptor d;
  int checked = 0, close = 0;
  // At textured points (flat patches have no defined orientation).
  for (int y = 40; y < 160; y += 3)
    for (int x = 40; x < 160; x += 3) {
      if (fast9_score(view_of(img), x, y) < 20) continue;
      const float a0 = OrbDescriptor::orientation_deg(view_of(img), x, y);
      const float a1 = OrbDescriptor::orientation_deg(view_of(rot), 199 - y, x);
      float diff = std::fmod(a1 - a0 + 720.f, 360.f);
      CHECK(std::abs(diff - 90.f) < 1.0f);
      Descriptor d0, d1;
      d.compute(view_of(s0), x, y, a0, d0.data());
      d.compute(view_of(s1), 199 - y, x, a1, d1.data());
      ++checked;
      close += hamming256(d0.data(), d1.data()) < 40 ? 1 : 0;
    }
  CHECK(checked > 20);
  CHECK(close >= 0.9 * checked);
}

TEST_CASE("orb matcher: search by projection, ratio, orientation check and bad input") {
  const cv::Mat img = real_frame_luma(1280, 720);
  OrbExtractor orb;
  REQUIRE(orb.configure(OrbConfig{}, 1280, 720));
  auto f = std::make_unique<FeatureSet>();
  REQUIRE(orb.extract(view_of(img), GrayView(), GrayView(), *f));
  FeatureGrid grid;
  REQUIRE(grid.configure(1280, 720));
  grid.build(*f);
  OrbMatcher m;
  REQUIRE(m.configure(MatchConfig{}));
  std::vector<ProjectedPoint> pts(static_cast<std::size_t>(f->count));
  for (int i = 0; i < f->count; ++i) {
    const Keypoint& k = f->keypoints[static_cast<std::size_t>(i)];
    pts[static_cast<std::size_t>(i)] = ProjectedPoint{k.x + 1.5f, k.y - 1.0f, 8.f, k.octave, k.angle_deg,
                                                      f->descriptors[static_cast<std::size_t>(i)]};
  }
  std::vector<int> match(pts.size()), dist(pts.size());
  const int n = m.search_by_projection(pts.data(), f->count, *f, grid, match.data(), dist.data());
  int right = 0;
  for (int i = 0; i < f->count; ++i) right += match[static_cast<std::size_t>(i)] == i ? 1 : 0;
  CHECK(n >= 0.9 * f->count);
  CHECK(right == n);
  // A small minority (< 10% of the fullest bin, ORB-SLAM's rule) with a
  // reference angle 90 degrees off is rejected by the rotation histogram.
  for (int i = 0; i < f->count; i += 40) pts[static_cast<std::size_t>(i)].ref_angle_deg = std::fmod(pts[static_cast<std::size_t>(i)].ref_angle_deg + 90.f, 360.f);
  m.search_by_projection(pts.data(), f->count, *f, grid, match.data(), dist.data());
  int rotated_kept = 0;
  for (int i = 0; i < f->count; i += 40) rotated_kept += match[static_cast<std::size_t>(i)] >= 0 ? 1 : 0;
  CHECK(rotated_kept == 0);
  CHECK(m.stats().orientation_rejected > 0);
  // Bad input: NaN position, negative radius, no points: no match, no crash.
  pts[0].x = std::nanf("");
  pts[1].radius_px = -3.f;
  m.search_by_projection(pts.data(), 2, *f, grid, match.data(), dist.data());
  CHECK(match[0] == -1);
  CHECK(match[1] == -1);
  CHECK(m.search_by_projection(pts.data(), 0, *f, grid, match.data(), nullptr) == 0);
  // Brute force against itself: identity.
  const int nb = m.match_brute_force(*f, *f, match.data(), nullptr);
  int ident = 0;
  for (int i = 0; i < f->count; ++i) ident += match[static_cast<std::size_t>(i)] == i ? 1 : 0;
  CHECK(nb >= 0.9 * f->count);
  CHECK(ident == nb);
}

TEST_CASE("orb feature grid: query equals a brute-force radius search") {
  auto f = std::make_unique<FeatureSet>();
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> ux(-5.f, 645.f), uy(-5.f, 485.f);
  f->count = 2000;
  for (int i = 0; i < f->count; ++i)
    f->keypoints[static_cast<std::size_t>(i)] = Keypoint{ux(rng), uy(rng), 0.f, 0.f, i % 8};
  FeatureGrid g;
  REQUIRE(g.configure(640, 480, 16));
  g.build(*f);
  std::vector<int> out(kMaxKeypoints);
  for (int q = 0; q < 200; ++q) {
    const float x = ux(rng), y = uy(rng), r = static_cast<float>(q % 40);
    const int lo = q % 3 == 0 ? -1 : 2, hi = q % 3 == 0 ? -1 : 4;
    const int n = g.query(x, y, r, lo, hi, out.data(), kMaxKeypoints);
    std::set<int> got(out.begin(), out.begin() + n), want;
    for (int i = 0; i < f->count; ++i) {
      const Keypoint& k = f->keypoints[static_cast<std::size_t>(i)];
      if (lo >= 0 && (k.octave < lo || k.octave > hi)) continue;
      if ((k.x - x) * (k.x - x) + (k.y - y) * (k.y - y) <= r * r) want.insert(i);
    }
    CHECK(got == want);
  }
}

TEST_CASE("orb configure rejects bad configs, extract and the mask builder reject wrong sizes") {
  OrbExtractor orb;
  OrbConfig c;
  c.n_features = kMaxKeypoints + 1;
  CHECK_FALSE(orb.configure(c, 1280, 720));
  c = OrbConfig{};
  c.levels = kMaxPyramidLevels + 1;
  CHECK_FALSE(orb.configure(c, 1280, 720));
  c = OrbConfig{};
  c.scale_factor = 1.0f;
  CHECK_FALSE(orb.configure(c, 1280, 720));
  c = OrbConfig{};
  c.fast_threshold_relaxed = 30;  // above the strict one
  CHECK_FALSE(orb.configure(c, 1280, 720));
  CHECK_FALSE(orb.configure(OrbConfig{}, 8, 8));
  CHECK_FALSE(orb.configure(OrbConfig{}, 100000, 720));
  REQUIRE(orb.configure(OrbConfig{}, 640, 480));
  const cv::Mat wrong(360, 640, CV_8UC1, cv::Scalar(0));
  auto f = std::make_unique<FeatureSet>();
  f->count = 5;
  CHECK_FALSE(orb.extract(view_of(wrong), GrayView(), GrayView(), *f));
  CHECK(f->count == 0);
  CHECK_FALSE(orb.extract(GrayView(), GrayView(), GrayView(), *f));
  // A flat frame: no corners, no crash.
  const cv::Mat flat(480, 640, CV_8UC1, cv::Scalar(128));
  CHECK(orb.extract(view_of(flat), GrayView(), GrayView(), *f));
  CHECK(f->count == 0);
  // A mask wider than kMaxImageWidth (the mask scratch's size) is refused.
  const cv::Mat huge_mask(2, kMaxImageWidth + 1, CV_8UC1, cv::Scalar(255));
  CHECK_FALSE(orb.extract(view_of(flat), view_of(huge_mask), GrayView(), *f));
  CHECK_FALSE(orb.extract(view_of(flat), GrayView(), view_of(huge_mask), *f));
  CHECK(f->count == 0);
  ValidMaskBuilder vmb;
  ValidMaskConfig vc;
  vc.downscale = 3;
  CHECK_FALSE(vmb.configure(vc, 640, 480));
  REQUIRE(vmb.configure(ValidMaskConfig{}, 640, 480));
  CHECK(vmb.build(view_of(wrong)).empty());
  // A frame without any black border is valid everywhere but highlights.
  CHECK(cv::countNonZero(mat_of(vmb.build(view_of(flat)))) == 320 * 240);
}

TEST_CASE("orb valid mask: highlight dilation (band of rows only) equals a full cv::dilate") {
  // Two highlight spots far apart vertically, on a frame without border.
  cv::Mat frame(480, 640, CV_8UC1, cv::Scalar(100));
  frame(cv::Rect(200, 40, 5, 3)).setTo(255);
  frame(cv::Rect(31, 300, 2, 7)).setTo(250);
  ValidMaskBuilder vmb;
  const ValidMaskConfig vc;  // downscale 2, dilation 6 px -> 3 mask pixels
  REQUIRE(vmb.configure(vc, frame.cols, frame.rows));
  const GrayView m = vmb.build(view_of(frame));
  REQUIRE(m.width == 320);
  // Reference: 2x2 block maximum, threshold, square dilation, inverted.
  cv::Mat sat(240, 320, CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < 240; ++y)
    for (int x = 0; x < 320; ++x) {
      const cv::Mat block = frame(cv::Rect(2 * x, 2 * y, 2, 2));
      double mx = 0;
      cv::minMaxLoc(block, nullptr, &mx);
      sat.at<std::uint8_t>(y, x) = mx >= vmb.highlight_threshold() ? 255 : 0;
    }
  const int r = (vc.highlight_dilate_px + vc.downscale - 1) / vc.downscale;
  const cv::Mat expected = 255 - test::opencv_morph_square(sat, r);
  CHECK(vmb.highlight_pixels() > 0);
  CHECK(cv::countNonZero(mat_of(m) != expected) == 0);
  CHECK(cv::countNonZero(expected == 0) > 0);
}
