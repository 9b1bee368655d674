#include "hal/storage/mesh_file.h"

#include "core/base/capacity.h"
#include "hal/storage/file_io.h"

namespace st {

Result<Mesh> load_mesh_file(const std::filesystem::path& path, MeshReport* report) {
  Result<std::string> bytes = read_file(path, kMaxMeshFileBytes);
  if (!bytes) return bytes.error();
  Result<Mesh> mesh = parse_mesh(bytes.value());
  if (!mesh) return make_error(path.string() + ": " + mesh.message());
  if (Status s = validate_and_orient(mesh.value(), report); !s)
    return make_error(path.string() + ": " + s.message());
  return mesh;
}

Status save_mesh_ply(const std::filesystem::path& path, const Mesh& mesh,
                     const std::uint8_t* face_rgb) {
  return write_file(path, format_ply_binary(mesh, face_rgb));
}

}  // namespace st
