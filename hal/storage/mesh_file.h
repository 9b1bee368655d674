// Prior-shape files: read + parse (PLY or STL, sniffed) + validate + orient.
#pragma once

#include <cstdint>
#include <filesystem>

#include "core/mesh/mesh.h"
#include "core/formats/mesh_io.h"
#include "core/base/result.h"

namespace st {

// Loads a mesh file, validates it and fixes inward winding; `report` (may
// be null) says what was found and done. Errors name the file.
Result<Mesh> load_mesh_file(const std::filesystem::path& path, MeshReport* report);
// Binary little-endian PLY, optionally with per-face colours (3 bytes each).
Status save_mesh_ply(const std::filesystem::path& path, const Mesh& mesh,
                     const std::uint8_t* face_rgb = nullptr);

}  // namespace st
