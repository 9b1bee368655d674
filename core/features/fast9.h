// FAST-9 (segment test, 9 contiguous pixels of the 16 on a Bresenham circle
// of radius 3) with score and 3x3 non-maximum suppression, row by row.
//
// Score: the largest t for which the pixel is still a corner, plus one, i.e.
// max over 9-arcs of min |I(circle) - I(centre)| along the arc with one sign.
// A pixel is a corner at threshold t iff score > t, so one detection at the
// relaxed threshold also answers "is it a corner at the strict threshold".
//
// configure() allocates the rolling row buffers; detect() allocates nothing.
// SIMD (16 pixels at a time) through OpenCV universal intrinsics, with a
// scalar path that builds everywhere. Single-threaded: one instance per thread.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image/image.h"
#include "core/base/result.h"

namespace st {

struct FastCorner {
  std::uint16_t x = 0;  // level pixel coordinates
  std::uint16_t y = 0;
  std::uint8_t score = 0;
};

class Fast9Detector {
 public:
  Status configure(int max_width);

  // Corners with score > threshold in [border, w - border) x [border, h - border),
  // after 3x3 non-maximum suppression, appended to out[0..capacity) in raster
  // order; returns the count (stops at capacity). allowed (may be null) holds
  // one byte per 16-pixel column chunk (x >> 4) per row, allowed_stride bytes
  // apart: chunks with 0 are skipped (rows are read up to allowed_stride
  // bytes, eight at a time).
  int detect(GrayView image, int threshold, int border, const std::uint8_t* allowed,
             int allowed_stride, FastCorner* out, int capacity);

 private:
  void score_row(GrayView image, int y, int threshold, int x_begin, int x_end,
                 const std::uint8_t* allowed, int allowed_chunks, std::uint8_t* scores,
                 std::uint16_t* xs, int* n);
  std::vector<std::uint8_t> score_rows_;   // 3 rolling rows of scores (0: no corner)
  std::vector<std::uint16_t> corner_xs_;   // 3 rolling lists of corner columns
  int max_width_ = 0;
};

// Scalar FAST-9 score of one pixel (0 if no arc passes threshold 0); the
// pixel must be at least 3 pixels inside the image. Exposed for tests.
int fast9_score(GrayView image, int x, int y);

}  // namespace st
