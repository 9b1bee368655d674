// scopetrack --check DIR: loads a sequence the way a replay would and
// prints what a user needs to know before relying on it. Exit status 0 only
// when the sequence is usable: everything loads, the video has complete
// frames of the calibrated size, and the mesh projects into frame 0 at
// T_camera_model_init (rendered: it covers part of the image). Runs once
// at the command line (allocates freely).
#include <algorithm>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <limits>
#include <string>

#include "core/geometry/camera.h"
#include "core/raster/rasterizer.h"
#include "firmware_app/cli.h"
#include "hal/storage/sequence_loader.h"
#include "hal/capture/y4m_reader.h"

namespace st::app {
namespace {

class Report {
 public:
  // quiet: print nothing, keep the first error (a replay's pre-flight check).
  explicit Report(bool quiet = false) : quiet_(quiet) {}
  const std::string& first_error() const { return first_error_; }
  void line(const char* topic, const char* fmt, ...) __attribute__((format(printf, 3, 4))) {
    va_list a;
    va_start(a, fmt);
    emit(topic, "", fmt, a);
    va_end(a);
  }
  void warn(const char* topic, const char* fmt, ...) __attribute__((format(printf, 3, 4))) {
    ++warnings_;
    va_list a;
    va_start(a, fmt);
    emit(topic, "WARNING: ", fmt, a);
    va_end(a);
  }
  void error(const char* topic, const char* fmt, ...) __attribute__((format(printf, 3, 4))) {
    ++errors_;
    va_list a;
    va_start(a, fmt);
    if (first_error_.empty()) {
      char buf[1024];
      va_list b;
      va_copy(b, a);
      std::vsnprintf(buf, sizeof buf, fmt, b);
      va_end(b);
      first_error_ = std::string(topic) + ": " + buf;
    }
    emit(topic, "ERROR: ", fmt, a);
    va_end(a);
  }
  int finish() const {
    if (errors_ == 0)
      std::printf("%-12s USABLE (%d warning%s)\n", "verdict", warnings_, warnings_ == 1 ? "" : "s");
    else
      std::printf("%-12s NOT USABLE (%d error%s, %d warning%s)\n", "verdict", errors_,
                  errors_ == 1 ? "" : "s", warnings_, warnings_ == 1 ? "" : "s");
    return errors_ == 0 ? 0 : 1;
  }

 private:
  void emit(const char* topic, const char* kind, const char* fmt, va_list a) const {
    if (quiet_) return;
    std::printf("%-12s %s", topic, kind);
    std::vprintf(fmt, a);
    std::printf("\n");
  }
  int errors_ = 0, warnings_ = 0;
  bool quiet_ = false;
  std::string first_error_;
};

void report_video(const LoadedSequence& s, Report& r) {
  const Y4mHeader& h = s.video_header;
  if (s.video_is_pipe) {
    r.line("video", "%s is a pipe: frames are not counted (reading would consume them)",
           s.config.video.c_str());
    return;
  }
  Y4mReader reader;
  if (Status st = reader.open(s.video_path, 1); !st) return r.error("video", "%s", st.message().c_str());
  FrameRef f;
  ReadResult res;
  while ((res = reader.read_frame(&f)) == ReadResult::kFrame) {
  }
  const int n = reader.frames_read();
  if (res == ReadResult::kError)
    return r.error("video", "%s (after %d complete frames)", reader.error().c_str(), n);
  if (n == 0) return r.error("video", "%s has no frames", s.config.video.c_str());
  r.line("video", "%d frames, %dx%d, %s (C%s), header %d:%d fps, %.2f s at the calibrated %.3g fps", n,
         h.width, h.height, h.chroma == Chroma::kMono ? "mono" : "4:2:0",
         h.chroma_tag.empty() ? "420, default" : h.chroma_tag.c_str(), h.fps_num, h.fps_den,
         n / s.config.fps, s.config.fps);
  if (std::abs(h.fps() - s.config.fps) > 1e-3 * s.config.fps)
    r.warn("video", "the Y4M header says %.3f fps, sequence.yaml %.3f fps: timestamps use sequence.yaml",
           h.fps(), s.config.fps);
}

void report_camera(const SequenceConfig& c, Report& r) {
  const Pinhole& K = c.K;
  r.line("camera", "%dx%d, fx %.2f fy %.2f, principal point (%.2f, %.2f), field of view %.1f x %.1f deg",
         c.width, c.height, K.fx, K.fy, K.cx, K.cy, K.hfov_deg(), K.vfov_deg());
  const Distortion& d = c.distortion;
  if (d.is_zero()) {
    r.line("distortion", "none (ideal pinhole)");
  } else {
    std::string ks;
    for (int i = 0; i < d.count; ++i) {
      if (i > 0) ks += ' ';
      ks += std::to_string(d.k[static_cast<std::size_t>(i)]);
    }
    r.line("distortion", "%d coefficients: %s", d.count, ks.c_str());
  }
}

void report_pose(const SequenceConfig& c, Report& r) {
  const SE3& T = c.T_camera_model_init;
  const Vec3 t = T.translation();
  const Vec3 camera_in_model = T.inverse().translation();
  r.line("T_init", "rotation %.2f deg, translation (%.1f, %.1f, %.1f) mm; camera at (%.1f, %.1f, %.1f) mm in the model frame",
         so3_log(T.rotation()).norm() * 180.0 / M_PI, t.x(), t.y(), t.z(), camera_in_model.x(),
         camera_in_model.y(), camera_in_model.z());
  if (c.T_init_reorthonormalised)
    r.line("T_init", "its rotation was slightly off (rounding) and has been re-orthonormalised");
}

void report_mesh(const LoadedSequence& s, Report& r) {
  r.line("mesh", "%s: %s", s.config.mesh.c_str(), s.mesh_report.summary.c_str());
  const Vec3 e = s.mesh_report.max - s.mesh_report.min;
  if (e.maxCoeff() < 5.0 || e.maxCoeff() > 2000.0)
    r.warn("mesh", "its largest extent is %.3g: the mesh must be in millimetres (an organ is ~20..300 mm)",
           e.maxCoeff());
}

// Vertices of the mesh seen from frame 0's camera.
struct VertexProjection {
  int in_front = 0, inside = 0;
  double centre_depth_mm = 0;
};

VertexProjection project_vertices(const LoadedSequence& s) {
  const CameraModel cam(s.config.K, s.config.distortion);
  const SE3& T = s.config.T_camera_model_init;
  VertexProjection p;
  for (int i = 0; i < s.mesh.vertex_count(); ++i) {
    const Vec3 p_camera = T * s.mesh.vertex(i);
    if (p_camera.z() < 1.0) continue;
    ++p.in_front;
    p.inside += s.config.K.in_image(cam.project(p_camera)) ? 1 : 0;
  }
  const Vec3 centre_model = 0.5 * (s.mesh_report.min + s.mesh_report.max);
  p.centre_depth_mm = (T * centre_model).z();
  return p;
}

// The mesh rendered at T_init (ideal pinhole: the rasteriser ignores lens
// distortion, a good approximation for the covered fraction), at most
// kCoverageWidth wide: a fraction and a depth range need no more, and a
// render at 4K (83 MB of targets) set the replay's peak memory before the
// tracker had allocated anything.
struct Coverage {
  double fraction = 0.0;
  float near_mm = 0.0f, far_mm = 0.0f;
};
constexpr int kCoverageWidth = 1280;

Result<Coverage> render_coverage(const LoadedSequence& s) {
  MeshRasterizer raster;
  RasterConfig rc;
  const double f = std::min(1.0, static_cast<double>(kCoverageWidth) / s.config.width);
  rc.width = std::max(1, static_cast<int>(std::lround(s.config.width * f)));
  rc.height = std::max(1, static_cast<int>(std::lround(s.config.height * f)));
  if (Status st = raster.configure(s.mesh, rc); !st) return Error{st.message()};
  const double sx = static_cast<double>(rc.width) / s.config.width, sy = static_cast<double>(rc.height) / s.config.height;
  raster.render(s.config.T_camera_model_init, s.config.K.scaled(sx, sy, rc.width, rc.height));
  Coverage c;
  c.fraction = static_cast<double>(raster.covered_pixels()) / (static_cast<double>(rc.width) * rc.height);
  const ImageView<const float> depth = raster.depth();
  c.near_mm = std::numeric_limits<float>::max();
  for (int y = 0; y < depth.height; ++y)
    for (int x = 0; x < depth.width; ++x)
      if (depth(x, y) > 0.0f) {
        c.near_mm = std::min(c.near_mm, depth(x, y));
        c.far_mm = std::max(c.far_mm, depth(x, y));
      }
  return c;
}

void report_projection(const LoadedSequence& s, Report& r) {
  const VertexProjection p = project_vertices(s);
  const double n = s.mesh.vertex_count();
  r.line("frame 0", "at T_init the mesh centre is %.1f mm in front of the camera; %.1f%% of its vertices are in front, %.1f%% inside the image",
         p.centre_depth_mm, 100.0 * p.in_front / n, 100.0 * p.inside / n);
  if (p.in_front == 0)
    return r.error("frame 0", "the mesh is entirely behind the camera at T_camera_model_init (is it T_model_camera, or in metres?)");
  const Result<Coverage> c = render_coverage(s);
  if (!c) return r.error("frame 0", "cannot render the mesh: %s", c.message().c_str());
  if (c->fraction <= 0.0)
    return r.error("frame 0", "no part of the mesh projects into the image at T_camera_model_init");
  r.line("frame 0", "the rendered mesh covers %.1f%% of the image, visible depth %.1f..%.1f mm",
         100.0 * c->fraction, static_cast<double>(c->near_mm), static_cast<double>(c->far_mm));
  if (c->fraction < 0.01)
    r.warn("frame 0", "the organ covers under 1%% of frame 0: initialisation will find few points on it");
}

void report_groundtruth(const LoadedSequence& s, Report& r) {
  if (s.config.groundtruth.empty()) return r.line("groundtruth", "none");
  if (s.groundtruth.empty()) return r.warn("groundtruth", "%s has no poses", s.config.groundtruth.c_str());
  const TimedPose& first = s.groundtruth.front();
  const PoseDelta d = pose_delta(first.T_model_camera.inverse(), s.config.T_camera_model_init);
  r.line("groundtruth", "%zu poses from t = %.3f s to %.3f s; the first differs from T_init by %.2f deg, %.2f mm",
         s.groundtruth.size(), first.timestamp_s, s.groundtruth.back().timestamp_s, d.angle_deg, d.distance_mm);
  if (first.timestamp_s < 0.5 / s.config.fps && (d.angle_deg > 10.0 || d.distance_mm > 50.0))
    r.warn("groundtruth", "the frame-0 ground truth and T_init disagree a lot: check that groundtruth is T_model_camera");
}

void report_markers(const LoadedSequence& s, Report& r) {
  if (s.config.markers.empty()) return r.line("markers", "none");
  const CameraModel cam(s.config.K, s.config.distortion);
  int visible = 0;
  for (const Marker& m : s.markers) {
    const Vec3 p = s.config.T_camera_model_init * m.p_model;
    visible += p.z() > 1.0 && s.config.K.in_image(cam.project(p)) ? 1 : 0;
  }
  r.line("markers", "%zu markers, %d project into frame 0 at T_init", s.markers.size(), visible);
}

}  // namespace

Status check_sequence_for_replay(const LoadedSequence& s) {
  Report r(/*quiet=*/true);
  report_mesh(s, r);
  report_camera(s.config, r);
  report_pose(s.config, r);
  report_projection(s, r);
  report_groundtruth(s, r);
  report_markers(s, r);
  if (!r.first_error().empty()) return make_error(r.first_error());
  return Status::Ok();
}

int run_check(Args args) {
  if (args.size() != 1) {
    std::fprintf(stderr, "usage: scopetrack --check DIR\n");
    return 2;
  }
  Report r;
  std::printf("%-12s %s\n", "sequence", args[0]);
  Result<LoadedSequence> s = load_sequence(args[0]);
  if (!s) {
    r.error("load", "%s", s.message().c_str());
    return r.finish();
  }
  report_video(s.value(), r);
  report_mesh(s.value(), r);
  report_camera(s->config, r);
  report_pose(s->config, r);
  report_projection(s.value(), r);
  report_groundtruth(s.value(), r);
  report_markers(s.value(), r);
  return r.finish();
}

}  // namespace st::app
