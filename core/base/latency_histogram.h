// Latency statistics in fixed memory: a histogram of 10 us bins up to
// kMaxLatencyMs (larger values go to an overflow count and still enter the
// mean and maximum). Quantiles are exact to one bin width. add() is O(1)
// and allocates nothing: the replay's tracking thread records every
// frame's latency here, however long the sequence (no per-frame storage).
#pragma once

#include <array>
#include <cstdint>

namespace st {

class LatencyHistogram {
 public:
  static constexpr double kBinMs = 0.01;
  static constexpr double kMaxLatencyMs = 500.0;
  static constexpr int kBins = 50'000;  // kMaxLatencyMs / kBinMs

  void clear();
  // Negative or non-finite values count as 0 (a clock that went backwards
  // must not corrupt the statistics).
  void add(double latency_ms);

  std::int64_t count() const { return count_; }
  double mean_ms() const;  // 0 when empty
  double max_ms() const { return max_ms_; }
  // The smallest bin upper edge below which at least q (0..1) of the values
  // lie; values past the last bin report max_ms(). 0 when empty.
  double quantile_ms(double q) const;

 private:
  std::array<std::uint32_t, kBins> bins_{};
  std::int64_t count_ = 0;
  std::int64_t overflow_ = 0;
  double sum_ms_ = 0.0;
  double max_ms_ = 0.0;
};

}  // namespace st
