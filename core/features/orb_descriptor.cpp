#include "core/features/orb_descriptor.h"

#include <cmath>
#include <numbers>

#include <opencv2/core/hal/intrin.hpp>

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

namespace {

// The disc moments m10 = sum dx * I, m01 = sum dy * I (integers).
void moments_scalar(GrayView level, int x, int y, int* m10_out, int* m01_out) {
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
  *m10_out = m10;
  *m01_out = m01;
}

#if CV_SIMD128
// Per row offset dy: the weights of the 32 columns dx = -16..15 for m10 (dx
// inside the disc row, else 0) and m01 (dy inside, else 0), int16.
struct MomentWeights {
  alignas(16) std::int16_t wx[kOrbPatchRadius + 1][32];
  alignas(16) std::int16_t wy[kOrbPatchRadius + 1][32];
  MomentWeights() {
    for (int dy = 0; dy <= kOrbPatchRadius; ++dy)
      for (int i = 0; i < 32; ++i) {
        const int dx = i - 16;
        const bool in = dx >= -kDisc.half[dy] && dx <= kDisc.half[dy];
        wx[dy][i] = static_cast<std::int16_t>(in ? dx : 0);
        wy[dy][i] = static_cast<std::int16_t>(in ? dy : 0);
      }
  }
};
const MomentWeights kWeights;

// Same sums as moments_scalar, 32 columns per row pair: (dn + up) and
// (dn - up) fit int16 (<= 510), products with the weights are summed in
// int32 by v_dotprod. Reads columns x - 16 .. x + 15.
void moments_simd(GrayView level, int x, int y, int* m10_out, int* m01_out) {
  cv::v_int32x4 a10 = cv::v_setzero_s32(), a01 = cv::v_setzero_s32();
  const std::uint8_t* c = level.row(y) + x - 16;
  for (int dy = 0; dy <= kOrbPatchRadius; ++dy) {
    const std::uint8_t* dn = c + dy * level.stride;
    cv::v_uint16x8 d[4], u[4];
    cv::v_expand(cv::v_load(dn), d[0], d[1]);
    cv::v_expand(cv::v_load(dn + 16), d[2], d[3]);
    if (dy == 0) {
      for (int i = 0; i < 4; ++i) u[i] = cv::v_setzero_u16();
    } else {
      const std::uint8_t* up = c - dy * level.stride;
      cv::v_expand(cv::v_load(up), u[0], u[1]);
      cv::v_expand(cv::v_load(up + 16), u[2], u[3]);
    }
    for (int i = 0; i < 4; ++i) {
      const cv::v_int16x8 sum = cv::v_reinterpret_as_s16(d[i] + u[i]);
      const cv::v_int16x8 diff = cv::v_reinterpret_as_s16(d[i]) - cv::v_reinterpret_as_s16(u[i]);
      a10 += cv::v_dotprod(sum, cv::v_load(kWeights.wx[dy] + 8 * i));
      a01 += cv::v_dotprod(diff, cv::v_load(kWeights.wy[dy] + 8 * i));
    }
  }
  *m10_out = cv::v_reduce_sum(a10);
  *m01_out = cv::v_reduce_sum(a01);
}
#endif

}  // namespace

float OrbDescriptor::orientation_deg(GrayView level, int x, int y) {
  int m10 = 0, m01 = 0;
#if CV_SIMD128
  if (x >= 16 && x + 16 <= level.width)  // the 32-column loads stay inside the row
    moments_simd(level, x, y, &m10, &m01);
  else
    moments_scalar(level, x, y, &m10, &m01);
#else
  moments_scalar(level, x, y, &m10, &m01);
#endif
  float a = std::atan2(static_cast<float>(m01), static_cast<float>(m10)) *
            (180.0f / std::numbers::pi_v<float>);
  if (a < 0.f) a += 360.f;
  if (a >= 360.f) a -= 360.f;
  return a;
}

bool OrbDescriptor::set_stride(std::ptrdiff_t stride) {
  offsets_stride_ = 0;
  constexpr int kReach = 14;  // pattern radius (the disc of random_point)
  if (stride <= 0 || stride * kReach + kReach > 32767) {
    offsets_.clear();
    return false;
  }
  offsets_.assign(static_cast<std::size_t>(kOrbAngleBins) * 512, 0);
  for (int k = 0; k < kOrbAngleBins; ++k)
    for (int i = 0; i < 256; ++i) {
      const PointPair& p = rotated_[static_cast<std::size_t>(k)][static_cast<std::size_t>(i)];
      std::int16_t* o = offsets_.data() + static_cast<std::ptrdiff_t>(k) * 512 + 2 * i;
      o[0] = static_cast<std::int16_t>(p.ay * stride + p.ax);
      o[1] = static_cast<std::int16_t>(p.by * stride + p.bx);
    }
  offsets_stride_ = stride;
  return true;
}

void OrbDescriptor::compute(GrayView smoothed_level, int x, int y, float angle_deg,
                            std::uint8_t* out32) const {
  int bin = static_cast<int>(std::lround(angle_deg * (kOrbAngleBins / 360.0f)));
  bin = ((bin % kOrbAngleBins) + kOrbAngleBins) % kOrbAngleBins;
  const std::uint8_t* c = smoothed_level.row(y) + x;
  if (offsets_stride_ != 0 && smoothed_level.stride == offsets_stride_) {
    const std::int16_t* o = offsets_.data() + static_cast<std::ptrdiff_t>(bin) * 512;
    for (int byte = 0; byte < 32; ++byte, o += 16) {
      unsigned v = 0;
      for (int bit = 0; bit < 8; ++bit) v |= (c[o[2 * bit]] < c[o[2 * bit + 1]] ? 1u : 0u) << bit;
      out32[byte] = static_cast<std::uint8_t>(v);
    }
    return;
  }
  const std::array<PointPair, 256>& pat = rotated_[static_cast<std::size_t>(bin)];
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
