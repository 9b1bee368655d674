#include "core/mask_ops.h"

#include <algorithm>

namespace st {

void dilate_binary(GrayView src, int radius, std::uint8_t* dst, std::uint8_t* tmp) {
  const int w = src.width, h = src.height;
  const int r = std::max(radius, 0);
  // Horizontal: distance to the last set pixel on the left, then on the right.
  for (int y = 0; y < h; ++y) {
    const std::uint8_t* s = src.row(y);
    std::uint8_t* t = tmp + static_cast<std::ptrdiff_t>(y) * w;
    int last = -r - 1;
    for (int x = 0; x < w; ++x) {
      if (s[x]) last = x;
      t[x] = (x - last <= r) ? 255 : 0;
    }
    int next = w + r + 1;
    for (int x = w - 1; x >= 0; --x) {
      if (s[x]) next = x;
      if (next - x <= r) t[x] = 255;
    }
  }
  // Vertical: OR of the 2r+1 rows around (rows are contiguous: vectorises).
  for (int y = 0; y < h; ++y) {
    std::uint8_t* d = dst + static_cast<std::ptrdiff_t>(y) * w;
    const int y0 = std::max(0, y - r), y1 = std::min(h - 1, y + r);
    std::copy(tmp + static_cast<std::ptrdiff_t>(y0) * w, tmp + static_cast<std::ptrdiff_t>(y0 + 1) * w, d);
    for (int yy = y0 + 1; yy <= y1; ++yy) {
      const std::uint8_t* t = tmp + static_cast<std::ptrdiff_t>(yy) * w;
      for (int x = 0; x < w; ++x) d[x] |= t[x];
    }
  }
}

}  // namespace st
