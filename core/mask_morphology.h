// Binary mask erosion / dilation with a square structuring element: erosion
// by running counts (cost independent of the radius), dilation by nearest
// set pixel per row and an OR of rows (cheaper for the small radii of masks). Pixels outside the image
// never erode nor dilate (OpenCV's default border for erode/dilate).
// No allocation: the caller passes the scratch (configure-time buffers).
#pragma once

#include <cstdint>

#include "core/image.h"

namespace st {

struct MorphScratch {
  ImageView<std::uint8_t> rows;  // same size as the mask: horizontal pass result
  std::int32_t* column_counts;   // mask width entries (erosion only)
  std::int32_t* row_prefix;      // mask width + 1 entries (erosion only)
};

// k < 0: erode by |k|; k > 0: dilate by k; k == 0: copy. in and out have the
// same size and may not alias; values are 0 or 255 (anything nonzero is set).
void morph_square(ImageView<const std::uint8_t> in, int k, ImageView<std::uint8_t> out,
                  const MorphScratch& scratch);

}  // namespace st
