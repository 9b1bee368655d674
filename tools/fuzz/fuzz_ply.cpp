// Fuzzes the PLY parser and the mesh validation behind it.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/formats/mesh_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  st::Result<st::Mesh> m = st::parse_ply(std::string_view(reinterpret_cast<const char*>(data), size));
  if (!m) return 0;
  st::MeshReport report;
  if (st::validate_and_orient(m.value(), &report).ok()) {
    // What validation accepted must survive a write/parse round trip.
    st::Result<st::Mesh> again = st::parse_ply(st::format_ply_binary(m.value()));
    if (!again || again->tri != m->tri) __builtin_trap();
  }
  return 0;
}
