// Descriptor distance: the SIMD Hamming path against the portable one and
// against OpenCV's own Hamming norm, on random and extreme descriptors.
#include <doctest/doctest.h>

#include <array>
#include <cstdint>
#include <random>

#include <opencv2/core.hpp>

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
