// Descriptor distance: the SIMD Hamming path against the portable one and
// against OpenCV's own Hamming norm, on random and extreme descriptors.
#include <doctest/doctest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "core/features/feature_grid.h"
#include "core/features/orb_matcher.h"

namespace {

int opencv_hamming(const std::array<std::uint8_t, 32>& a, const std::array<std::uint8_t, 32>& b) {
  const cv::Mat ma(1, 32, CV_8U, const_cast<std::uint8_t*>(a.data()));
  const cv::Mat mb(1, 32, CV_8U, const_cast<std::uint8_t*>(b.data()));
  return static_cast<int>(cv::norm(ma, mb, cv::NORM_HAMMING));
}

}  // namespace

TEST_CASE("orb matcher: hamming256 equals the portable count and cv::norm(NORM_HAMMING)") {
  std::mt19937 rng(7);
  std::uniform_int_distribution<int> byte(0, 255);
  std::array<std::uint8_t, 32> a{}, b{};
  CHECK(st::hamming256(a.data(), b.data()) == 0);
  b.fill(0xff);
  CHECK(st::hamming256(a.data(), b.data()) == 256);
  CHECK(st::hamming256_portable(a.data(), b.data()) == 256);
  for (int i = 0; i < 2000; ++i) {
    for (auto& v : a) v = static_cast<std::uint8_t>(byte(rng));
    for (auto& v : b) v = static_cast<std::uint8_t>(byte(rng));
    if (i % 3 == 0) b[static_cast<std::size_t>(i % 32)] = a[static_cast<std::size_t>(i % 32)];  // some equal bytes
    const int expected = opencv_hamming(a, b);
    REQUIRE(st::hamming256(a.data(), b.data()) == expected);
    REQUIRE(st::hamming256_portable(a.data(), b.data()) == expected);
    if (st::cpu_has_popcnt()) REQUIRE(st::hamming256_popcnt(a.data(), b.data()) == expected);
  }
}

// Brute force (relocalisation) and search by projection (tracking) with
// the POPCNT count where the CPU has it: the same matches and distances as
// with the SIMD count, on 1500 x 1500 descriptors, half of them planted
// near-copies (a few bits flipped) so that matches, ratio rejections and
// the orientation filter all happen.
TEST_CASE("orb matcher: brute force and search by projection match the same with the POPCNT count as with the SIMD count") {
  std::mt19937 rng(11);
  auto query = std::make_unique<st::FeatureSet>(), train = std::make_unique<st::FeatureSet>();
  for (st::FeatureSet* f : {query.get(), train.get()}) {
    f->count = 1500;
    f->width = 1280;
    f->height = 720;
    for (int i = 0; i < f->count; ++i) {
      const auto is = static_cast<std::size_t>(i);
      for (auto& v : f->descriptors[is]) v = static_cast<std::uint8_t>(rng());
      f->keypoints[is].x = static_cast<float>(rng() % 1280);
      f->keypoints[is].y = static_cast<float>(rng() % 720);
      f->keypoints[is].angle_deg = static_cast<float>(rng() % 360);
      f->keypoints[is].octave = static_cast<int>(rng() % 8);
    }
  }
  for (int i = 0; i < 750; ++i) {  // near-copies, mostly with consistent angles
    const auto it = static_cast<std::size_t>(i), iq = static_cast<std::size_t>(2 * i);
    train->descriptors[it] = query->descriptors[iq];
    for (int flip = 0; flip < i % 40; ++flip) train->descriptors[it][rng() % 32] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
    if (i % 5) train->keypoints[it].angle_deg = std::fmod(query->keypoints[iq].angle_deg + 20.f, 360.f);
  }
  // Runs one search with the SIMD count, then with POPCNT (where the CPU
  // has it), and checks that the matches and distances are the same.
  const auto same_both_ways = [](const char* what, const auto& search) {
    std::vector<int> match[2], dist[2];
    int n[2] = {0, 0};
    for (int k = 0; k < 2; ++k) {
      st::OrbMatcher m;
      st::MatchConfig c;
      c.use_popcnt = k == 1;
      REQUIRE(m.configure(c).ok());
      match[k].assign(1500, -2);
      dist[k].assign(1500, -2);
      n[k] = search(m, match[k].data(), dist[k].data());
    }
    MESSAGE(std::string(what) << " matches " << n[0] << " / " << n[1] << "; POPCNT "
                 << std::string(st::cpu_has_popcnt() ? "used" : "absent"));
    CHECK(n[0] > 400);
    CHECK(n[0] == n[1]);
    CHECK(match[0] == match[1]);
    CHECK(dist[0] == dist[1]);
  };
  same_both_ways("brute force", [&](st::OrbMatcher& m, int* match, int* dist) {
    return m.match_brute_force(*query, *train, match, dist);
  });

  // Search by projection: the train keypoints as map points projected
  // 3 px off their query partner (or anywhere, for the unplanted ones).
  st::FeatureGrid grid;
  REQUIRE(grid.configure(1280, 720).ok());
  grid.build(*query);
  std::vector<st::ProjectedPoint> points(1500);
  for (int i = 0; i < 1500; ++i) {
    const auto is = static_cast<std::size_t>(i);
    const st::Keypoint& kp = i < 750 ? query->keypoints[2 * is] : train->keypoints[is];
    points[is].x = kp.x + 3.f;
    points[is].y = kp.y;
    points[is].radius_px = 20.f;
    points[is].predicted_octave = i % 3 ? kp.octave : -1;
    points[is].ref_angle_deg = train->keypoints[is].angle_deg;
    points[is].descriptor = train->descriptors[is];
  }
  same_both_ways("search by projection", [&](st::OrbMatcher& m, int* match, int* dist) {
    return m.search_by_projection(points.data(), 1500, *query, grid, match, dist);
  });
}

// The grid's branch-free scan writes past the hits; with a small capacity
// it must switch to the checked loop: never more than capacity written,
// every written index a true hit, and the count min(capacity, hits).
TEST_CASE("orb feature grid: a small output capacity is respected and filled with true hits") {
  auto f = std::make_unique<st::FeatureSet>();
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> ux(0.f, 320.f), uy(0.f, 240.f);
  f->count = 3000;
  for (int i = 0; i < f->count; ++i)
    f->keypoints[static_cast<std::size_t>(i)] = st::Keypoint{ux(rng), uy(rng), 0.f, 0.f, i % 4};
  st::FeatureGrid g;
  REQUIRE(g.configure(320, 240, 16));
  g.build(*f);
  for (int capacity : {0, 1, 3, 17, 64}) {
    std::vector<int> out(static_cast<std::size_t>(capacity) + 8, -7);  // 8 guard entries
    const float x = 160.f, y = 120.f, r = 40.f;
    const int n = g.query(x, y, r, 1, 2, out.data(), capacity);
    int hits = 0;
    for (int i = 0; i < f->count; ++i) {
      const st::Keypoint& k = f->keypoints[static_cast<std::size_t>(i)];
      hits += k.octave >= 1 && k.octave <= 2 && (k.x - x) * (k.x - x) + (k.y - y) * (k.y - y) <= r * r ? 1 : 0;
    }
    REQUIRE(hits > 64);
    CHECK(n == capacity);
    for (int j = 0; j < n; ++j) {
      const st::Keypoint& k = f->keypoints[static_cast<std::size_t>(out[static_cast<std::size_t>(j)])];
      CHECK((k.octave >= 1 && k.octave <= 2));
      CHECK((k.x - x) * (k.x - x) + (k.y - y) * (k.y - y) <= r * r);
    }
    for (std::size_t j = static_cast<std::size_t>(capacity); j < out.size(); ++j) CHECK(out[j] == -7);
  }
}

// Both forms of the grid query (AVX-512 where the CPU has it, portable)
// against the definition, in order: random queries of any radius and
// octave window, keypoints on the query circle exactly (integer offsets
// 3-4-5 from integer centres), keypoints stacked on one spot, runs of any
// length (cells hold 0 to ~60 keypoints).
TEST_CASE("orb feature grid: the AVX-512 and portable queries return the definition's hits in order") {
  auto f = std::make_unique<st::FeatureSet>();
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> ux(0.f, 640.f), uy(0.f, 480.f), ur(0.f, 60.f);
  std::uniform_int_distribution<int> oct(0, 7), cx(10, 630), cy(10, 470), kind(0, 3);
  f->count = 4000;
  std::vector<std::pair<int, int>> centres;
  for (int i = 0; i < f->count; ++i) {
    st::Keypoint k{ux(rng), uy(rng), 0.f, 0.f, oct(rng)};
    if (i % 4 == 0) {  // on the circle of radius 5 around an integer centre
      const int c = kind(rng);
      centres.emplace_back(cx(rng), cy(rng));
      k.x = static_cast<float>(centres.back().first + (c & 1 ? 3 : -4));
      k.y = static_cast<float>(centres.back().second + (c & 2 ? 4 : -3));
    } else if (i % 4 == 1) {  // many on one spot (a long run in one cell)
      k.x = 100.f;
      k.y = 200.f;
    }
    f->keypoints[static_cast<std::size_t>(i)] = k;
  }
  st::FeatureGrid g;
  REQUIRE(g.configure(640, 480, 16));
  g.build(*f);
  const bool avx512 = g.uses_avx512();
  if (avx512) MESSAGE("AVX-512 grid query tested too");
  std::vector<int> portable(4000), simd(4000);
  long hits_total = 0, on_circle = 0;
  for (int q = 0; q < 3000; ++q) {
    float x = ux(rng), y = uy(rng), r = ur(rng);
    if (q % 3 == 0) {  // exactly through keypoints on a circle
      const auto& c = centres[static_cast<std::size_t>(q) % centres.size()];
      x = static_cast<float>(c.first);
      y = static_cast<float>(c.second);
      r = 5.f;
    } else if (q % 3 == 1) {
      x = 100.f + (q % 7);
      y = 200.f;
    }
    const int lo = q % 5 == 0 ? -1 : oct(rng), hi = q % 5 == 0 ? -1 : std::min(7, lo + q % 3);
    std::vector<int> want;
    for (int i = 0; i < f->count; ++i) {
      const st::Keypoint& k = f->keypoints[static_cast<std::size_t>(i)];
      const float dx = k.x - x, dy = k.y - y;
      if ((lo < 0 || (k.octave >= lo && k.octave <= hi)) && dx * dx + dy * dy <= r * r) want.push_back(i);
      on_circle += q % 3 == 0 && dx * dx + dy * dy == r * r;
    }
    g.use_avx512(false);
    const int n = g.query(x, y, r, lo, hi, portable.data(), 4000);
    REQUIRE(n == static_cast<int>(want.size()));
    // The grid returns hits cell by cell: compare as sets, then the forms in order.
    std::vector<int> got(portable.begin(), portable.begin() + n);
    std::sort(got.begin(), got.end());
    CHECK(got == want);
    if (avx512) {
      g.use_avx512(true);
      REQUIRE(g.query(x, y, r, lo, hi, simd.data(), 4000) == n);
      CHECK(std::equal(portable.begin(), portable.begin() + n, simd.begin()));
    }
    hits_total += n;
  }
  CHECK(hits_total > 100000);
  CHECK(on_circle > 400);  // exact boundary cases occurred
}

// The tracker's refine pass skips points that found no candidate within
// max_distance in the previous, larger search (tracker_track.cpp): that
// relies on best_distances() being the true minimum over the candidates,
// and on inactive points leaving the other points' matches unchanged.
TEST_CASE("orb matcher: best_distances is the candidates' minimum, inactive points change no other match") {
  auto f = std::make_unique<st::FeatureSet>();
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> ux(0.f, 640.f), uy(0.f, 480.f);
  std::uniform_int_distribution<int> byte(0, 255), bit(0, 255);
  f->count = 1200;
  for (int i = 0; i < f->count; ++i) {
    f->keypoints[static_cast<std::size_t>(i)] = st::Keypoint{ux(rng), uy(rng), 10.f, 1.f, i % 3};
    for (auto& b : f->descriptors[static_cast<std::size_t>(i)]) b = static_cast<std::uint8_t>(byte(rng));
  }
  st::FeatureGrid grid;
  REQUIRE(grid.configure(640, 480, 16));
  grid.build(*f);
  // Half the points copy a keypoint's descriptor with a few bits flipped
  // (matchable), half are random (best distance ~90-110 against max 60).
  const int n = 800;
  std::vector<st::ProjectedPoint> pts(static_cast<std::size_t>(n));
  for (int i = 0; i < n; ++i) {
    st::ProjectedPoint& p = pts[static_cast<std::size_t>(i)];
    const int k = static_cast<int>(rng() % static_cast<unsigned>(f->count));
    const st::Keypoint& kp = f->keypoints[static_cast<std::size_t>(k)];
    p.x = kp.x + 3.f;
    p.y = kp.y - 2.f;
    p.radius_px = 12.f;
    p.predicted_octave = kp.octave;
    p.ref_angle_deg = 10.f;
    if (i % 2 == 0) {
      p.descriptor = f->descriptors[static_cast<std::size_t>(k)];
      for (int j = 0; j < 12; ++j) {
        const int b = bit(rng);
        p.descriptor[static_cast<std::size_t>(b / 8)] ^= static_cast<std::uint8_t>(1u << (b % 8));
      }
    } else {
      for (auto& b : p.descriptor) b = static_cast<std::uint8_t>(byte(rng));
    }
  }
  st::MatchConfig mc;
  mc.max_distance = 60;
  st::OrbMatcher m;
  REQUIRE(m.configure(mc));
  std::vector<int> match_all(static_cast<std::size_t>(n)), match_some(static_cast<std::size_t>(n));
  const int matched = m.search_by_projection(pts.data(), n, *f, grid, match_all.data(), nullptr);
  CHECK(matched > n / 4);
  const std::vector<std::uint16_t> best(m.best_distances().begin(), m.best_distances().begin() + n);
  std::vector<std::uint8_t> active(static_cast<std::size_t>(n));
  int unmatchable = 0;
  for (int i = 0; i < n; ++i) {
    const st::ProjectedPoint& p = pts[static_cast<std::size_t>(i)];
    int expected = st::OrbMatcher::kNoCandidate;  // brute force over the window the grid serves
    for (int k = 0; k < f->count; ++k) {
      const st::Keypoint& kp = f->keypoints[static_cast<std::size_t>(k)];
      const float dx = kp.x - p.x, dy = kp.y - p.y;
      if (std::abs(kp.octave - p.predicted_octave) > mc.octave_window || dx * dx + dy * dy > p.radius_px * p.radius_px) continue;
      expected = std::min(expected, st::hamming256(p.descriptor.data(), f->descriptors[static_cast<std::size_t>(k)].data()));
    }
    CHECK(best[static_cast<std::size_t>(i)] == expected);
    active[static_cast<std::size_t>(i)] = best[static_cast<std::size_t>(i)] <= mc.max_distance ? 1 : 0;
    unmatchable += active[static_cast<std::size_t>(i)] ? 0 : 1;
  }
  CHECK(unmatchable > n / 4);
  CHECK(m.search_by_projection(pts.data(), n, *f, grid, match_some.data(), nullptr, active.data()) == matched);
  CHECK(match_some == match_all);
  for (int i = 0; i < n; ++i)
    if (!active[static_cast<std::size_t>(i)]) CHECK(m.best_distances()[static_cast<std::size_t>(i)] == st::OrbMatcher::kNoCandidate);
}
