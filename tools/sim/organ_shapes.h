// Procedural organs other than the liver, for testing that the tracker is
// not tuned to one shape: a kidney (small, bean-shaped, seen from close
// up) and a stomach (a long, bent, flattened sack). Closed surfaces of
// 20,480 triangles in mm, outward counter-clockwise faces, centred on their
// bounding box. Each is a subdivided icosphere mapped by a smooth function
// of the direction that turns no face over (tests/test_sim_mesh.cpp).
//
// Sizes are adult anatomy's order of magnitude (kidney about 110 x 60 x 50
// mm, stomach about 180 x 110 x 70 mm); the seed varies the proportions by
// up to +-8 % and the low-frequency surface irregularity.
#pragma once

#include <cstdint>
#include <string_view>

#include "core/mesh/mesh.h"
#include "core/base/result.h"

namespace st::sim {

enum class OrganKind { Liver, Kidney, Stomach };

// "liver", "kidney" or "stomach"; an error naming the choices otherwise.
Result<OrganKind> parse_organ(std::string_view name);
const char* organ_name(OrganKind kind);

// The organ's mesh for a seed (the liver: make_liver_mesh with that seed).
Mesh make_organ_mesh(OrganKind kind, std::uint64_t seed);

}  // namespace st::sim
