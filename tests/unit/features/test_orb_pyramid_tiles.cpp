// ImagePyramid fast paths: tile-wise smoothing equals whole-level smoothing;
// the denoised level 0 equals the 3x3 binomial filter.
#include <doctest/doctest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include "core/image/image_pyramid.h"
#include "support/alloc_guard.h"
#include "support/orb_fixtures.h"

using namespace st;
using namespace st::test;

TEST_CASE("orb pyramid: smooth_tiles is bit-identical to the whole level's smoothing in the tiles it smooths") {
  const cv::Mat img = synthetic_texture(1283, 725, 7u);  // odd size: partial tiles at both edges
  ImagePyramid full, tiled;
  REQUIRE(full.configure(img.cols, img.rows, 8, 1.2f));
  REQUIRE(tiled.configure(img.cols, img.rows, 8, 1.2f));
  REQUIRE(full.build_levels(view_of(img)));
  REQUIRE(tiled.build_levels(view_of(img)));
  constexpr int kT = ImagePyramid::kSmoothTilePx;
  for (int k = 0; k < full.levels(); ++k) {
    const GrayView lf = full.level(k), lt = tiled.level(k);
    const int tx = (lf.width + kT - 1) / kT, ty = (lf.height + kT - 1) / kT;
    std::vector<std::uint8_t> tiles(static_cast<std::size_t>(tx * ty), 0);
    for (int i = 0; i < tx * ty; ++i) tiles[static_cast<std::size_t>(i)] = (i % 3 != 1) ? 1 : 0;
    tiles.back() = 1;  // the bottom-right corner tile (both edges replicated)
    full.smooth_level(k);  // one level at a time: the smoothing buffer is shared
    tiled.smooth_tiles(k, tiles.data(), tx);
    int compared = 0, differ = 0, level_differ = 0;
    for (int y = 0; y < lf.height; ++y)
      for (int x = 0; x < lf.width; ++x) {
        level_differ += lf(x, y) != lt(x, y);
        if (!tiles[static_cast<std::size_t>((y / kT) * tx + x / kT)]) continue;
        ++compared;
        differ += full.smoothed(k)(x, y) != tiled.smoothed(k)(x, y);
      }
    CHECK(level_differ == 0);
    CHECK(compared > 0);
    CHECK(differ == 0);
  }
}

TEST_CASE("orb pyramid: the denoised level 0 is the 3x3 binomial filter, edges replicated, without allocating") {
  const cv::Mat img = synthetic_texture(1283, 725, 11u);  // odd width: the SIMD loop's scalar tail
  ImagePyramid p;
  REQUIRE(p.configure(img.cols, img.rows, 4, 1.2f));
  const GrayView in = view_of(img);
  const test::AllocationCounter counter;
  REQUIRE(p.build_levels(in, true));
  CHECK(counter.count() == 0);
  const GrayView l0 = p.level(0);
  const auto at = [&](int x, int y) {
    return int{in(std::clamp(x, 0, in.width - 1), std::clamp(y, 0, in.height - 1))};
  };
  int differ = 0, changed = 0;
  for (int y = 0; y < in.height; ++y)
    for (int x = 0; x < in.width; ++x) {
      int sum = 8;
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) sum += (2 - std::abs(dx)) * (2 - std::abs(dy)) * at(x + dx, y + dy);
      differ += int{l0(x, y)} != sum / 16;
      changed += l0(x, y) != in(x, y);
    }
  CHECK(differ == 0);
  CHECK(changed > in.width * in.height / 4);  // the texture is not flat: the filter did something
  // Without denoise, level 0 is the image.
  REQUIRE(p.build_levels(in));
  int copied = 0;
  for (int y = 0; y < in.height; ++y)
    for (int x = 0; x < in.width; ++x) copied += p.level(0)(x, y) == in(x, y);
  CHECK(copied == in.width * in.height);
}
