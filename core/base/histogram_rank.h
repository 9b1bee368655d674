// Order statistics of a fixed-size count histogram (no allocation): the
// median block-mean luma of the valid mask, the median texture contrast of
// the tracker's FAST threshold scale.
#pragma once

#include <array>
#include <cstddef>

namespace st {

// The value below which at most `rank` of the histogram's samples lie: the
// first bin whose cumulative count exceeds rank (N - 1 if none). For the
// median of n > 0 samples (the lower one when n is even) pass (n - 1) / 2.
template <std::size_t N>
int histogram_rank(const std::array<int, N>& hist, long long rank) {
  long long acc = 0;
  int level = 0;
  while (level < static_cast<int>(N) - 1 && acc + hist[static_cast<std::size_t>(level)] <= rank)
    acc += hist[static_cast<std::size_t>(level++)];
  return level;
}

}  // namespace st
