// A small, valid sequence folder written with the project's own writers:
// 64x48 video of a few frames, a 40 mm cube 150 mm in front of the camera,
// ground truth and markers. Tests then break one thing at a time.
#pragma once

#include <filesystem>

#include "core/mesh/mesh.h"
#include "core/formats/sequence.h"

namespace st::test {

struct TinySequence {
  std::filesystem::path dir;
  SequenceConfig config;
  Mesh mesh;
};

// A closed cube of side s mm with outward winding, centred at the origin.
Mesh centred_cube(float side_mm);
// Writes the sequence into dir (created); frames = number of video frames.
TinySequence write_tiny_sequence(const std::filesystem::path& dir, int frames = 3);

}  // namespace st::test
