// RGB -> Y'CbCr 4:2:0, BT.601 full range (JPEG), the colour space of the
// Y4M tag C420jpeg. Chroma is the mean of each 2x2 block (JPEG siting).
// Allocation-free: the caller owns the planes.
#pragma once

#include <cstdint>

#include <opencv2/core.hpp>

#include "core/image/image.h"

namespace st::sim {

// rgb: CV_8UC3 in R, G, B order. y: width x height; u, v: (w+1)/2 x (h+1)/2.
void rgb_to_yuv420_jpeg(const cv::Mat& rgb, ImageView<std::uint8_t> y, ImageView<std::uint8_t> u,
                        ImageView<std::uint8_t> v);

}  // namespace st::sim
