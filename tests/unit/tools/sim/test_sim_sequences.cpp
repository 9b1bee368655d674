// End-to-end: every scenario written to disk, read back with the project's
// parsers, and its ground truth checked against an independent projection.
#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <vector>

#include <opencv2/core.hpp>

#include "core/geometry/camera.h"
#include "core/formats/sequence.h"
#include "core/formats/trajectory.h"
#include "core/formats/y4m.h"
#include "hal/storage/file_io.h"
#include "hal/storage/mesh_file.h"
#include "support/shell.h"
#include "support/support.h"
#include "tools/sim/renderer.h"
#include "tools/sim/sim_run.h"

using namespace st;
using namespace st::sim;

namespace {

// Silhouette of a mesh at a pose through a distorted camera: every triangle
// in front of the camera filled at pixel centres (edge functions) between
// its projected vertices. Independent of the simulator's rasteriser and of
// its distortion map.
cv::Mat project_silhouette(const Mesh& mesh, const SE3& T_camera_model, const CameraModel& cam) {
  const int W = cam.pinhole().width, H = cam.pinhole().height;
  cv::Mat mask(H, W, CV_8U, cv::Scalar(0));
  std::vector<Vec2> px(static_cast<std::size_t>(mesh.vertex_count()));
  std::vector<char> front(px.size());
  for (int i = 0; i < mesh.vertex_count(); ++i) {
    const Vec3 p = T_camera_model * mesh.vertex(i);
    front[i] = p.z() > 1.0;
    if (front[i]) px[i] = cam.project(p);
  }
  for (int t = 0; t < mesh.triangle_count(); ++t) {
    const int ia = mesh.tri[3 * t], ib = mesh.tri[3 * t + 1], ic = mesh.tri[3 * t + 2];
    if (!front[ia] || !front[ib] || !front[ic]) continue;
    const Vec2 a = px[ia], b = px[ib], c = px[ic];
    const int x0 = std::max(0, static_cast<int>(std::ceil(std::min({a.x(), b.x(), c.x()}))));
    const int x1 = std::min(W - 1, static_cast<int>(std::floor(std::max({a.x(), b.x(), c.x()}))));
    const int y0 = std::max(0, static_cast<int>(std::ceil(std::min({a.y(), b.y(), c.y()}))));
    const int y1 = std::min(H - 1, static_cast<int>(std::floor(std::max({a.y(), b.y(), c.y()}))));
    auto edge = [](const Vec2& p, const Vec2& q, double x, double y) {
      return (q.x() - p.x()) * (y - p.y()) - (q.y() - p.y()) * (x - p.x());
    };
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x) {
        const double e0 = edge(a, b, x, y), e1 = edge(b, c, x, y), e2 = edge(c, a, x, y);
        if ((e0 >= 0 && e1 >= 0 && e2 >= 0) || (e0 <= 0 && e1 <= 0 && e2 <= 0)) mask.at<std::uint8_t>(y, x) = 255;
      }
  }
  return mask;
}

// IoU of the renderer's organ label and a projected silhouette, on pixels
// not covered by the instrument (which occludes the organ on purpose).
double organ_iou(const cv::Mat& labels, const cv::Mat& silhouette, int* organ_pixels) {
  int inter = 0, uni = 0, organ = 0;
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x) {
      const std::uint8_t l = labels.at<std::uint8_t>(y, x);
      if (l == kLabelInstrument) continue;
      const bool a = l == kLabelOrgan, b = silhouette.at<std::uint8_t>(y, x) != 0;
      inter += a && b;
      uni += a || b;
      organ += a;
    }
  *organ_pixels = organ;
  return uni == 0 ? 1.0 : static_cast<double>(inter) / uni;
}

struct ReadBack {
  SequenceConfig config;
  std::vector<TimedPose> groundtruth;
  std::vector<Marker> markers;
  Mesh organ;
  Y4mHeader video;
};

ReadBack read_back(const std::filesystem::path& dir) {
  ReadBack r;
  auto yaml = read_file(dir / "sequence.yaml", 1 << 20);
  REQUIRE(yaml.ok());
  auto cfg = parse_sequence_yaml(yaml.value());
  REQUIRE_MESSAGE(cfg.ok(), (cfg.ok() ? std::string() : cfg.message()));
  r.config = cfg.value();
  auto gt = read_file(dir / r.config.groundtruth, 1 << 26);
  REQUIRE(gt.ok());
  auto poses = parse_tum(gt.value());
  REQUIRE(poses.ok());
  r.groundtruth = poses.value();
  auto mk = read_file(dir / r.config.markers, 1 << 20);
  REQUIRE(mk.ok());
  auto markers = parse_markers(mk.value());
  REQUIRE(markers.ok());
  r.markers = markers.value();
  auto mesh = load_mesh_file(dir / r.config.mesh, nullptr);
  REQUIRE(mesh.ok());
  r.organ = mesh.value();
  auto video = read_file(dir / r.config.video, 1ll << 32);
  REQUIRE(video.ok());
  auto header = parse_y4m_header(video.value());
  REQUIRE(header.ok());
  r.video = header.value();
  CHECK(video.value().size() == r.video.header_bytes + r.groundtruth.size() * (6 + r.video.frame_bytes()));
  return r;
}

bool same_pose(const SE3& a, const SE3& b, double tol) {
  return (a.rotation() - b.rotation()).cwiseAbs().maxCoeff() < tol &&
         (a.translation() - b.translation()).cwiseAbs().maxCoeff() < tol;
}

void check_scenario(const char* name, int frames, const std::filesystem::path& mesh = {}) {
  SimOptions o;
  o.scenario = parse_scenario(name).value();
  o.out_dir = st::test::scratch_dir(std::string("sim_") + name);
  o.frames = frames;
  o.width = 640;
  o.height = 360;
  o.seed = 4;
  o.mesh_file = mesh;
  std::vector<cv::Mat> labels;
  const auto report = run_simulation(o, [&](int, const cv::Mat&, const cv::Mat& l) { labels.push_back(l.clone()); });
  REQUIRE_MESSAGE(report.ok(), (report.ok() ? std::string() : report.message()));
  const ReadBack r = read_back(o.out_dir);
  CHECK(r.video.width == 640);
  CHECK(r.video.chroma_tag == "420jpeg");
  REQUIRE(static_cast<int>(r.groundtruth.size()) == frames);
  // Files read back to the poses the renderer used, within 1e-6.
  for (int i = 0; i < frames; ++i) {
    CHECK(same_pose(r.groundtruth[i].T_model_camera, report->groundtruth[i].T_model_camera, 1e-6));
    CHECK(r.groundtruth[i].timestamp_s == doctest::Approx(i / r.config.fps));
  }
  CHECK(same_pose(r.config.T_camera_model_init, r.groundtruth[0].T_model_camera.inverse(), 1e-6));
  // The organ pixels of every frame = the silhouette of the rendered mesh
  // at the ground-truth pose read from the files.
  auto setup = make_setup(o);
  REQUIRE(setup.ok());
  const bool prior_is_rendered = o.scenario != ScenarioKind::InVivo;
  const Mesh& rendered = prior_is_rendered ? r.organ : setup->scene.organ;
  const CameraModel cam(r.config.K, r.config.distortion);
  double worst = 1.0, worst_prior = 1.0;
  int empty_frames = 0;
  for (int i = 0; i < frames; ++i) {
    const SE3 T_camera_model = r.groundtruth[i].T_model_camera.inverse();
    int organ_px = 0;
    const double iou = organ_iou(labels[i], project_silhouette(rendered, T_camera_model, cam), &organ_px);
    if (organ_px == 0) ++empty_frames;
    worst = std::min(worst, iou);
    if (!prior_is_rendered)
      worst_prior = std::min(worst_prior, organ_iou(labels[i], project_silhouette(r.organ, T_camera_model, cam), &organ_px));
  }
  MESSAGE(std::string(name) << ": worst organ IoU " << worst << ", prior IoU " << worst_prior << ", frames without organ "
               << empty_frames << ", " << report->fps << " frames/s at 640x360");
  CHECK(worst >= 0.99);
  if (!prior_is_rendered) CHECK(worst_prior >= 0.9);
  if (o.scenario == ScenarioKind::OutOfView) CHECK(empty_frames >= 2);
  else CHECK(empty_frames == 0);
  // Markers of frame 0 lie on the organ seen in frame 0.
  REQUIRE(r.markers.size() == 3);
  for (const Marker& m : r.markers) {
    const Vec2 px = cam.project(r.config.T_camera_model_init * m.p_model);
    const int x = static_cast<int>(std::lround(px.x())), y = static_cast<int>(std::lround(px.y()));
    REQUIRE(cam.pinhole().in_image(Vec2(x, y)));
    CHECK(labels[0].at<std::uint8_t>(y, x) == kLabelOrgan);
  }
  const double spread = (r.markers[0].p_model - r.markers[1].p_model).norm();
  CHECK(spread > 30.0);
}

}  // namespace

TEST_CASE("sim sequence: orbit ground truth is exact" * doctest::timeout(st::test::budget_s(30)) * doctest::test_suite(test::kLongSuite)) {
  check_scenario("orbit", 20);
}
TEST_CASE("sim sequence: fast ground truth is exact, blurred frames included" * doctest::timeout(st::test::budget_s(30)) * doctest::test_suite(test::kLongSuite)) {
  check_scenario("fast", 20);
}
TEST_CASE("sim sequence: outofview ground truth is exact, organ leaves the image" * doctest::timeout(st::test::budget_s(30)) * doctest::test_suite(test::kLongSuite)) {
  check_scenario("outofview", 20);
}
TEST_CASE("sim sequence: manipulation ground truth is exact (organ moves)" * doctest::timeout(st::test::budget_s(30)) * doctest::test_suite(test::kLongSuite)) {
  check_scenario("manipulation", 20);
}
TEST_CASE("sim sequence: invivo ground truth is exact through distortion" * doctest::timeout(st::test::budget_s(30)) * doctest::test_suite(test::kLongSuite)) {
  check_scenario("invivo", 20);
}

TEST_CASE("sim sequence: the CT liver of shared/data as the organ (--mesh)" * doctest::timeout(st::test::budget_s(30)) * doctest::test_suite(test::kLongSuite)) {
  check_scenario("orbit", 10, st::test::shared_data("liver/liver.ply"));
}

TEST_CASE("sim sequence: deterministic for a seed" * doctest::timeout(st::test::budget_s(30)) * doctest::test_suite(test::kLongSuite)) {
  auto video_of = [](std::uint64_t seed, const char* dir) {
    SimOptions o;
    o.scenario = ScenarioKind::InVivo;
    o.out_dir = st::test::scratch_dir(dir);
    o.frames = 3;
    o.width = 320;
    o.height = 180;
    o.seed = seed;
    REQUIRE(run_simulation(o).ok());
    auto v = read_file(o.out_dir / "video.y4m", 1 << 26);
    REQUIRE(v.ok());
    auto p = read_file(o.out_dir / "organ.ply", 1 << 26);
    REQUIRE(p.ok());
    return v.value() + p.value();
  };
  const std::string a = video_of(7, "sim_det_a"), b = video_of(7, "sim_det_b"), c = video_of(8, "sim_det_c");
  CHECK(a == b);
  CHECK(a != c);
}

TEST_CASE("sim sequence: bad options are refused with a message") {
  SimOptions o;
  o.out_dir = st::test::scratch_dir("sim_bad");
  o.width = 641;
  o.height = 360;
  auto r = run_simulation(o);
  REQUIRE_FALSE(r.ok());
  CHECK(r.message().find("even") != std::string::npos);
  o.width = 640;
  o.mesh_file = o.out_dir / "missing.ply";
  CHECK_FALSE(run_simulation(o).ok());
}

TEST_CASE("sim CLI: --shutter, --organ-detail, --smoke and --organ refuse what they do not take, writing nothing" *
          doctest::test_suite(st::test::kProcessSuite)) {
  const auto dir = st::test::scratch_dir("sim_cli_bad");
  const std::string log = (dir / "log").string();
  // args refused with exit 2 and a message holding says; nothing written.
  const auto refused_saying = [&](const std::string& args, const std::string& says) {
    CAPTURE(args);
    const std::string cmd = st::test::bin_command("scopetrack-sim") + " --scenario orbit --frames 2 --out " +
                            st::test::shell_quoted(dir / "seq") + " " + args + " > " + st::test::shell_quoted(log) +
                            " 2>&1";
    CHECK(st::test::run_shell(cmd) == 2);
    CHECK(st::test::read_file_bytes(log).find(says) != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir / "seq" / "video.y4m"));
  };
  const auto refused = [&](const std::string& opt, const std::string& bad) {
    refused_saying(opt + " " + bad, opt + " wants");
  };
  for (const char* opt : {"--shutter", "--organ-detail", "--smoke"})
    for (const char* bad : {"nan", "-0.1", "3", "0.5x", "''", "1e"}) refused(opt, bad);
  refused("--smoke", "0.95");  // a veil that hides everything
  for (const char* bad : {"nan", "-0.1", "0", "2000", "0.5x", "''", "1e"}) refused("--texture-scale", bad);
  for (const char* bad : {"-1", "4", "1.5", "x", "''"}) refused("--prior-subdivide", bad);
  // --organ: a name it knows, and not together with --mesh.
  refused_saying("--organ spleen", "unknown organ 'spleen': use liver, kidney or stomach");
  refused_saying("--organ ''", "unknown organ");
  refused_saying("--organ kidney --mesh " + st::test::shell_quoted(st::test::shared_data("liver/liver.ply")),
                 "--organ and --mesh both name the organ");
  // A texture that is no photo: a clear error naming it, nothing written.
  {
    std::ofstream(dir / "not.y4m") << "P5 no video";
  }
  const std::string cmd = st::test::bin_command("scopetrack-sim") + " --scenario orbit --frames 2 --out " +
                          st::test::shell_quoted(dir / "seq") + " --texture " +
                          st::test::shell_quoted(dir / "not.y4m") + " > " + st::test::shell_quoted(log) + " 2>&1";
  CHECK(st::test::run_shell(cmd) == 1);
  CHECK(st::test::read_file_bytes(log).find("not.y4m") != std::string::npos);
  CHECK_FALSE(std::filesystem::exists(dir / "seq" / "video.y4m"));
}

TEST_CASE("sim and console CLI: --help prints the usage on stdout and exits 0" *
          doctest::test_suite(st::test::kProcessSuite)) {
  const auto dir = st::test::scratch_dir("cli_help");
  for (const char* tool : {"scopetrack-sim", "scopetrack-console"}) {
    CAPTURE(tool);
    const auto out = dir / (std::string(tool) + ".out");
    CHECK(st::test::run_shell(st::test::bin_command(tool) + " --help > " + st::test::shell_quoted(out) + " 2>&1") == 0);
    CHECK(st::test::read_file_bytes(out).rfind("usage: ", 0) == 0);
  }
}
