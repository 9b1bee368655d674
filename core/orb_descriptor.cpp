#include "core/orb_descriptor.h"

#include <cmath>
#include <numbers>

namespace st {
namespace {

// splitmix64: a tiny, fully specified generator (identical on every build).
struct SplitMix64 {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  int uniform(int lo, int hi) {  // inclusive
    return lo + static_cast<int>(next() % static_cast<std::uint64_t>(hi - lo + 1));
  }
};

// Sum of four uniform integers in [-5, 5]: mean 0, sigma ~6.3, integer only.
int gaussian_like(SplitMix64& rng) {
  int s = 0;
  for (int i = 0; i < 4; ++i) s += rng.uniform(-5, 5);
  return s;
}

constexpr int kPatternRadius2 = 14 * 14;

void random_point(SplitMix64& rng, int* x, int* y) {
  do {
    *x = gaussian_like(rng);
    *y = gaussian_like(rng);
  } while (*x * *x + *y * *y > kPatternRadius2);
}

// Half-width of the orientation disc per row offset |dy| <= 15.
struct DiscRows {
  int half[kOrbPatchRadius + 1];
  DiscRows() {
    for (int v = 0; v <= kOrbPatchRadius; ++v)
      // dx^2 + dy^2 <= r^2: symmetric under 90-degree rotations, so the
      // centroid turns exactly with the image.
      half[v] = static_cast<int>(std::floor(std::sqrt(static_cast<double>(
          kOrbPatchRadius * kOrbPatchRadius - v * v)) + 1e-9));
  }
};
const DiscRows kDisc;

}  // namespace

OrbDescriptor::OrbDescriptor() {
  SplitMix64 rng{0x5C09E7A11CEull};
  for (PointPair& p : pattern_) {
    int ax, ay, bx, by;
    do {
      random_point(rng, &ax, &ay);
      random_point(rng, &bx, &by);
    } while ((ax - bx) * (ax - bx) + (ay - by) * (ay - by) < 4);  // no near-identical pairs
    p = {static_cast<std::int8_t>(ax), static_cast<std::int8_t>(ay), static_cast<std::int8_t>(bx),
         static_cast<std::int8_t>(by)};
  }
  for (int k = 0; k < kOrbAngleBins; ++k) {
    const double a = 2.0 * std::numbers::pi * k / kOrbAngleBins;
    const double c = std::cos(a), s = std::sin(a);
    auto rot_x = [&](int x, int y) { return static_cast<std::int8_t>(std::lround(c * x - s * y)); };
    auto rot_y = [&](int x, int y) { return static_cast<std::int8_t>(std::lround(s * x + c * y)); };
    for (int i = 0; i < 256; ++i) {
      const PointPair& p = pattern_[static_cast<std::size_t>(i)];
      rotated_[static_cast<std::size_t>(k)][static_cast<std::size_t>(i)] = {
          rot_x(p.ax, p.ay), rot_y(p.ax, p.ay), rot_x(p.bx, p.by), rot_y(p.bx, p.by)};
    }
  }
}

float OrbDescriptor::orientation_deg(GrayView level, int x, int y) {
  int m10 = 0, m01 = 0;
  const std::uint8_t* c = level.row(y) + x;
  for (int dx = -kOrbPatchRadius; dx <= kOrbPatchRadius; ++dx) m10 += dx * c[dx];
  for (int dy = 1; dy <= kOrbPatchRadius; ++dy) {
    const std::uint8_t* up = c - dy * level.stride;
    const std::uint8_t* dn = c + dy * level.stride;
    const int h = kDisc.half[dy];
    int diff = 0, sum_x = 0;
    for (int dx = -h; dx <= h; ++dx) {
      diff += dn[dx] - up[dx];
      sum_x += dx * (dn[dx] + up[dx]);
    }
    m01 += dy * diff;
    m10 += sum_x;
  }
  float a = std::atan2(static_cast<float>(m01), static_cast<float>(m10)) *
            (180.0f / std::numbers::pi_v<float>);
  if (a < 0.f) a += 360.f;
  if (a >= 360.f) a -= 360.f;
  return a;
}

void OrbDescriptor::compute(GrayView smoothed_level, int x, int y, float angle_deg,
                            std::uint8_t* out32) const {
  int bin = static_cast<int>(std::lround(angle_deg * (kOrbAngleBins / 360.0f)));
  bin = ((bin % kOrbAngleBins) + kOrbAngleBins) % kOrbAngleBins;
  const std::array<PointPair, 256>& pat = rotated_[static_cast<std::size_t>(bin)];
  const std::uint8_t* c = smoothed_level.row(y) + x;
  const std::ptrdiff_t st = smoothed_level.stride;
  for (int byte = 0; byte < 32; ++byte) {
    unsigned v = 0;
    for (int bit = 0; bit < 8; ++bit) {
      const PointPair& p = pat[static_cast<std::size_t>(byte * 8 + bit)];
      const unsigned t = c[p.ay * st + p.ax] < c[p.by * st + p.bx] ? 1u : 0u;
      v |= t << bit;
    }
    out32[byte] = static_cast<std::uint8_t>(v);
  }
}

}  // namespace st
