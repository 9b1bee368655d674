#include "hal/storage/sequence_loader.h"

#include <cstdio>

#include "core/base/capacity.h"
#include "hal/storage/file_io.h"
#include "hal/storage/mesh_file.h"

namespace st {

namespace {
constexpr std::int64_t kMaxYamlBytes = 1 << 20;
constexpr std::int64_t kMaxTextFileBytes = std::int64_t{1} << 30;

Result<std::filesystem::path> referenced_file(const std::filesystem::path& dir,
                                              const std::string& name, const char* key) {
  const std::filesystem::path p = dir / name;
  std::error_code ec;
  if (!std::filesystem::exists(p, ec))
    return make_error(std::string("sequence.yaml: ") + key + " '" + name + "' does not exist (" +
                      p.string() + ")");
  return p;
}

Status load_optional(const LoadedSequence& s, LoadedSequence* out) {
  const SequenceConfig& c = s.config;
  if (!c.groundtruth.empty()) {
    auto path = referenced_file(s.dir, c.groundtruth, "groundtruth");
    if (!path) return Error{path.message()};
    auto text = read_file(path.value(), kMaxTextFileBytes);
    if (!text) return Error{text.message()};
    auto poses = parse_tum(text.value());
    if (!poses) return make_error(path->string() + ": " + poses.message());
    out->groundtruth = std::move(poses.value());
  }
  if (!c.markers.empty()) {
    auto path = referenced_file(s.dir, c.markers, "markers");
    if (!path) return Error{path.message()};
    auto text = read_file(path.value(), kMaxYamlBytes);
    if (!text) return Error{text.message()};
    auto markers = parse_markers(text.value());
    if (!markers) return make_error(path->string() + ": " + markers.message());
    out->markers = std::move(markers.value());
  }
  return Status::Ok();
}

Status load_video_header(LoadedSequence* s) {
  auto path = referenced_file(s->dir, s->config.video, "video");
  if (!path) return Error{path.message()};
  s->video_path = path.value();
  std::error_code ec;
  s->video_is_pipe = std::filesystem::is_fifo(s->video_path, ec);
  if (s->video_is_pipe) return Status::Ok();  // checked when the stream is opened
  auto h = read_y4m_file_header(s->video_path);
  if (!h) return Error{h.message()};
  s->video_header = h.value();
  if (h->width != s->config.width || h->height != s->config.height)
    return make_error("video " + s->video_path.string() + " is " + std::to_string(h->width) + "x" +
                      std::to_string(h->height) + " but sequence.yaml calibrates " +
                      std::to_string(s->config.width) + "x" + std::to_string(s->config.height));
  return Status::Ok();
}

}  // namespace

Result<Y4mHeader> read_y4m_file_header(const std::filesystem::path& path) {
  std::FILE* f = std::fopen(path.c_str(), "rb");
  if (!f) return make_error("cannot open video " + path.string());
  std::string head(kMaxY4mLineBytes, '\0');
  head.resize(std::fread(head.data(), 1, head.size(), f));
  std::fclose(f);
  auto h = parse_y4m_header(head);
  if (!h) return make_error(path.string() + ": " + h.message());
  return h;
}

Result<LoadedSequence> load_sequence(const std::filesystem::path& dir) {
  LoadedSequence s;
  s.dir = dir;
  auto yaml = read_file(dir / "sequence.yaml", kMaxYamlBytes);
  if (!yaml) return yaml.error();
  auto config = parse_sequence_yaml(yaml.value());
  if (!config) return make_error((dir / "sequence.yaml").string() + ": " + config.message());
  s.config = std::move(config.value());
  auto mesh_path = referenced_file(dir, s.config.mesh, "mesh");
  if (!mesh_path) return mesh_path.error();
  s.mesh_path = mesh_path.value();
  auto mesh = load_mesh_file(s.mesh_path, &s.mesh_report);
  if (!mesh) return mesh.error();
  s.mesh = std::move(mesh.value());
  if (Status st = load_video_header(&s); !st) return Error{st.message()};
  if (Status st = load_optional(s, &s); !st) return Error{st.message()};
  return s;
}

Status write_sequence_files(const std::filesystem::path& dir, const SequenceConfig& config,
                            const std::vector<TimedPose>* groundtruth,
                            const std::vector<Marker>* markers) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) return make_error("cannot create " + dir.string() + ": " + ec.message());
  if (Status s = write_file(dir / "sequence.yaml", format_sequence_yaml(config)); !s) return s;
  if (groundtruth && !config.groundtruth.empty())
    if (Status s = write_file(dir / config.groundtruth, format_tum(*groundtruth)); !s) return s;
  if (markers && !config.markers.empty())
    if (Status s = write_file(dir / config.markers, format_markers(*markers)); !s) return s;
  return Status::Ok();
}

}  // namespace st
