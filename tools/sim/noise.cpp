#include "tools/sim/noise.h"

#include <cmath>
#include <numeric>

#include "tools/sim/rng.h"

namespace st::sim {
namespace {

// Quintic fade: C2 continuity, no lattice-aligned creases in shading.
inline float fade(float t) { return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f); }
inline float lerp(float a, float b, float t) { return a + t * (b - a); }

// 12 edge directions of a cube (Perlin's improved noise) picked by hash.
inline float grad(int h, float x, float y, float z) {
  switch (h % 12) {
    case 0: return x + y;
    case 1: return -x + y;
    case 2: return x - y;
    case 3: return -x - y;
    case 4: return x + z;
    case 5: return -x + z;
    case 6: return x - z;
    case 7: return -x - z;
    case 8: return y + z;
    case 9: return -y + z;
    case 10: return y - z;
    default: return -y - z;
  }
}

}  // namespace

Noise3::Noise3(std::uint64_t seed) {
  std::array<int, 256> p{};
  std::iota(p.begin(), p.end(), 0);
  Rng rng(seed);
  for (int i = 255; i > 0; --i) {
    const int j = static_cast<int>(rng.next_u64() % static_cast<std::uint64_t>(i + 1));
    std::swap(p[i], p[j]);
  }
  for (int i = 0; i < 256; ++i) {
    perm_[i] = static_cast<std::uint8_t>(p[i]);
    values_[i] = static_cast<float>(rng.uniform());
  }
}

float Noise3::gradient(float x, float y, float z) const {
  const float fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const int X = static_cast<int>(fx), Y = static_cast<int>(fy), Z = static_cast<int>(fz);
  x -= fx;
  y -= fy;
  z -= fz;
  const float u = fade(x), v = fade(y), w = fade(z);
  const float n000 = grad(hash(X, Y, Z), x, y, z);
  const float n100 = grad(hash(X + 1, Y, Z), x - 1, y, z);
  const float n010 = grad(hash(X, Y + 1, Z), x, y - 1, z);
  const float n110 = grad(hash(X + 1, Y + 1, Z), x - 1, y - 1, z);
  const float n001 = grad(hash(X, Y, Z + 1), x, y, z - 1);
  const float n101 = grad(hash(X + 1, Y, Z + 1), x - 1, y, z - 1);
  const float n011 = grad(hash(X, Y + 1, Z + 1), x, y - 1, z - 1);
  const float n111 = grad(hash(X + 1, Y + 1, Z + 1), x - 1, y - 1, z - 1);
  const float a = lerp(lerp(n000, n100, u), lerp(n010, n110, u), v);
  const float b = lerp(lerp(n001, n101, u), lerp(n011, n111, u), v);
  return lerp(a, b, w);
}

float Noise3::value(float x, float y, float z) const {
  const float fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const int X = static_cast<int>(fx), Y = static_cast<int>(fy), Z = static_cast<int>(fz);
  const float u = fade(x - fx), v = fade(y - fy), w = fade(z - fz);
  auto val = [&](int i, int j, int k) { return values_[hash(X + i, Y + j, Z + k)]; };
  const float a = lerp(lerp(val(0, 0, 0), val(1, 0, 0), u), lerp(val(0, 1, 0), val(1, 1, 0), u), v);
  const float b = lerp(lerp(val(0, 0, 1), val(1, 0, 1), u), lerp(val(0, 1, 1), val(1, 1, 1), u), v);
  return lerp(a, b, w);
}

Noise3::Cell Noise3::cellular(float x, float y, float z) const {
  const float fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  const int X = static_cast<int>(fx), Y = static_cast<int>(fy), Z = static_cast<int>(fz);
  Cell best{1e9f, 0.0f};
  for (int k = -1; k <= 1; ++k)
    for (int j = -1; j <= 1; ++j)
      for (int i = -1; i <= 1; ++i) {
        const int h = hash(X + i, Y + j, Z + k);
        // Jitter within the cell from three further table lookups.
        const float px = static_cast<float>(i) + values_[h] - (x - fx);
        const float py = static_cast<float>(j) + values_[(h + 71) & 255] - (y - fy);
        const float pz = static_cast<float>(k) + values_[(h + 157) & 255] - (z - fz);
        const float d2 = px * px + py * py + pz * pz;
        if (d2 < best.distance) best = {d2, values_[(h + 211) & 255]};
      }
  best.distance = std::sqrt(best.distance);
  return best;
}

float Noise3::fbm(float x, float y, float z, int octaves, float gain) const {
  float sum = 0.0f, amp = 1.0f, norm = 0.0f;
  for (int i = 0; i < octaves; ++i) {
    sum += amp * gradient(x, y, z);
    norm += amp;
    amp *= gain;
    // Non-integer lacunarity and an offset keep octaves from aligning.
    x = x * 2.03f + 17.1f;
    y = y * 2.03f + 5.3f;
    z = z * 2.03f + 11.7f;
  }
  return sum / norm;
}

float Noise3::ridge(float x, float y, float z, float width) const {
  const float n = std::abs(gradient(x, y, z));
  if (n >= width) return 0.0f;
  const float t = 1.0f - n / width;
  return t * t;
}

}  // namespace st::sim
