// scopetrack-overlay: the silhouette drawn at a pose must coincide with the
// organ seen in the frame. The frames here are ray-cast analytically (a box,
// through the lens distortion) independently of the rasteriser and of the
// overlay's distortion lookup; the "tracker output" is the ground truth.
#include <doctest/doctest.h>

#include <cmath>
#include <fstream>

#include "core/evaluation/evaluation.h"
#include "core/formats/trajectory.h"
#include "hal/storage/file_io.h"
#include "hal/storage/mesh_file.h"
#include "hal/storage/sequence_loader.h"
#include "hal/capture/y4m_reader.h"
#include "hal/storage/y4m_writer.h"
#include "support/support.h"
#include "support/tiny_sequence.h"
#include "tools/overlay/overlay.h"
#include "tools/overlay/run_output.h"

using namespace st;

namespace {

constexpr int kW = 160, kH = 120;
constexpr double kHalf = 20.0;  // the box: a 40 mm cube centred at the model origin
constexpr std::uint8_t kOrganY = 200, kBackgroundY = 40;

SE3 box_pose(int frame) {  // T_camera_model: three faces in view, drifting
  const Mat3 R = (Eigen::AngleAxisd(0.35 + 0.04 * frame, Vec3::UnitX()) *
                  Eigen::AngleAxisd(0.5 - 0.03 * frame, Vec3::UnitY()))
                     .toRotationMatrix();
  return SE3(R, Vec3(6.0 * std::sin(0.5 * frame), -3.0, 150.0));
}

// Slab test: does the ray o + s d (s > 0) hit the box?
bool hits_box(const Vec3& o, const Vec3& d) {
  double s_near = 0, s_far = 1e9;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(d[k]) < 1e-12) {
      if (std::abs(o[k]) > kHalf) return false;
      continue;
    }
    double s0 = (-kHalf - o[k]) / d[k], s1 = (kHalf - o[k]) / d[k];
    if (s0 > s1) std::swap(s0, s1);
    s_near = std::max(s_near, s0);
    s_far = std::min(s_far, s1);
  }
  return s_near <= s_far;
}

// The captured (distorted) image of the box: every pixel's ray through the lens.
Image<std::uint8_t> box_frame(const CameraModel& cam, const SE3& T_camera_model) {
  Image<std::uint8_t> y(kW, kH);
  const SE3 T_model_camera = T_camera_model.inverse();
  const Pinhole& K = cam.pinhole();
  bool all_converged = true;
  for (int v = 0; v < kH; ++v)
    for (int u = 0; u < kW; ++u) {
      Vec2 ideal;
      all_converged = cam.undistort_pixel(Vec2(u, v), &ideal) && all_converged;
      const Vec3 d_camera((ideal.x() - K.cx) / K.fx, (ideal.y() - K.cy) / K.fy, 1.0);
      const bool organ = hits_box(T_model_camera.translation(), T_model_camera.rotation() * d_camera);
      y(u, v) = organ ? kOrganY : kBackgroundY;
    }
  REQUIRE(all_converged);
  return y;
}

struct BoxSequence {
  std::filesystem::path dir;
  std::vector<TimedPose> gt;
};

BoxSequence write_box_sequence(const std::filesystem::path& dir, int frames) {
  SequenceConfig c;
  c.width = kW;
  c.height = kH;
  c.K = Pinhole{140, 140, 79.5, 59.5, kW, kH};
  c.distortion.count = 5;
  c.distortion.k = {-0.28, 0.08, 0.001, -0.001, 0, 0, 0, 0};  // clear barrel distortion
  c.fps = 30;
  c.T_camera_model_init = box_pose(0);
  c.video = "video.y4m";
  c.mesh = "organ.ply";
  c.groundtruth = "groundtruth.txt";
  c.markers = "markers.txt";
  BoxSequence s{dir, {}};
  for (int i = 0; i < frames; ++i) s.gt.push_back({i / c.fps, box_pose(i).inverse()});
  const std::vector<Marker> markers = {{1, Vec3(0, 0, 0)}, {2, Vec3(5, -5, 0)}};  // well inside the silhouette
  REQUIRE(write_sequence_files(dir, c, &s.gt, &markers).ok());
  REQUIRE(save_mesh_ply(dir / c.mesh, test::centred_cube(static_cast<float>(2 * kHalf))).ok());
  Y4mWriter writer;
  Y4mHeader h;
  h.width = kW;
  h.height = kH;
  h.fps_num = 30;
  REQUIRE(writer.open(dir / c.video, h).ok());
  Image<std::uint8_t> U(kW / 2, kH / 2), V(kW / 2, kH / 2);
  U.fill(128);
  V.fill(128);
  const CameraModel cam(c.K, c.distortion);
  for (int i = 0; i < frames; ++i) REQUIRE(writer.write(box_frame(cam, box_pose(i)).cview(), U.cview(), V.cview()).ok());
  REQUIRE(writer.close().ok());
  return s;
}

// A run folder as the tracker would write it, from given poses and states.
void write_run(const std::filesystem::path& out, const std::vector<TimedPose>& poses,
               const std::vector<std::string>& states) {
  std::filesystem::create_directories(out);
  REQUIRE(write_file(out / "trajectory.txt", format_tum(poses)).ok());
  std::string csv = frames_csv_header();
  for (std::size_t i = 0; i < states.size(); ++i)
    csv += std::to_string(i) + "," + format_number(static_cast<double>(i) / 30.0) + "," + states[i] + ",100,5,900,6\n";
  REQUIRE(write_file(out / "frames.csv", csv).ok());
}

struct EdgeAgreement {
  double mean_px = 0, max_px = 0;  // silhouette pixel -> nearest true edge pixel
  double coverage = 0;              // true edge pixels with a silhouette pixel within 1.5 px
  int silhouette_pixels = 0;
};

// True edge: a pixel of the source frame whose 4-neighbour differs.
bool is_edge(const FrameRef& f, int x, int y) {
  const int nx[4] = {x - 1, x + 1, x, x}, ny[4] = {y, y, y - 1, y + 1};
  for (int k = 0; k < 4; ++k)
    if (f.y.contains(nx[k], ny[k]) && f.y(nx[k], ny[k]) != f.y(x, y)) return true;
  return false;
}

double nearest(const std::vector<Vec2>& pts, const Vec2& p) {
  double best = 1e9;
  for (const Vec2& q : pts) best = std::min(best, (q - p).norm());
  return best;
}

// Silhouette pixels are exactly the overlay's opaque green (Y 150).
EdgeAgreement compare(const FrameRef& source, const FrameRef& drawn) {
  std::vector<Vec2> edge, sil;
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      if (is_edge(source, x, y)) edge.emplace_back(x, y);
      if (drawn.y(x, y) == 150) sil.emplace_back(x, y);
    }
  EdgeAgreement a;
  a.silhouette_pixels = static_cast<int>(sil.size());
  for (const Vec2& p : sil) {
    const double d = nearest(edge, p);
    a.mean_px += d / static_cast<double>(sil.size());
    a.max_px = std::max(a.max_px, d);
  }
  int covered = 0;
  for (const Vec2& p : edge) covered += nearest(sil, p) <= 1.5 ? 1 : 0;
  a.coverage = edge.empty() ? 0 : static_cast<double>(covered) / static_cast<double>(edge.size());
  return a;
}

// Renders the overlay and compares every frame with the source.
std::vector<EdgeAgreement> overlay_agreement(const BoxSequence& s, const std::filesystem::path& run,
                                             const std::string& name) {
  overlay::OverlayOptions o;
  o.sequence_dir = s.dir;
  o.run_dir = run;
  o.video_out = s.dir.parent_path() / name;
  o.style.text = false;
  o.style.markers = false;  // the silhouette alone: Y 150 is then only its green
  auto r = overlay::render_overlay(o);
  REQUIRE_MESSAGE(r.ok(), (r.ok() ? std::string() : r.message()));
  CHECK(r->error.empty());
  Y4mReader src, out;
  REQUIRE(src.open(s.dir / "video.y4m", 2).ok());
  REQUIRE(out.open(o.video_out, 2).ok());
  std::vector<EdgeAgreement> result;
  FrameRef a, b;
  while (src.read_frame(&a) == ReadResult::kFrame) {
    REQUIRE(out.read_frame(&b) == ReadResult::kFrame);
    result.push_back(compare(a, b));
  }
  CHECK(out.read_frame(&b) == ReadResult::kEndOfStream);
  return result;
}

}  // namespace

TEST_CASE("overlay: silhouette at the true pose coincides with the organ in distorted frames") {
  const auto dir = test::scratch_dir("overlay_gt");
  const BoxSequence s = write_box_sequence(dir / "seq", 6);
  write_run(dir / "run", s.gt, std::vector<std::string>(6, "tracking"));
  const auto agreement = overlay_agreement(s, dir / "run", "gt.y4m");
  REQUIRE(agreement.size() == 6);
  for (const EdgeAgreement& a : agreement) {
    CHECK(a.silhouette_pixels > 100);
    CHECK(a.mean_px < 0.5);
    CHECK(a.max_px <= 1.5);
    CHECK(a.coverage > 0.95);
    MESSAGE("silhouette to true edge: mean " << a.mean_px << " px, max " << a.max_px << " px, edge coverage "
                                               << a.coverage);
  }
}

TEST_CASE("overlay: a pose 8 mm off draws a silhouette visibly off the organ") {
  const auto dir = test::scratch_dir("overlay_off");
  const BoxSequence s = write_box_sequence(dir / "seq", 3);
  std::vector<TimedPose> shifted = s.gt;
  for (TimedPose& p : shifted) p.T_model_camera = SE3(Mat3::Identity(), Vec3(8, 0, 0)) * p.T_model_camera;
  write_run(dir / "run", shifted, std::vector<std::string>(3, "tracking"));
  for (const EdgeAgreement& a : overlay_agreement(s, dir / "run", "off.y4m")) {
    CHECK(a.mean_px > 1.5);
    CHECK(a.coverage < 0.6);
  }
}

TEST_CASE("overlay: lost frames get a red border and no silhouette, markers at both poses") {
  const auto dir = test::scratch_dir("overlay_lost");
  const BoxSequence s = write_box_sequence(dir / "seq", 3);
  write_run(dir / "run", {s.gt[0], s.gt[2]}, {"initialised", "lost", "tracking"});
  overlay::OverlayOptions o;
  o.sequence_dir = s.dir;
  o.run_dir = dir / "run";
  o.video_out = dir / "lost.y4m";
  auto r = overlay::render_overlay(o);
  REQUIRE(r.ok());
  CHECK(r->frames == 3);
  CHECK(r->frames_with_pose == 2);
  CHECK(r->frames_with_groundtruth == 3);
  Y4mReader out;
  REQUIRE(out.open(o.video_out, 3).ok());
  FrameRef f[3];
  for (auto& fr : f) REQUIRE(out.read_frame(&fr) == ReadResult::kFrame);
  const auto red = overlay::to_yuv({255, 0, 0});
  CHECK(std::abs(f[1].y(1, kH - 2) - red.y) <= 2);
  CHECK(std::abs(f[1].v(0, kH / 2 - 1) - red.v) <= 2);
  CHECK(std::abs(f[0].y(1, kH - 2) - kBackgroundY) <= 1);  // tracked: no border
  // The ground-truth marker ring (magenta) is drawn around the centre
  // marker's projection on every frame, the tracked dot (yellow) only with a pose.
  const auto cam = CameraModel(Pinhole{140, 140, 79.5, 59.5, kW, kH}, load_sequence(s.dir).value().config.distortion);
  for (int i = 0; i < 3; ++i) {
    Vec2 px;
    REQUIRE(project_marker(cam, s.gt[static_cast<std::size_t>(i)].T_model_camera, Vec3::Zero(), &px));
    const int cx = static_cast<int>(std::lround(px.x())), cy = static_cast<int>(std::lround(px.y()));
    int magenta = 0;
    for (int y = cy - 10; y <= cy + 10; ++y)
      for (int x = cx - 10; x <= cx + 10; ++x)
        magenta += f[i].v.contains(x / 2, y / 2) && f[i].v(x / 2, y / 2) > 200 && f[i].u(x / 2, y / 2) > 180;
    CHECK(magenta > 10);
    const auto yellow = overlay::to_yuv({255, 230, 0});
    CHECK((std::abs(f[i].y(cx, cy) - yellow.y) <= 3) == (i != 1));
  }
}

TEST_CASE("overlay: mp4 through ffmpeg") {
  if (std::string(SCOPETRACK_FFMPEG).empty()) return;  // ffmpeg is optional (Dependencies.cmake)
  const auto dir = test::scratch_dir("overlay_mp4");
  const BoxSequence s = write_box_sequence(dir / "seq", 4);
  write_run(dir / "run", s.gt, std::vector<std::string>(4, "tracking"));
  overlay::OverlayOptions o;
  o.sequence_dir = s.dir;
  o.run_dir = dir / "run";
  o.video_out = dir / "out.mp4";
  auto r = overlay::render_overlay(o);
  REQUIRE_MESSAGE(r.ok(), (r.ok() ? std::string() : r.message()));
  CHECK(r->through_ffmpeg);
  CHECK(std::filesystem::file_size(o.video_out) > 1000);
  o.video_out = dir / "no-such-dir" / "out.mp4";  // ffmpeg fails: reported, not ignored
  auto bad = overlay::render_overlay(o);
  REQUIRE_FALSE(bad.ok());
  CHECK(bad.message().find("ffmpeg") != std::string::npos);
}

TEST_CASE("overlay: run output parsing refuses bad trajectory times and bad frames.csv") {
  CHECK(overlay::parse_frame_states("frame,timestamp,state,inliers,latency_ms\n0,0,tracking,1,2\n2,0.1,lost,0,1\n")
            .ok());
  auto states =
      overlay::parse_frame_states("frame,timestamp,state,inliers,latency_ms\n0,0,tracking,1,2\n2,0.1,lost,0,1\n").value();
  REQUIRE(states.size() == 3);
  CHECK(*states[0] == FrameState::kTracking);
  CHECK_FALSE(states[1].has_value());
  CHECK(*states[2] == FrameState::kLost);
  CHECK_FALSE(overlay::parse_frame_states("frame,state\n0,tracking\n").ok());
  auto bad_state = overlay::parse_frame_states("frame,timestamp,state,inliers,latency_ms\n0,0,dancing,1,2\n");
  REQUIRE_FALSE(bad_state.ok());
  CHECK(bad_state.message().find("line 2") != std::string::npos);
  CHECK_FALSE(overlay::parse_frame_states("frame,timestamp,state,inliers,latency_ms\n-4,0,lost,1,2\n").ok());
  CHECK_FALSE(overlay::parse_frame_states("frame,timestamp,state,inliers,latency_ms\nx,0,lost,1,2\n").ok());
  const std::vector<TimedPose> poses = {{0.0, SE3()}, {0.1, SE3()}};
  CHECK(overlay::poses_by_frame(poses, 30).ok());  // 0.1 s = frame 3
  CHECK_FALSE(overlay::poses_by_frame({{0.05, SE3()}}, 30).ok());  // frame 1.5
  CHECK_FALSE(overlay::poses_by_frame({{-1.0, SE3()}}, 30).ok());
  CHECK_FALSE(overlay::poses_by_frame(poses, 0).ok());
}
