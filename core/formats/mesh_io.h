// Prior-shape meshes as bytes: PLY (ascii, binary little/big endian) and
// STL (binary, ascii) parsers, validation + winding fix, and a binary PLY
// writer. Counts are capped (core/base/capacity.h) and checked against the bytes
// actually present before anything is allocated, so a 100-byte file cannot
// ask for gigabytes. These run at load time, never on the tracking thread.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>

#include "core/mesh/mesh.h"
#include "core/base/result.h"
#include "core/geometry/se3.h"

namespace st {

// PLY: vertex x y z of any scalar type; faces as a list property named
// vertex_indices or vertex_index with any count/index types; polygons are
// fan-triangulated; other elements and properties are skipped.
Result<Mesh> parse_ply(std::string_view bytes);
// STL: binary (80-byte header + count + 50 bytes per facet) or ascii
// (solid/facet/vertex). Identical vertices are merged so the result is indexed.
Result<Mesh> parse_stl(std::string_view bytes);
// True when the size matches a binary STL's declared facet count exactly.
bool looks_like_binary_stl(std::string_view bytes);
// Sniffs the format ("ply" magic, binary STL size rule, "solid") and parses.
Result<Mesh> parse_mesh(std::string_view bytes);

struct MeshReport {
  bool flipped = false;             // faces were wound inward and have been flipped
  int reoriented = 0;               // faces wound against their neighbours, turned to agree
  double signed_volume_mm3 = 0.0;   // after any flip (>= 0 for a closed, outward mesh)
  Vec3 min = Vec3::Zero(), max = Vec3::Zero();  // bounding box, mm
  int triangles = 0, vertices = 0;
  std::string summary;              // one line for a user
};

// Checks a mesh (non-empty, indices in range, coordinates finite, counts
// within caps) and makes its winding consistent and outward: faces wound
// against their neighbours (across edges two faces share) are turned to
// agree with the majority of their connected part; then, if the signed
// volume is negative (segmentations are often wound inward), every
// triangle is flipped. The report says what was changed. `report` may be
// null.
Status validate_and_orient(Mesh& mesh, MeshReport* report);

// Binary little-endian PLY: float x y z; faces as uchar count + int indices;
// with face_rgb (3 bytes per triangle) also uchar red green blue per face.
std::string format_ply_binary(const Mesh& mesh, const std::uint8_t* face_rgb = nullptr);

}  // namespace st
