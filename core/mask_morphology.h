// Binary mask erosion / dilation with a square structuring element: small
// radii by the AND / OR of shifted rows and of rows (vectorised loops),
// larger ones by running counts (erosion) or the nearest set pixel per row
// (dilation). Pixels outside the image never erode nor dilate (OpenCV's
// default border for erode/dilate).
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
