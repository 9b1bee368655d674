// Quality of the ORB frontend against cv::ORB with the same feature count:
// repeatability and matching precision on homography warps of the real frame
// and of a synthetic texture. (The simulator's sequences are not available
// yet: warps of the real frame stand in for them.)
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>
#include <string>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "core/features/orb_extractor.h"
#include "core/features/orb_matcher.h"
#include "core/image/valid_mask.h"
#include "support/orb_fixtures.h"

using namespace st;
using namespace st::test;

namespace {

constexpr int kW = 1280, kH = 720, kFeatures = 1500;
constexpr float kRepeatPx = 3.f;  // a keypoint is repeated if one lies this close after warping
constexpr float kMatchPx = 5.f;   // a match is correct if it lands this close to the truth

cv::Point2f apply(const cv::Matx33d& H, float x, float y) {
  const cv::Vec3d p = H * cv::Vec3d(x, y, 1.0);
  return {static_cast<float>(p[0] / p[2]), static_cast<float>(p[1] / p[2])};
}

bool valid_at(const cv::Mat& valid_full, cv::Point2f p) {
  const int x = static_cast<int>(std::lround(p.x)), y = static_cast<int>(std::lround(p.y));
  return x >= 0 && y >= 0 && x < valid_full.cols && y < valid_full.rows && valid_full.at<std::uint8_t>(y, x);
}

struct Scores {
  double repeatability = 0, precision = 0, correct = 0, matches = 0;
  int n = 0;
  void add(const Scores& s) {
    repeatability += s.repeatability; precision += s.precision; correct += s.correct; matches += s.matches; ++n;
  }
  Scores mean() const {
    Scores m = *this;
    if (n) { m.repeatability /= n; m.precision /= n; m.correct /= n; m.matches /= n; }
    return m;
  }
};

// Repeatability: A keypoints that land (by H) in B's valid area and have a B
// keypoint within kRepeatPx, over the smaller count of keypoints in the
// common area. Precision: brute-force ratio-test matches (same matcher and
// ratio for both detectors) within kMatchPx of H * a, over all matches.
Scores evaluate(const FeatureSet& a, const FeatureSet& b, const cv::Matx33d& H, const cv::Mat& valid_a,
                const cv::Mat& valid_b) {
  const cv::Matx33d Hinv = H.inv();
  int na = 0, nb = 0, repeated = 0;
  for (int j = 0; j < b.count; ++j) {
    const Keypoint& k = b.keypoints[static_cast<std::size_t>(j)];
    if (valid_at(valid_a, apply(Hinv, k.x, k.y))) ++nb;
  }
  // One-to-one: each B keypoint repeats at most one A keypoint (nearest
  // unused), so detectors that fire on one corner at several levels are not
  // credited twice.
  std::vector<char> used(static_cast<std::size_t>(b.count), 0);
  for (int i = 0; i < a.count; ++i) {
    const Keypoint& k = a.keypoints[static_cast<std::size_t>(i)];
    const cv::Point2f p = apply(H, k.x, k.y);
    if (!valid_at(valid_b, p)) continue;
    ++na;
    int best = -1;
    float best_d = kRepeatPx;
    for (int j = 0; j < b.count; ++j) {
      const Keypoint& q = b.keypoints[static_cast<std::size_t>(j)];
      const float d = std::hypot(q.x - p.x, q.y - p.y);
      if (!used[static_cast<std::size_t>(j)] && d <= best_d) { best_d = d; best = j; }
    }
    if (best >= 0) { used[static_cast<std::size_t>(best)] = 1; ++repeated; }
  }
  MatchConfig mc;
  mc.check_orientation = false;  // descriptor and detector quality only
  OrbMatcher matcher;
  REQUIRE(matcher.configure(mc));
  std::vector<int> match(static_cast<std::size_t>(a.count));
  matcher.match_brute_force(a, b, match.data(), nullptr);
  int matches = 0, correct = 0;
  for (int i = 0; i < a.count; ++i) {
    if (match[static_cast<std::size_t>(i)] < 0) continue;
    ++matches;
    const Keypoint& k = a.keypoints[static_cast<std::size_t>(i)];
    const Keypoint& q = b.keypoints[static_cast<std::size_t>(match[static_cast<std::size_t>(i)])];
    const cv::Point2f p = apply(H, k.x, k.y);
    if (std::hypot(q.x - p.x, q.y - p.y) <= kMatchPx) ++correct;
  }
  Scores s;
  s.repeatability = std::min(na, nb) > 0 ? static_cast<double>(repeated) / std::min(na, nb) : 0.0;
  s.precision = matches > 0 ? static_cast<double>(correct) / matches : 0.0;
  s.correct = correct;
  s.matches = matches;
  return s;
}

// Evenness: share of 64x64 blocks, at least half valid, holding a keypoint.
double coverage(const FeatureSet& f, const cv::Mat& valid_full) {
  constexpr int kB = 64;
  const int bx = (valid_full.cols + kB - 1) / kB, by = (valid_full.rows + kB - 1) / kB;
  std::vector<int> hit(static_cast<std::size_t>(bx * by), 0);
  for (int i = 0; i < f.count; ++i) {
    const Keypoint& k = f.keypoints[static_cast<std::size_t>(i)];
    const int cx = std::clamp(static_cast<int>(k.x) / kB, 0, bx - 1), cy = std::clamp(static_cast<int>(k.y) / kB, 0, by - 1);
    hit[static_cast<std::size_t>(cy * bx + cx)] = 1;
  }
  int blocks = 0, covered = 0;
  for (int y = 0; y < by; ++y)
    for (int x = 0; x < bx; ++x) {
      const cv::Rect r = cv::Rect(x * kB, y * kB, kB, kB) & cv::Rect(0, 0, valid_full.cols, valid_full.rows);
      if (cv::countNonZero(valid_full(r)) * 2 < kB * kB) continue;
      ++blocks;
      covered += hit[static_cast<std::size_t>(y * bx + x)];
    }
  return blocks ? static_cast<double>(covered) / blocks : 0.0;
}

struct Detectors {
  OrbExtractor ours;
  ValidMaskBuilder valid;
  cv::Ptr<cv::ORB> cv_orb = cv::ORB::create(kFeatures, 1.2f, 8);
  cv::Ptr<cv::ORB> cv_default = cv::ORB::create(kFeatures, 1.2f, 8);
  Detectors() {
    const OrbConfig oc;
    REQUIRE(ours.configure(oc, kW, kH));
    // Same feature count: on smooth tissue cv::ORB's default FAST threshold
    // (20) finds fewer than 1500 corners, so the asserted baseline uses our
    // relaxed threshold and delivers 1500 like ours; the default cv::ORB is
    // reported alongside.
    cv_orb->setFastThreshold(oc.fast_threshold_relaxed);
    REQUIRE(valid.configure(ValidMaskConfig{}, kW, kH));
  }
  // Both detectors see the same valid mask (full-resolution copy in valid_full).
  void run(const cv::Mat& img, FeatureSet& f_ours, FeatureSet& f_cv, FeatureSet& f_cvd, cv::Mat& valid_full) {
    const GrayView vm = valid.build(view_of(img));
    cv::resize(mat_of(vm), valid_full, img.size(), 0, 0, cv::INTER_NEAREST);
    REQUIRE(ours.extract(view_of(img), GrayView(), vm, f_ours));
    std::vector<cv::KeyPoint> kps;
    cv::Mat desc;
    cv_orb->detectAndCompute(img, valid_full, kps, desc);
    to_feature_set(kps, desc, img.cols, img.rows, f_cv);
    cv_default->detectAndCompute(img, valid_full, kps, desc);
    to_feature_set(kps, desc, img.cols, img.rows, f_cvd);
  }
};

struct Warp {
  const char* name;
  double rot_deg, scale, px, py;
};
constexpr Warp kWarps[] = {
    {"rot 10", 10, 1.0, 0, 0},           {"rot 30", 30, 1.0, 0, 0},
    {"scale 0.8", 0, 0.8, 0, 0},         {"scale 1.25", 0, 1.25, 0, 0},
    {"persp x", 0, 1.0, 2.5e-4, 0},      {"persp y + rot 5", 5, 1.0, 0, 3e-4},
    {"rot 20 scale 1.1 persp", 20, 1.1, 1.5e-4, 1e-4},
};

void compare_on(const char* image_name, const cv::Mat& base, Scores& ours_total, Scores& cv_total,
                Scores& cvd_total) {
  auto d = std::make_unique<Detectors>();
  auto fa = std::make_unique<FeatureSet>(), fb = std::make_unique<FeatureSet>();
  auto ca = std::make_unique<FeatureSet>(), cb = std::make_unique<FeatureSet>();
  auto da = std::make_unique<FeatureSet>(), db = std::make_unique<FeatureSet>();
  cv::Mat valid_a, valid_b;
  d->run(base, *fa, *ca, *da, valid_a);
  MESSAGE(std::string(image_name) << " coverage of 64x64 blocks: ours " << coverage(*fa, valid_a)
                                  << " | cv::ORB " << coverage(*ca, valid_a));
  for (const Warp& w : kWarps) {
    const cv::Matx33d H = centred_homography(kW, kH, w.rot_deg, w.scale, w.px, w.py);
    const cv::Mat warped = warp(base, H);
    d->run(warped, *fb, *cb, *db, valid_b);
    const Scores so = evaluate(*fa, *fb, H, valid_a, valid_b);
    const Scores sc = evaluate(*ca, *cb, H, valid_a, valid_b);
    const Scores sd = evaluate(*da, *db, H, valid_a, valid_b);
    cvd_total.add(sd);
    MESSAGE(std::string(image_name) << " / " << std::string(w.name) << ": ours n=" << fa->count << "/" << fb->count
                       << " rep=" << so.repeatability << " prec=" << so.precision << " correct=" << so.correct
                       << " | cv::ORB n=" << ca->count << "/" << cb->count << " rep=" << sc.repeatability
                       << " prec=" << sc.precision << " correct=" << sc.correct << " | cv::ORB default n="
                       << da->count << "/" << db->count << " rep=" << sd.repeatability << " prec=" << sd.precision);
    ours_total.add(so);
    cv_total.add(sc);
  }
}

void check_within_5_percent(const char* what, const Scores& ours, const Scores& cv) {
  MESSAGE(std::string(what) << " mean over warps: ours rep=" << ours.repeatability << " prec=" << ours.precision
               << " correct=" << ours.correct << " | cv::ORB rep=" << cv.repeatability
               << " prec=" << cv.precision << " correct=" << cv.correct);
  CHECK(ours.repeatability >= 0.95 * cv.repeatability);
  CHECK(ours.precision >= 0.95 * cv.precision);
}

}  // namespace

TEST_CASE("orb quality: real frame warps, repeatability and precision within 5% of cv::ORB") {
  cv::setNumThreads(1);
  const cv::Mat base = real_frame_luma(kW, kH);
  REQUIRE(!base.empty());
  Scores ours, cvs, cvd;
  compare_on("real", base, ours, cvs, cvd);
  MESSAGE("real, cv::ORB default (threshold 20): rep=" << cvd.mean().repeatability << " prec=" << cvd.mean().precision);
  check_within_5_percent("real", ours.mean(), cvs.mean());
}

TEST_CASE("orb quality: synthetic texture warps, repeatability and precision within 5% of cv::ORB") {
  cv::setNumThreads(1);
  const cv::Mat base = synthetic_texture(kW, kH, 11);
  Scores ours, cvs, cvd;
  compare_on("synthetic", base, ours, cvs, cvd);
  MESSAGE("synthetic, cv::ORB default (threshold 20): rep=" << cvd.mean().repeatability << " prec=" << cvd.mean().precision);
  check_within_5_percent("synthetic", ours.mean(), cvs.mean());
}
