// ORB frontend shortcuts must not change results: FAST with a sparse chunk
// map (8 closed chunks skipped per 64-bit test) equals FAST everywhere
// filtered to the open chunks, and rBRIEF through precomputed pixel offsets
// equals the (dx, dy) path.
#include <doctest/doctest.h>

#include <random>
#include <set>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "core/features/fast9.h"
#include "core/features/orb_descriptor.h"
#include "support/orb_fixtures.h"

using namespace st;
using namespace st::test;

TEST_CASE("orb fast9: a sparse chunk map gives exactly the corners of the open chunks") {
  const cv::Mat img = real_frame_luma(1280, 720);
  REQUIRE(!img.empty());
  const int chunks = (1280 + 15) / 16;
  std::mt19937 rng(7);
  for (int threshold : {7, 13, 20}) {
    // Mostly closed rows, runs of open chunks of random length and place
    // (as the relaxed passes see them), one fully open and one fully closed row band.
    std::vector<std::uint8_t> allowed(static_cast<std::size_t>(720) * chunks, 0);
    for (int y = 0; y < 720; ++y) {
      std::uint8_t* row = allowed.data() + static_cast<std::ptrdiff_t>(y) * chunks;
      if (y >= 300 && y < 340) {
        std::fill(row, row + chunks, 1);
        continue;
      }
      if (y >= 400 && y < 440) continue;
      for (int run = 0; run < 3; ++run) {
        const int c0 = static_cast<int>(rng() % chunks), len = 1 + static_cast<int>(rng() % 12);
        for (int c = c0; c < std::min(c0 + len, chunks); ++c) row[c] = 1;
      }
    }
    Fast9Detector fast;
    REQUIRE(fast.configure(1280));
    std::vector<FastCorner> all(1280 * 720 / 4), masked(1280 * 720 / 4);
    const int n_all = fast.detect(view_of(img), threshold, 16, nullptr, 0, all.data(),
                                  static_cast<int>(all.size()));
    const int n_masked = fast.detect(view_of(img), threshold, 16, allowed.data(), chunks,
                                     masked.data(), static_cast<int>(masked.size()));
    // Suppression sees only scored pixels, so compare the scores of the open
    // pixels instead of the suppressed lists: every masked corner is open and
    // passes the threshold; every unmasked corner in an open chunk whose
    // 3x3 neighbourhood is all open is found by the masked run too.
    const auto open = [&](int x, int y) {
      return allowed[static_cast<std::size_t>(y) * chunks + (x >> 4)] != 0;
    };
    std::set<std::pair<int, int>> masked_set;
    for (int i = 0; i < n_masked; ++i) {
      const FastCorner& c = masked[static_cast<std::size_t>(i)];
      CHECK(open(c.x, c.y));
      CHECK(fast9_score(view_of(img), c.x, c.y) == c.score);
      CHECK(c.score > threshold);
      masked_set.insert({c.x, c.y});
    }
    int expected = 0, found = 0;
    for (int i = 0; i < n_all; ++i) {
      const FastCorner& c = all[static_cast<std::size_t>(i)];
      bool interior = true;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) interior = interior && open(c.x + dx, c.y + dy);
      if (!interior) continue;
      ++expected;
      found += masked_set.count({c.x, c.y}) ? 1 : 0;
    }
    MESSAGE("threshold " << threshold << ": all " << n_all << ", masked " << n_masked
                         << ", interior " << expected << " found " << found);
    CHECK(expected > 50);
    CHECK(found == expected);
  }
}

TEST_CASE("orb descriptor: precomputed pixel offsets give the same descriptors") {
  const cv::Mat img = synthetic_texture(320, 240, 11);
  cv::Mat smooth;
  cv::GaussianBlur(img, smooth, cv::Size(7, 7), 2.0);
  OrbDescriptor plain, offsets;
  REQUIRE(offsets.set_stride(static_cast<std::ptrdiff_t>(smooth.step[0])));
  CHECK(!plain.set_stride(4000));  // offsets beyond int16: falls back
  int checked = 0;
  for (int y = 16; y < 240 - 16; y += 5)
    for (int x = 16; x < 320 - 16; x += 7) {
      const float angle = OrbDescriptor::orientation_deg(view_of(img), x, y);
      Descriptor a{}, b{};
      plain.compute(view_of(smooth), x, y, angle, a.data());
      offsets.compute(view_of(smooth), x, y, angle, b.data());
      CHECK(a == b);
      ++checked;
    }
  CHECK(checked > 500);
  // An image of another stride takes the (dx, dy) path, with the same result.
  cv::Mat wide(240, 400, CV_8UC1, cv::Scalar(0));
  smooth.copyTo(wide(cv::Rect(0, 0, 320, 240)));
  const GrayView narrow_view(wide.ptr<std::uint8_t>(0), 320, 240,
                             static_cast<std::ptrdiff_t>(wide.step[0]));
  Descriptor a{}, b{};
  plain.compute(view_of(smooth), 100, 100, 33.f, a.data());
  offsets.compute(narrow_view, 100, 100, 33.f, b.data());
  CHECK(a == b);
}
