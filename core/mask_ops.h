// Binary mask helpers shared by the ORB frontend and the valid-mask builder.
// All allocation-free: callers own every buffer.
#pragma once

#include <cstdint>

#include "core/image.h"

namespace st {

// Dilation of src (non-zero = set) by a (2r+1) x (2r+1) square into dst
// (255 / 0, src size, stride = width). tmp holds width * height bytes.
// radius <= 0 copies (as 255 / 0).
void dilate_binary(GrayView src, int radius, std::uint8_t* dst, std::uint8_t* tmp);

}  // namespace st
