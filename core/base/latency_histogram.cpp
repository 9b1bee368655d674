#include "core/base/latency_histogram.h"

#include <algorithm>
#include <cmath>

namespace st {

void LatencyHistogram::clear() {
  bins_.fill(0);
  count_ = overflow_ = 0;
  sum_ms_ = max_ms_ = 0.0;
}

void LatencyHistogram::add(double latency_ms) {
  const double v = std::isfinite(latency_ms) && latency_ms > 0.0 ? latency_ms : 0.0;
  ++count_;
  sum_ms_ += v;
  max_ms_ = std::max(max_ms_, v);
  const double bin = std::floor(v / kBinMs);
  if (bin >= kBins) {
    ++overflow_;
    return;
  }
  ++bins_[static_cast<std::size_t>(bin)];
}

double LatencyHistogram::mean_ms() const {
  return count_ > 0 ? sum_ms_ / static_cast<double>(count_) : 0.0;
}

double LatencyHistogram::quantile_ms(double q) const {
  if (count_ == 0) return 0.0;
  const double qc = std::clamp(q, 0.0, 1.0);
  // Rank of the value we want (1-based), at least the first value.
  const std::int64_t rank =
      std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(qc * static_cast<double>(count_))));
  std::int64_t seen = 0;
  for (int b = 0; b < kBins; ++b) {
    seen += bins_[static_cast<std::size_t>(b)];
    // The bin's upper edge, but never above the largest value seen.
    if (seen >= rank) return std::min((b + 1) * kBinMs, max_ms_);
  }
  return max_ms_;
}

}  // namespace st
