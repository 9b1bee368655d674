// Fuzzes the STL parser (binary and ascii) and the mesh validation behind it.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "core/formats/mesh_io.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view bytes(reinterpret_cast<const char*>(data), size);
  st::Result<st::Mesh> m = st::parse_stl(bytes);
  if (m) {
    st::MeshReport report;
    (void)st::validate_and_orient(m.value(), &report);
  }
  (void)st::parse_mesh(bytes);  // the sniffing path
  return 0;
}
