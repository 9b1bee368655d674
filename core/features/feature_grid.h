// FeatureGrid: a per-frame grid index over a FeatureSet's keypoints, for
// "which keypoints lie within r pixels of (x, y)" in search by projection.
// Cells are cell_px x cell_px level-0 pixels; the index is a counting sort
// (cell starts + keypoint indices), so build() is O(keypoints + cells).
//
// configure() allocates (cells and kMaxKeypoints indices); build() and
// query() allocate nothing. Tracking thread.
#pragma once

#include <cstdint>
#include <vector>

#include "core/base/cpu_features.h"
#include "core/features/feature_set.h"
#include "core/base/result.h"

namespace st {

class FeatureGrid {
 public:
  Status configure(int width, int height, int cell_px = 16);
  // Indexes features (its keypoints must refer to the configured size;
  // keypoints outside the image are clamped into the border cells).
  void build(const FeatureSet& features);
  // Writes the indices of the last build()'s keypoints with |p - (x, y)| <=
  // radius and octave in [min_octave, max_octave] (pass -1, -1 for any) to
  // out (at most capacity); returns how many were written.
  int query(float x, float y, float radius, int min_octave, int max_octave, int* out,
            int capacity) const;
  // With on (the default after configure() where the CPU has AVX-512F),
  // query() tests 16 keypoints a step; off forces the portable loop. Same
  // results either way (tests compare them).
  void use_avx512(bool on) { use_avx512_ = on && cpu_has_avx512f(); }
  bool uses_avx512() const { return use_avx512_; }

  int cell_px() const { return cell_px_; }
  int cells_x() const { return cells_x_; }
  int cells_y() const { return cells_y_; }

 private:
  int cell_of(float x, float y) const;
  std::vector<std::int32_t> cell_start_;  // cells + 1 entries
  std::vector<std::int32_t> cell_fill_;   // scratch while building
  // Each keypoint's position, octave and index, stored by cell so that a
  // query reads one contiguous run per grid row instead of chasing indices
  // into the FeatureSet (search by projection runs ~10^4 queries per
  // frame); one array per field, so that a SIMD step loads 16 of each.
  // kMaxKeypoints entries each.
  std::vector<float> item_x_, item_y_;
  std::vector<std::int32_t> item_octave_, item_index_;
  int cell_px_ = 16, cells_x_ = 0, cells_y_ = 0;
  bool use_avx512_ = false;
};

}  // namespace st
