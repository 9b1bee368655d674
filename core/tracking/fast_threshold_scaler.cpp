#include "core/tracking/fast_threshold_scaler.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdlib>

#include "core/base/histogram_rank.h"

namespace st {

void FastThresholdScaler::configure(double reference_luma, double reference_contrast) {
  reference_luma_ = reference_luma;
  reference_contrast_ = reference_contrast;
}

FastThresholdScale FastThresholdScaler::measure(GrayView luma, GrayView organ, GrayView valid,
                                                const ValidMaskBuilder& valid_mask) const {
  constexpr int kBlack = 16;
  FastThresholdScale out;
  if (valid.empty()) return out;
  double s = 1.0;
  if (reference_luma_ > kBlack) {
    const int median = valid_mask.median_block_mean(valid, organ);
    if (median >= 0) s = std::min(1.0, static_cast<double>(median - kBlack) / (reference_luma_ - kBlack));
  }
  if (reference_contrast_ > 0) {
    const double contrast = organ_contrast(luma, organ, valid);
    if (contrast >= 0 && contrast < s * reference_contrast_) {
      s = contrast / reference_contrast_;
      out.low_contrast = true;
    }
  }
  out.scale = static_cast<float>(std::clamp(s, 0.0, 1.0));
  return out;
}

double FastThresholdScaler::organ_contrast(GrayView luma, GrayView organ, GrayView valid) {
  constexpr int kStep = 16, kBlock = 4;
  constexpr int kBins = 1024;  // in 1/16 luma units (block sums of 16 pixels)
  std::array<int, kBins> hist{};
  long long n = 0;
  const GrayView& v = valid;
  const auto block = [&](int x, int y) {
    int sum = 0;
    for (int j = 0; j < kBlock; ++j) {
      const std::uint8_t* row = luma.row(y + j) + x;
      for (int i = 0; i < kBlock; ++i) sum += row[i];
    }
    return sum;
  };
  for (int y = 0; y + 2 * kBlock <= luma.height; y += kStep) {
    const std::uint8_t* vrow = v.row((y + kBlock) * v.height / luma.height);
    const std::uint8_t* orow = organ.empty() ? nullptr : organ.row((y + kBlock) * organ.height / luma.height);
    for (int x = 0; x + 2 * kBlock <= luma.width; x += kStep) {
      const int cx = x + kBlock;
      if (!vrow[cx * v.width / luma.width] || (orow && !orow[cx * organ.width / luma.width])) continue;
      const int b = block(x, y);
      const int d = std::abs(block(x + kBlock, y) - b) + std::abs(block(x, y + kBlock) - b);
      ++hist[static_cast<std::size_t>(std::min(d, kBins - 1))];
      ++n;
    }
  }
  if (n == 0) return -1.0;
  return static_cast<double>(histogram_rank(hist, (n - 1) / 2)) / (kBlock * kBlock);
}

}  // namespace st
