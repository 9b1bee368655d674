// ImagePyramid fast paths: tile-wise smoothing equals whole-level smoothing.
#include <doctest/doctest.h>

#include <cstdint>
#include <vector>

#include "core/image/image_pyramid.h"
#include "support/orb_fixtures.h"

using namespace st;
using namespace st::test;

TEST_CASE("orb pyramid: smooth_tiles is bit-identical to build() in the tiles it smooths") {
  const cv::Mat img = synthetic_texture(1283, 725, 7u);  // odd size: partial tiles at both edges
  ImagePyramid full, tiled;
  REQUIRE(full.configure(img.cols, img.rows, 8, 1.2f));
  REQUIRE(tiled.configure(img.cols, img.rows, 8, 1.2f));
  REQUIRE(full.build(view_of(img)));
  REQUIRE(tiled.build_levels(view_of(img)));
  constexpr int kT = ImagePyramid::kSmoothTilePx;
  for (int k = 0; k < full.levels(); ++k) {
    const GrayView lf = full.level(k), lt = tiled.level(k);
    const int tx = (lf.width + kT - 1) / kT, ty = (lf.height + kT - 1) / kT;
    std::vector<std::uint8_t> tiles(static_cast<std::size_t>(tx * ty), 0);
    for (int i = 0; i < tx * ty; ++i) tiles[static_cast<std::size_t>(i)] = (i % 3 != 1) ? 1 : 0;
    tiles.back() = 1;  // the bottom-right corner tile (both edges replicated)
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
