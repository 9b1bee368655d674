#include "core/feature_grid.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/capacity.h"

namespace st {

Status FeatureGrid::configure(int width, int height, int cell_px) {
  if (width < 1 || height < 1 || width > kMaxImageWidth || height > kMaxImageHeight)
    return make_error("FeatureGrid: image size outside [1, kMaxImageWidth/Height]");
  if (cell_px < 4 || cell_px > 512) return make_error("FeatureGrid: cell_px must be in [4, 512]");
  cell_px_ = cell_px;
  cells_x_ = (width + cell_px - 1) / cell_px;
  cells_y_ = (height + cell_px - 1) / cell_px;
  const std::size_t n = static_cast<std::size_t>(cells_x_) * cells_y_;
  cell_start_.assign(n + 1, 0);
  cell_fill_.assign(n, 0);
  items_.assign(kMaxKeypoints, Item{});
  return Status::Ok();
}

int FeatureGrid::cell_of(float x, float y) const {
  const int cx = std::clamp(static_cast<int>(std::floor(x / static_cast<float>(cell_px_))), 0, cells_x_ - 1);
  const int cy = std::clamp(static_cast<int>(std::floor(y / static_cast<float>(cell_px_))), 0, cells_y_ - 1);
  return cy * cells_x_ + cx;
}

void FeatureGrid::build(const FeatureSet& f) {
  std::fill(cell_start_.begin(), cell_start_.end(), 0);
  const int n = std::min(f.count, kMaxKeypoints);
  for (int i = 0; i < n; ++i) {
    const Keypoint& k = f.keypoints[static_cast<std::size_t>(i)];
    ++cell_start_[static_cast<std::size_t>(cell_of(k.x, k.y)) + 1];
  }
  for (std::size_t c = 1; c < cell_start_.size(); ++c) cell_start_[c] += cell_start_[c - 1];
  std::copy(cell_start_.begin(), cell_start_.end() - 1, cell_fill_.begin());
  for (int i = 0; i < n; ++i) {
    const Keypoint& k = f.keypoints[static_cast<std::size_t>(i)];
    items_[static_cast<std::size_t>(cell_fill_[static_cast<std::size_t>(cell_of(k.x, k.y))]++)] = {k.x, k.y, k.octave, i};
  }
}

int FeatureGrid::query(float x, float y, float radius, int min_octave, int max_octave, int* out,
                       int capacity) const {
  if (!(radius >= 0.f) || !std::isfinite(x) || !std::isfinite(y) || cells_x_ == 0) return 0;
  const float cp = static_cast<float>(cell_px_);
  const int cx0 = std::max(0, static_cast<int>(std::floor((x - radius) / cp)));
  const int cy0 = std::max(0, static_cast<int>(std::floor((y - radius) / cp)));
  const int cx1 = std::min(cells_x_ - 1, static_cast<int>(std::floor((x + radius) / cp)));
  const int cy1 = std::min(cells_y_ - 1, static_cast<int>(std::floor((y + radius) / cp)));
  const float r2 = radius * radius;
  // Octave window as one unsigned compare; any octave: the whole int range.
  const bool any_octave = min_octave < 0 && max_octave < 0;
  const int lo = any_octave ? 0 : min_octave;
  const auto span = any_octave ? ~0u : static_cast<unsigned>(max_octave - min_octave);
  int n = 0;
  // The cells cx0..cx1 of one row are consecutive in the counting sort. The
  // tests are random per keypoint (octaves mix), so the loop is branch-free:
  // every item is written and the count advances only for a hit.
  for (int cy = cy0; cy <= cy1; ++cy) {
    const std::size_t row = static_cast<std::size_t>(cy * cells_x_);
    const int begin = cell_start_[row + static_cast<std::size_t>(cx0)];
    const int end = cell_start_[row + static_cast<std::size_t>(cx1) + 1];
    if (capacity - n < end - begin) {  // may not fit: the checked loop
      for (int j = begin; j < end; ++j) {
        const Item& k = items_[static_cast<std::size_t>(j)];
        const float dx = k.x - x, dy = k.y - y;
        if (static_cast<unsigned>(k.octave - lo) > span || dx * dx + dy * dy > r2) continue;
        if (n >= capacity) return n;
        out[n++] = k.index;
      }
      continue;
    }
    for (int j = begin; j < end; ++j) {
      const Item& k = items_[static_cast<std::size_t>(j)];
      const float dx = k.x - x, dy = k.y - y;
      const bool hit = (static_cast<unsigned>(k.octave - lo) <= span) & (dx * dx + dy * dy <= r2);
      out[n] = k.index;
      n += hit ? 1 : 0;
    }
  }
  return n;
}

}  // namespace st
