// Random vectors for test fixtures, drawn one component after the other
// (x, then y, then z). Vec3(d(rng), d(rng), d(rng)) leaves the order of the
// three draws to the compiler: GCC takes a call's arguments right to left on
// x86-64 and left to right on aarch64, so such a fixture is another one on
// the scope processor (and with another compiler) than on the host.
#pragma once

#include <random>

#include "core/geometry/se3.h"

namespace st::test {

// x from dx, then y from dy (an image position from per-axis ranges).
template <typename DistX, typename DistY, typename Rng>
Vec2 draw_vec2(DistX& dx, DistY& dy, Rng& rng) {
  const double x = dx(rng);
  const double y = dy(rng);
  return {x, y};
}

template <typename Dist, typename Rng>
Vec2 draw_vec2(Dist& d, Rng& rng) {
  return draw_vec2(d, d, rng);
}

template <typename Dist, typename Rng>
Vec3 draw_vec3(Dist& d, Rng& rng) {
  const Vec2 xy = draw_vec2(d, rng);
  const double z = d(rng);
  return {xy.x(), xy.y(), z};
}

// A direction uniform on the unit sphere.
inline Vec3 random_unit(std::mt19937& rng) {
  std::normal_distribution<double> g(0.0, 1.0);
  return draw_vec3(g, rng).normalized();
}

}  // namespace st::test
