// Descriptor distance: the SIMD Hamming path against the portable one and
// against OpenCV's own Hamming norm, on random and extreme descriptors.
#include <doctest/doctest.h>

#include <array>
#include <cstdint>
#include <memory>
#include <random>
#include <set>
#include <vector>

#include <opencv2/core.hpp>

#include "core/feature_grid.h"
#include "core/orb_matcher.h"

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
  }
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
