// Binary mask erosion / dilation with a square structuring element: small
// radii by the AND / OR of shifted rows and of rows (vectorised loops),
// larger ones by running counts (erosion) or the nearest set pixel per row
// (dilation). Pixels outside the image never erode nor dilate (OpenCV's
// default border for erode/dilate).
// No allocation: the caller passes the scratch (configure-time buffers,
// MorphBuffers).
#pragma once

#include <cstdint>
#include <vector>

#include "core/image/image.h"

namespace st {

struct MorphScratch {
  ImageView<std::uint8_t> rows;  // same size as the mask: horizontal pass result
  std::int32_t* column_counts;   // mask width entries (erosion only)
  std::int32_t* row_prefix;      // mask width + 1 entries (erosion only)
};

// The scratch of morph_square for masks up to a size, allocated once at
// configure time; scratch() hands out views of it for a mask of any size
// within that (no allocation).
class MorphBuffers {
 public:
  void configure(int max_width, int max_height);
  // Views for a width x height mask; both within the configured size (a
  // larger request gets an empty view of rows and null counts: a caller bug).
  MorphScratch scratch(int width, int height);

 private:
  int max_width_ = 0, max_height_ = 0;
  std::vector<std::uint8_t> rows_;
  std::vector<std::int32_t> counts_, prefix_;
};

// k < 0: erode by |k|; k > 0: dilate by k; k == 0: copy. in and out have the
// same size and may not alias; values are 0 or 255 (anything nonzero is set).
// Mismatched sizes or a scratch smaller than the mask leave out untouched.
void morph_square(ImageView<const std::uint8_t> in, int k, ImageView<std::uint8_t> out,
                  const MorphScratch& scratch);

}  // namespace st
