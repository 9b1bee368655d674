// Small deterministic random number generator (PCG32, O'Neill 2014) for
// sampling in real-time code: 16 bytes of state, no allocation, the same
// sequence on every platform and standard library (std:: distributions are
// implementation-defined, which would make RANSAC results differ by host).
#pragma once

#include <cstdint>

namespace st {

class Pcg32 {
 public:
  explicit Pcg32(std::uint64_t seed = 0x853c49e6748fea9bULL,
                 std::uint64_t stream = 0xda3e39cb94b95bdbULL) {
    reseed(seed, stream);
  }
  void reseed(std::uint64_t seed, std::uint64_t stream = 0xda3e39cb94b95bdbULL) {
    state_ = 0;
    inc_ = (stream << 1u) | 1u;
    next();
    state_ += seed;
    next();
  }
  std::uint32_t next() {
    const std::uint64_t old = state_;
    state_ = old * 6364136223846793005ULL + inc_;
    const auto xorshifted = static_cast<std::uint32_t>(((old >> 18u) ^ old) >> 27u);
    const auto rot = static_cast<std::uint32_t>(old >> 59u);
    return (xorshifted >> rot) | (xorshifted << ((32u - rot) & 31u));
  }
  // Uniform in [0, n) for n >= 1 (multiply-shift; bias below n / 2^32).
  std::uint32_t below(std::uint32_t n) {
    return static_cast<std::uint32_t>((static_cast<std::uint64_t>(next()) * n) >> 32u);
  }

 private:
  std::uint64_t state_ = 0, inc_ = 1;
};

}  // namespace st
