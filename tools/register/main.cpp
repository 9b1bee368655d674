// scopetrack-register SEQ PAIRS [--inlier-px PX] [--write]: the first
// frame's registration (T_camera_model_init) from a few picked 2D-3D pairs
// (registration.h). Prints every pair's residual and its distance to the
// mesh, the pose, and how far it is from the sequence's current one;
// --write stores it in SEQ/sequence.yaml (the old file kept as
// sequence.yaml.bak). Exit: 0 done, 1 bad input or no pose, 2 bad command line.
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>

#include "core/mesh/closest_point.h"
#include "core/formats/sequence.h"
#include "core/formats/text_scan.h"
#include "hal/storage/file_io.h"
#include "hal/storage/mesh_file.h"
#include "registration.h"

namespace {

constexpr std::int64_t kMaxTextBytes = 1 << 20;
constexpr double kOffMeshMm = 5.0;  // a picked model point this far from the surface is flagged

int usage() {
  std::fprintf(stderr,
               "usage: scopetrack-register SEQUENCE_DIR PAIRS_FILE [--inlier-px PX (8)] [--write]\n"
               "  PAIRS_FILE: one pair per line, 'u v x y z': a pixel of frame 0 (as in the video),\n"
               "  then the same point on the mesh in model mm; '#' comments. At least 4 pairs.\n");
  return 2;
}

void print_matrix(const st::SE3& T) {
  const st::Mat3& R = T.rotation();
  const st::Vec3& t = T.translation();
  std::printf("T_camera_model_init:\n");
  for (int r = 0; r < 3; ++r)
    std::printf("  [ % .9f % .9f % .9f % 12.6f ]\n", R(r, 0), R(r, 1), R(r, 2), t(r));
  std::printf("  [ % .9f % .9f % .9f % 12.6f ]\n", 0.0, 0.0, 0.0, 1.0);
}

}  // namespace

int main(int argc, char** argv) {
  std::string seq_dir, pairs_path;
  st::RegistrationOptions options;
  bool write = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--help" || a == "-h") return usage(), 0;
    if (a == "--write") {
      write = true;
    } else if (a == "--inlier-px" && i + 1 < argc) {
      if (!st::parse_double_in(argv[++i], 0.1, 1000.0, &options.inlier_px)) {
        std::fprintf(stderr, "scopetrack-register: --inlier-px wants pixels in 0.1..1000\n");
        return 2;
      }
    } else if (!a.empty() && a[0] == '-') {
      std::fprintf(stderr, "scopetrack-register: unknown or incomplete argument '%s'\n", a.c_str());
      return usage();
    } else if (seq_dir.empty()) {
      seq_dir = a;
    } else if (pairs_path.empty()) {
      pairs_path = a;
    } else {
      std::fprintf(stderr, "scopetrack-register: unexpected argument '%s'\n", a.c_str());
      return usage();
    }
  }
  if (seq_dir.empty() || pairs_path.empty()) return usage();
  const std::filesystem::path yaml_path = std::filesystem::path(seq_dir) / "sequence.yaml";
  auto yaml = st::read_file(yaml_path, kMaxTextBytes);
  if (!yaml) return std::fprintf(stderr, "scopetrack-register: %s\n", yaml.message().c_str()), 1;
  auto cfg = st::parse_sequence_yaml(yaml.value());
  if (!cfg) return std::fprintf(stderr, "scopetrack-register: %s: %s\n", yaml_path.c_str(), cfg.message().c_str()), 1;
  auto text = st::read_file(pairs_path, kMaxTextBytes);
  if (!text) return std::fprintf(stderr, "scopetrack-register: %s\n", text.message().c_str()), 1;
  auto pairs = st::parse_registration_pairs(text.value());
  if (!pairs) return std::fprintf(stderr, "scopetrack-register: %s: %s\n", pairs_path.c_str(), pairs.message().c_str()), 1;
  auto mesh = st::load_mesh_file(std::filesystem::path(seq_dir) / cfg->mesh, nullptr);
  if (!mesh) return std::fprintf(stderr, "scopetrack-register: %s\n", mesh.message().c_str()), 1;
  st::ClosestPointIndex surface;
  if (st::Status s = surface.configure(mesh.value()); !s.ok())
    return std::fprintf(stderr, "scopetrack-register: mesh: %s\n", s.message().c_str()), 1;

  const st::CameraModel camera(cfg->K, cfg->distortion);
  auto result = st::register_first_frame(pairs.value(), camera, options);
  if (!result) return std::fprintf(stderr, "scopetrack-register: %s\n", result.message().c_str()), 1;
  const st::RegistrationResult& r = result.value();

  std::printf("%-6s %-21s %-32s %10s %10s\n", "line", "pixel", "model point (mm)", "resid px", "mesh mm");
  int off_mesh = 0;
  for (std::size_t i = 0; i < pairs->size(); ++i) {
    const st::RegistrationPair& p = pairs.value()[i];
    st::SurfacePoint sp;
    const double d = surface.closest(p.p_model, &sp) ? sp.distance_mm : -1.0;
    const bool far = d > kOffMeshMm;
    off_mesh += far ? 1 : 0;
    std::printf("%-6d (%8.2f, %8.2f)  (%9.3f, %9.3f, %9.3f) %10.2f %10.2f%s%s\n", p.line, p.px.x(), p.px.y(),
                p.p_model.x(), p.p_model.y(), p.p_model.z(), r.residual_px[i], d, r.inlier[i] ? "" : "  OUTLIER",
                far ? "  OFF THE MESH" : "");
  }
  std::printf("pairs %zu, inliers %d (within %.1f px), inlier RMS %.2f px; %lld triples, %lld P3P poses scored, "
              "LM %s\n",
              pairs->size(), r.inliers, options.inlier_px, r.rms_px, r.triples, r.hypotheses,
              r.refined ? "refined" : "not kept");
  if (off_mesh > 0)
    std::printf("warning: %d picked model point(s) more than %.0f mm from the mesh surface\n", off_mesh, kOffMeshMm);
  // Between the camera poses in the model frame: the distance is the camera centre's move.
  const st::PoseDelta change = st::pose_delta(cfg->T_camera_model_init.inverse(), r.T_camera_model.inverse());
  std::printf("change from the sequence's T_camera_model_init: %.3f deg, camera centre %.3f mm\n",
              change.angle_deg, change.distance_mm);
  print_matrix(r.T_camera_model);
  if (!write) return 0;
  const std::filesystem::path backup = yaml_path.string() + ".bak";
  if (st::Status s = st::write_file(backup, yaml.value()); !s.ok())
    return std::fprintf(stderr, "scopetrack-register: %s\n", s.message().c_str()), 1;
  st::SequenceConfig updated = cfg.value();
  updated.T_camera_model_init = r.T_camera_model;
  if (st::Status s = st::write_file(yaml_path, st::format_sequence_yaml(updated)); !s.ok())
    return std::fprintf(stderr, "scopetrack-register: %s\n", s.message().c_str()), 1;
  std::printf("written to %s (the old file: %s)\n", yaml_path.c_str(), backup.c_str());
  return 0;
}
