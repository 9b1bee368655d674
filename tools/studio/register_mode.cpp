#include "tools/studio/register_mode.h"

#include <cmath>
#include <cstdio>

#include <Eigen/Eigenvalues>

#include "core/formats/sequence.h"
#include "core/formats/text_scan.h"
#include "firmware_app/cli.h"
#include "hal/storage/file_io.h"

namespace st::studio {

namespace {

constexpr std::int64_t kMaxYamlBytes = 1 << 20;
constexpr double kOneSpotMm = 3.0;    // mesh points all within this of their centre: one spot
constexpr double kOneSpotPx = 4.0;    // pixels likewise
constexpr double kLineRatio = 0.04;   // second spread / first spread below this: one line
constexpr double kOffMeshMm = 5.0;    // a picked point this far from the surface is flagged

// Spread of points along their principal axes (square roots of the
// covariance's eigenvalues, largest first), and the largest distance from
// their centre.
template <int D>
void spread(const std::vector<Eigen::Matrix<double, D, 1>>& pts, Eigen::Matrix<double, D, 1>* axes, double* radius) {
  Eigen::Matrix<double, D, 1> c = Eigen::Matrix<double, D, 1>::Zero();
  for (const auto& p : pts) c += p;
  c /= static_cast<double>(pts.size());
  Eigen::Matrix<double, D, D> cov = Eigen::Matrix<double, D, D>::Zero();
  *radius = 0;
  for (const auto& p : pts) {
    cov += (p - c) * (p - c).transpose();
    *radius = std::max(*radius, (p - c).norm());
  }
  cov /= static_cast<double>(pts.size());
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, D, D>> es(cov);
  const auto ev = es.eigenvalues();  // increasing
  for (int i = 0; i < D; ++i) (*axes)(i) = std::sqrt(std::max(0.0, ev(D - 1 - i)));
}

}  // namespace

Result<LoadedSequence> load_checked_sequence(const std::filesystem::path& dir) {
  auto seq = load_sequence(dir);  // its errors name the file
  if (!seq) return seq;
  if (Status s = app::check_sequence_for_replay(seq.value()); !s)
    return make_error(s.message() + " (scopetrack --check " + dir.string() + " says more)");
  return seq;
}

std::string pairs_degeneracy(const std::vector<RegistrationPair>& pairs) {
  const int n = static_cast<int>(pairs.size());
  if (n < kMinRegistrationPairs)
    return "Registration needs at least " + std::to_string(kMinRegistrationPairs) + " pairs; there " +
           (n == 1 ? "is 1" : "are " + std::to_string(n)) +
           ". Click a point on the frame, then the same point on the mesh.";
  std::vector<Vec3> model;
  std::vector<Vec2> px;
  for (const RegistrationPair& p : pairs) {
    model.push_back(p.p_model);
    px.push_back(p.px);
  }
  Vec3 axes3;
  Vec2 axes2;
  double r3 = 0, r2 = 0;
  spread<3>(model, &axes3, &r3);
  spread<2>(px, &axes2, &r2);
  const auto one_spot = [](const char* what, double size, const char* unit) {
    char buf[320];
    std::snprintf(buf, sizeof buf,
                  "The %s points are all on one spot (within %.1f %s of each other): a pose cannot be fixed from "
                  "them. Pick points spread over the organ.",
                  what, size, unit);
    return std::string(buf);
  };
  const auto one_line = [](const char* what) {
    return std::string("The ") + what +
           " points lie on one line: a pose cannot be fixed from them. Add a point off that line.";
  };
  if (r3 < kOneSpotMm) return one_spot("mesh", 2 * r3, "mm");
  if (r2 < kOneSpotPx) return one_spot("frame", 2 * r2, "px");
  if (axes3(1) < kLineRatio * axes3(0)) return one_line("mesh");
  if (axes2(1) < kLineRatio * axes2(0)) return one_line("frame");
  return {};
}

std::string implausible_pose(const SE3& T_camera_model, const Mesh& mesh, const ClosestPointIndex& surface,
                             const std::vector<RegistrationPair>& pairs, const std::vector<bool>& inlier) {
  Vec3 centroid = Vec3::Zero();
  for (int i = 0; i < mesh.vertex_count(); ++i) centroid += mesh.vertex(i);
  centroid /= std::max(1, mesh.vertex_count());
  if ((T_camera_model * centroid).z() <= 0)
    return "The result puts the organ behind the camera: the picks do not describe a view of the organ. "
           "Check that each frame point and its mesh point are the same point.";
  // The surface a laparoscope sees faces it: a pose that sees the picked
  // points from behind the surface puts the camera inside the organ.
  const Vec3 camera_centre = T_camera_model.inverse().translation();
  int facing = 0, away = 0;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (i < inlier.size() && !inlier[i]) continue;
    SurfacePoint sp;
    if (!surface.closest(pairs[i].p_model, &sp) || sp.distance_mm > kOffMeshMm) continue;
    (sp.face_normal.dot(camera_centre - sp.p_model) >= 0 ? facing : away) += 1;
  }
  if (away > facing)
    return "The result sees the picked points from behind the organ's surface: the camera would be inside the "
           "organ. The picks may be mirrored: check that each frame point and its mesh point are the same point.";
  return {};
}

RegisterController::RegisterController(Result<LoadedSequence> sequence, int frame) : frame_(frame) {
  if (!sequence) {
    error_ = sequence.message();
    return;
  }
  seq_ = std::move(sequence.value());
  const SequenceConfig& c = seq_->config;
  camera_ = CameraModel(c.K, c.distortion);
  if (Status s = surface_.configure(seq_->mesh); !s) error_ = "mesh: " + s.message();
  if (Status s = renderer_.configure(*seq_, studio_overlay_style()); !s && error_.empty()) error_ = s.message();
  if (Status s = video_.open(seq_->video_path); !s && error_.empty()) error_ = s.message();
  if (error_.empty()) {
    auto f = video_.frame(frame_);
    if (!f) error_ = f.message();
    else frame_jpeg_ = encode_jpeg(f.value());
  }
  if (!error_.empty()) return;
  mesh_message_ = binary_message(binary_header(BinaryKind::kMesh, 0) + mesh_payload(seq_->mesh));
  check_current_pose();
}

// The tracker's own check of T_camera_model_init (why the sequence needs
// registering), shown to every page that opens; again after a save.
void RegisterController::check_current_pose() {
  const Status check = app::check_sequence_for_replay(*seq_);
  check_message_ = check ? "" : check.message();
}

std::vector<Outgoing> RegisterController::greeting() {
  if (!error_.empty()) return {error_message(error_)};
  std::vector<Outgoing> out = {text_message(info_json(*seq_, "register", video_.count(), frame_,
                                                      ",\"check\":" + json_string(check_message_))),
                               mesh_message_,
                               binary_message(binary_header(BinaryKind::kFrame, static_cast<std::uint32_t>(frame_)) +
                                              frame_jpeg_)};
  for (const Outgoing& m : last_answer_) out.push_back(m);
  return out;
}

void RegisterController::on_open(const PagePtr& page) {
  for (Outgoing& m : greeting()) page->send(std::move(m));
}

void RegisterController::on_text(const PagePtr& page, std::string_view text) {
  for (Outgoing& m : handle(text)) page->send(std::move(m));
}

std::vector<Outgoing> RegisterController::handle(std::string_view command) {
  if (!error_.empty()) return {error_message(error_)};
  const std::size_t eol = command.find('\n');
  const std::string_view first = command.substr(0, eol);
  const std::string_view rest = eol == std::string_view::npos ? std::string_view{} : command.substr(eol + 1);
  if (first.rfind("frame ", 0) == 0) {
    long long index = -1;
    if (!parse_int64_in(first.substr(6), 0, 10'000'000, &index))
      return {error_message("frame: want a frame number, got " + quote_bytes(first.substr(6)))};
    return show_frame(static_cast<int>(index));
  }
  if (first == "register" || first == "save") return run_registration(rest, first == "save");
  return {error_message("unknown command " + quote_bytes(first) +
                        ": the studio takes 'frame N', 'register' and 'save'")};
}

std::vector<Outgoing> RegisterController::show_frame(int index) {
  auto f = video_.frame(index);
  if (!f) return {error_message(f.message())};
  frame_ = index;
  frame_jpeg_ = encode_jpeg(f.value());
  std::vector<Outgoing> out = {
      binary_message(binary_header(BinaryKind::kFrame, static_cast<std::uint32_t>(frame_)) + frame_jpeg_)};
  if (!last_pairs_.empty()) {
    const std::string pairs = last_pairs_;
    for (Outgoing& m : run_registration(pairs, false)) out.push_back(std::move(m));
  }
  return out;
}

Outgoing RegisterController::overlay_message(const SE3* T_camera_model) {
  const auto header = binary_header(BinaryKind::kOverlay, static_cast<std::uint32_t>(frame_));
  if (!T_camera_model) return binary_message(header);
  const SE3 T_model_camera = T_camera_model->inverse();
  overlay::FrameAnnotations a;
  a.index = frame_;
  a.T_model_camera = &T_model_camera;
  return binary_message(header + encode_png(renderer_.draw_layer(a)));
}

std::vector<Outgoing> RegisterController::run_registration(std::string_view pairs_text, bool save) {
  last_pairs_ = std::string(pairs_text);
  const auto fail = [this](const std::string& message) {
    last_answer_ = {text_message("{\"type\":\"registration\",\"ok\":false,\"frame\":" + std::to_string(frame_) +
                                 ",\"message\":" + json_string(message) + "}"),
                    overlay_message(nullptr)};
    return last_answer_;
  };
  auto pairs = parse_registration_pairs(pairs_text);
  if (!pairs) return fail("The pairs sent are not readable: " + pairs.message());
  if (const std::string why = pairs_degeneracy(pairs.value()); !why.empty()) return fail(why);
  auto result = register_first_frame(pairs.value(), camera_);
  if (!result) return fail("No pose fits these pairs: " + result.message() + ".");
  const RegistrationResult& r = result.value();
  if (const std::string why = implausible_pose(r.T_camera_model, seq_->mesh, surface_, pairs.value(), r.inlier);
      !why.empty())
    return fail(why);

  std::vector<std::string> warnings;
  int off_mesh = 0;
  for (const RegistrationPair& p : pairs.value()) {
    SurfacePoint sp;
    if (!surface_.closest(p.p_model, &sp) || sp.distance_mm > kOffMeshMm) ++off_mesh;
  }
  if (off_mesh > 0) warnings.push_back(std::to_string(off_mesh) + " mesh point(s) more than 5 mm from the surface");
  const int outliers = static_cast<int>(pairs->size()) - r.inliers;
  if (outliers > 0)
    warnings.push_back(std::to_string(outliers) + " pair(s) do not agree with the others (outliers, over 8 px)");
  if (frame_ != 0) warnings.push_back("this is the pose of frame " + std::to_string(frame_) +
                                      "; only frame 0's registration can be saved");
  const PoseDelta change =
      pose_delta(seq_->config.T_camera_model_init.inverse(), r.T_camera_model.inverse());
  std::string json = "{\"type\":\"registration\",\"ok\":true,\"frame\":" + std::to_string(frame_) +
                     ",\"pairs\":" + std::to_string(pairs->size()) + ",\"inliers\":" + std::to_string(r.inliers) +
                     ",\"rms_px\":" + json_number(r.rms_px) + ",\"residual_px\":[";
  for (std::size_t i = 0; i < r.residual_px.size(); ++i)
    json += json_number(r.residual_px[i]) + (i + 1 < r.residual_px.size() ? "," : "");
  json += "],\"inlier\":[";
  for (std::size_t i = 0; i < r.inlier.size(); ++i)
    json += std::string(r.inlier[i] ? "true" : "false") + (i + 1 < r.inlier.size() ? "," : "");
  json += "],\"T_camera_model\":" + matrix_json(r.T_camera_model) + ",\"change_deg\":" +
          json_number(change.angle_deg) + ",\"change_mm\":" + json_number(change.distance_mm) + ",\"warnings\":[";
  for (std::size_t i = 0; i < warnings.size(); ++i) json += json_string(warnings[i]) + (i + 1 < warnings.size() ? "," : "");
  json += "]}";
  last_answer_ = {text_message(json), overlay_message(&r.T_camera_model)};
  std::vector<Outgoing> out = last_answer_;
  if (!save) return out;

  if (frame_ != 0) {
    out.push_back(error_message("Save writes T_camera_model_init, the pose of frame 0: show frame 0, register "
                                "there, then save."));
    return out;
  }
  const std::filesystem::path yaml_path = seq_->dir / "sequence.yaml";
  const std::filesystem::path backup = yaml_path.string() + ".bak";
  const std::filesystem::path pairs_path = seq_->dir / "registration_pairs.txt";
  auto old_yaml = read_file(yaml_path, kMaxYamlBytes);
  if (!old_yaml) {
    out.push_back(error_message("Not saved: " + old_yaml.message()));
    return out;
  }
  SequenceConfig updated = seq_->config;
  updated.T_camera_model_init = r.T_camera_model;
  std::string pairs_file =
      "# Registration pairs of frame 0 (scopetrack-studio): u v (pixel) x y z (mesh point, mm)\n";
  for (const RegistrationPair& p : pairs.value()) {
    char line[160];
    std::snprintf(line, sizeof line, "%.3f %.3f %.4f %.4f %.4f\n", p.px.x(), p.px.y(), p.p_model.x(), p.p_model.y(),
                  p.p_model.z());
    pairs_file += line;
  }
  Status s = write_file(backup, old_yaml.value());
  if (s) s = write_file(yaml_path, format_sequence_yaml(updated));
  if (s) s = write_file(pairs_path, pairs_file);
  if (!s) {
    out.push_back(error_message("Not saved: " + s.message()));
    return out;
  }
  seq_->config.T_camera_model_init = r.T_camera_model;
  check_current_pose();
  std::printf("scopetrack-studio: saved %s (the old file: %s) and %s\n", yaml_path.c_str(), backup.c_str(),
              pairs_path.c_str());
  std::fflush(stdout);
  out.push_back(text_message("{\"type\":\"saved\",\"yaml\":" + json_string(yaml_path.string()) +
                             ",\"backup\":" + json_string(backup.string()) + ",\"pairs\":" +
                             json_string(pairs_path.string()) + "}"));
  return out;
}

}  // namespace st::studio
