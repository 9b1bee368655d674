// A 4:2:0 frame of the organ (flat colour with a brightness falloff) on a
// background of another colour, with sensor noise: the textureless organ
// of the contour tests.
#pragma once

#include <cstdint>
#include <vector>

#include "core/geometry/camera.h"
#include "core/geometry/se3.h"
#include "core/image/image.h"
#include "core/mesh/mesh.h"

namespace st::test {

struct Frame {
  int w = 0, h = 0;
  std::vector<std::uint8_t> y, u, v;
  GrayView luma() const { return {y.data(), w, h, w}; }
  ChromaView chroma() const {
    return {GrayView{u.data(), (w + 1) / 2, (h + 1) / 2, (w + 1) / 2},
            GrayView{v.data(), (w + 1) / 2, (h + 1) / 2, (w + 1) / 2}};
  }
};

Frame render_flat(const Mesh& mesh, const Pinhole& K, const SE3& T, std::uint64_t seed);

}  // namespace st::test
