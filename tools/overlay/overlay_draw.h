// Drawing for the overlay video: a full-resolution colour + alpha layer
// (drawn with OpenCV primitives or per pixel from organ labels) blended
// into 4:2:0 planes, so the source video stays untouched where nothing is
// drawn. Colours are converted with full-range BT.601 (the Y4M C420jpeg
// convention of our simulator). Host tool code.
#pragma once

#include <cstdint>

#include <opencv2/core.hpp>

#include "core/image/image.h"

namespace st::overlay {

struct Rgb {
  std::uint8_t r = 0, g = 0, b = 0;
};

struct Yuv {
  double y = 0, u = 128, v = 128;
};
Yuv to_yuv(Rgb c);  // full-range BT.601

class OverlayLayer {
 public:
  void reset(int width, int height);  // also clears
  void clear();
  // BGRA, 8 bits: OpenCV drawing calls go here (alpha 255 = opaque).
  cv::Mat& bgra() { return bgra_; }
  void set(int x, int y, Rgb c, double alpha);
  static cv::Scalar scalar(Rgb c, double alpha = 1.0);
  // Blends the layer into the planes (u, v at half resolution, rounded up).
  void composite(ImageView<std::uint8_t> y, ImageView<std::uint8_t> u, ImageView<std::uint8_t> v) const;

 private:
  cv::Mat bgra_;
};

// Organ labels per output pixel: the visible triangle's id, -1 where no organ.
// Silhouette: pixels within half_width (>= 1) of the other side of an
// organ/background boundary, on both sides (a line 2 * half_width pixels
// wide centred on the true edge). The image border is not an edge.
// Wireframe: pixels where two visible triangles meet.
void draw_silhouette(ImageView<const std::int32_t> labels, Rgb colour, int half_width, OverlayLayer* layer);
void draw_wireframe(ImageView<const std::int32_t> labels, Rgb colour, double alpha, OverlayLayer* layer);

}  // namespace st::overlay
