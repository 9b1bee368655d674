// Procedural 3D noise for tissue textures, defined in a model frame (mm) so
// the texture sticks to the surface as the camera moves.
// Gradient (Perlin-style) noise on an integer lattice hashed by a seeded
// permutation; fbm sums octaves. Evaluation allocates nothing and is
// thread-compatible (const after construction).
#pragma once

#include <array>
#include <cstdint>

namespace st::sim {

class Noise3 {
 public:
  explicit Noise3(std::uint64_t seed);

  // Gradient noise, roughly in [-1, 1], zero at lattice points, smooth (C2).
  float gradient(float x, float y, float z) const;
  // Value noise in [0, 1]: cheaper, blobby; for speckle.
  float value(float x, float y, float z) const;
  // Fractal sum of gradient noise: octaves at frequency * 2.03^i with
  // amplitude gain^i, normalised to roughly [-1, 1].
  float fbm(float x, float y, float z, int octaves, float gain = 0.5f) const;
  // Thin dark lines where the noise crosses zero: 1 on a line, 0 away from
  // it; width is the half-width in noise units (vessel-like network).
  float ridge(float x, float y, float z, float width) const;
  // Cellular (Worley) noise: distance to the nearest of one jittered
  // feature point per unit cell, and that cell's random value in [0, 1]
  // (liver lobules: a dark central vein at every feature point).
  struct Cell {
    float distance = 0, value = 0;
  };
  Cell cellular(float x, float y, float z) const;

 private:
  int hash(int x, int y, int z) const {
    return perm_[(perm_[(perm_[x & 255] + y) & 255] + z) & 255];
  }
  std::array<std::uint8_t, 256> perm_{};
  std::array<float, 256> values_{};
};

}  // namespace st::sim
