// ImagePyramid: N levels, each 1/scale_factor the size of the one above
// (bilinear, chained from the previous level like cv::ORB), plus a smoothed
// copy (7-tap Gaussian, sigma ~2) that rBRIEF samples, of one level at a
// time: the extractor describes a level's keypoints before it smooths the
// next, so one level-0-sized buffer serves every level (1280x720: 0.9 MB
// instead of 4.2 for a copy per level, each at the level-0 stride).
//
// configure() allocates every level once; nothing else allocates.
// Level 0 is copied so that the pyramid owns every pixel it hands out (the
// caller's frame buffer may be re-queued to the camera right after).
// Single-threaded: one instance per thread.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/base/capacity.h"
#include "core/image/image.h"
#include "core/base/result.h"

namespace st {

class ImagePyramid {
 public:
  // levels in [1, kMaxPyramidLevels], scale_factor in (1, 2].
  Status configure(int width, int height, int levels, float scale_factor);
  // The levels (image must be width x height as configured; false
  // otherwise), without smoothing. Allocates nothing.
  // denoise: level 0 is the image through a 3x3 binomial filter ([1 2 1]
  // across and down, / 16, edges replicated), and every level with it.
  bool build_levels(GrayView image, bool denoise = false);
  // Level k's smoothing, into the one smoothing buffer: smoothed(k) is
  // level k's until another level is smoothed. Allocates nothing.
  void smooth_level(int k);
  // Smooths the kSmoothTilePx x kSmoothTilePx tiles of level k whose byte in
  // tiles (tiles_x per row) is non-zero; bit-identical to smooth_level(k)
  // there, and smoothed(k) valid only there. Allocates nothing.
  // 16: ~25% fewer pixels smoothed than 32 (for patches of radius 15).
  static constexpr int kSmoothTilePx = 16;
  void smooth_tiles(int k, const std::uint8_t* tiles, int tiles_x);

  int levels() const { return levels_; }
  float scale(int level) const { return scale_[level]; }  // level-k pixel * scale = level-0 pixel
  GrayView level(int k) const { return levels_img_[k].cview(); }
  // Smoothed levels share one row stride (the level-0 width), so rBRIEF
  // steps through all of them with one table of pixel offsets.
  GrayView smoothed(int k) const {
    return GrayView(smooth_.data(), levels_img_[k].width(), levels_img_[k].height(), width_);
  }
  int width() const { return width_; }
  int height() const { return height_; }

 private:
  struct ResizeTables {  // bilinear source index and 8-bit weight per output column/row
    std::vector<std::int32_t> x0, y0;
    std::vector<std::uint8_t> wx, wy;  // weight of the second sample, 0..128
    std::vector<std::int16_t> wpair;   // per output column: (128 - wx, wx)
  };
  void resize_level(int k);
  ImageView<std::uint8_t> smooth_view(int k) {
    return ImageView<std::uint8_t>(smooth_.data(), levels_img_[k].width(), levels_img_[k].height(), width_);
  }
  static void horizontal_blend(const std::uint16_t* tmp, const ResizeTables& t, std::uint8_t* out,
                               int width);
  std::array<Image<std::uint8_t>, kMaxPyramidLevels> levels_img_;
  Image<std::uint8_t> smooth_;  // the level smoothed last (level-0 size)
  std::array<ResizeTables, kMaxPyramidLevels> tables_;
  std::array<float, kMaxPyramidLevels> scale_{};
  std::vector<std::uint16_t> row_tmp_;  // one vertically blended row (resize)
  std::vector<std::uint8_t> blur_tmp_;  // one vertically blurred row + padding (smoothing)
  std::vector<std::uint16_t> denoise_row_;  // one row's [1 2 1] vertical sums, an edge column each side
  void denoise_level0(GrayView image);
  int levels_ = 0;
  int width_ = 0;
  int height_ = 0;
};

// 7-tap separable Gaussian (sigma ~2, integer weights summing to 256) of src
// into dst (same size); borders replicate. tmp must hold width + 6 bytes.
// Allocation-free; SIMD through OpenCV universal intrinsics where available.
void gaussian_blur7(GrayView src, ImageView<std::uint8_t> dst, std::uint8_t* tmp);

}  // namespace st
