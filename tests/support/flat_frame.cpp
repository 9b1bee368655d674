#include "tests/support/flat_frame.h"

#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "core/raster/rasterizer.h"
#include "tests/support/raster_scene.h"

namespace st::test {

Frame render_flat(const Mesh& mesh, const Pinhole& K, const SE3& T, std::uint64_t seed) {
  MeshRasterizer r;
  REQUIRE(r.configure(mesh, raster_config(K)));
  r.render(T, K);
  Frame f;
  f.w = K.width;
  f.h = K.height;
  const int cw = (f.w + 1) / 2, ch = (f.h + 1) / 2;
  f.y.assign(static_cast<std::size_t>(f.w * f.h), 0);
  f.u.assign(static_cast<std::size_t>(cw * ch), 0);
  f.v.assign(static_cast<std::size_t>(cw * ch), 0);
  std::mt19937 gen(static_cast<std::uint32_t>(seed));
  std::normal_distribution<double> nd;
  const auto normal = [&] { return nd(gen); };
  const auto m = r.mask();
  for (int y = 0; y < f.h; ++y)
    for (int x = 0; x < f.w; ++x) {
      const double falloff = 1.0 - 0.3 * (std::hypot(x - K.cx, y - K.cy) / K.width);
      const double base = m(x, y) ? 95.0 : 165.0;
      const double val = base * falloff + 3.0 * normal();
      f.y[static_cast<std::size_t>(y * f.w + x)] = static_cast<std::uint8_t>(std::clamp(val, 0.0, 255.0));
    }
  for (int y = 0; y < ch; ++y)
    for (int x = 0; x < cw; ++x) {
      // 4:2:0 chroma: the mean over its 2x2 luma pixels.
      double organ = 0;
      for (int k = 0; k < 4; ++k)
        organ += m(std::min(2 * x + (k & 1), f.w - 1), std::min(2 * y + (k >> 1), f.h - 1)) ? 0.25 : 0.0;
      f.u[static_cast<std::size_t>(y * cw + x)] = static_cast<std::uint8_t>(std::lround(92 + 20 * organ + 2 * normal()));
      f.v[static_cast<std::size_t>(y * cw + x)] = static_cast<std::uint8_t>(std::lround(150 + 18 * organ + 2 * normal()));
    }
  return f;
}

}  // namespace st::test
