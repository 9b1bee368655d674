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
  double contrast = -1.0;
  measure_places(luma, organ, valid, &contrast, nullptr);
  return contrast;
}

double FastThresholdScaler::organ_noise_ratio(GrayView luma, GrayView organ, GrayView valid) {
  double contrast = -1.0, fine = -1.0;
  measure_places(luma, organ, valid, &contrast, &fine);
  if (contrast < 0 || fine < 0) return -1.0;
  if (contrast > 0) return fine / contrast;
  return fine > 0 ? 1e3 : 0.0;
}

// The medians of organ_contrast() and (fine) of the pixel-level
// differences at the same places, luma units; -1 where no place qualifies.
void FastThresholdScaler::measure_places(GrayView luma, GrayView organ, GrayView valid, double* contrast,
                                         double* fine) {
  constexpr int kStep = 16, kBlock = 4;
  constexpr int kBins = 1024;  // in 1/16 luma units (block sums of 16 pixels)
  std::array<int, kBins> hist{}, hist_fine{};
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
  // Sum over the block at (x, y) of each pixel's differences to its right
  // and lower neighbours (inside the 8x8 area organ_contrast reads).
  const auto pixel_differences = [&](int x, int y) {
    int sum = 0;
    for (int j = 0; j < kBlock; ++j) {
      const std::uint8_t* row = luma.row(y + j) + x;
      const std::uint8_t* below = luma.row(y + j + 1) + x;
      for (int i = 0; i < kBlock; ++i) sum += std::abs(row[i + 1] - row[i]) + std::abs(below[i] - row[i]);
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
      if (fine) ++hist_fine[static_cast<std::size_t>(std::min(pixel_differences(x, y), kBins - 1))];
      ++n;
    }
  }
  if (n == 0) return;
  *contrast = static_cast<double>(histogram_rank(hist, (n - 1) / 2)) / (kBlock * kBlock);
  if (fine) *fine = static_cast<double>(histogram_rank(hist_fine, (n - 1) / 2)) / (kBlock * kBlock);
}

}  // namespace st
