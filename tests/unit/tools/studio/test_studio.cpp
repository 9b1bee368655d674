// scopetrack-studio's server side without a browser: the registration
// commands a page sends (tools/studio/register_mode.h), the checks of a
// pose's plausibility, the JSON and binary framing (web_server.h).
#ifdef SCOPETRACK_HAVE_STUDIO
#include <doctest/doctest.h>

#include <cstdio>
#include <string>
#include <vector>

#include "core/formats/sequence.h"
#include "hal/storage/file_io.h"
#include "support/support.h"
#include "support/tiny_sequence.h"
#include "tools/studio/register_mode.h"

using namespace st;
using namespace st::studio;

namespace {

// The cube of the tiny sequence seen from a corner: three faces in view.
SE3 corner_view() {
  const Mat3 R = Eigen::AngleAxisd(0.6, Vec3(1, 1, 0).normalized()).toRotationMatrix();
  return SE3(R, Vec3(0, 0, 150));
}

// "register" with the pairs of the given model points at their projections
// (pixel offset dx added to each u).
std::string pairs_command(const char* verb, const CameraModel& cam, const SE3& T, const std::vector<Vec3>& points,
                          bool mirror = false) {
  std::vector<Vec2> px;
  Vec2 mean = Vec2::Zero();
  for (const Vec3& p : points) {
    px.push_back(cam.project(T * p));
    mean += px.back();
  }
  mean /= static_cast<double>(px.size());
  std::string s = std::string(verb) + "\n";
  for (std::size_t i = 0; i < points.size(); ++i) {
    const double u = mirror ? 2 * mean.x() - px[i].x() : px[i].x();
    char line[160];
    std::snprintf(line, sizeof line, "%.4f %.4f %.4f %.4f %.4f\n", u, px[i].y(), points[i].x(), points[i].y(),
                  points[i].z());
    s += line;
  }
  return s;
}

std::string text_of(const Outgoing& m) { return m.binary ? std::string() : *m.bytes; }

// The visible corners of the 40 mm cube from corner_view (all but the far one).
std::vector<Vec3> visible_corners(const SE3& T) {
  std::vector<Vec3> out;
  Vec3 far = Vec3::Zero();
  double far_z = -1;
  for (int i = 0; i < 8; ++i) {
    const Vec3 p((i & 1) ? 20 : -20, (i & 2) ? 20 : -20, (i & 4) ? 20 : -20);
    if ((T * p).z() > far_z) far_z = (T * p).z(), far = p;
  }
  for (int i = 0; i < 8; ++i) {
    const Vec3 p((i & 1) ? 20 : -20, (i & 2) ? 20 : -20, (i & 4) ? 20 : -20);
    if (p != far) out.push_back(p);
  }
  return out;
}

}  // namespace

TEST_CASE("studio: register commands give the pose, each pair's residual and the organ drawn at it") {
  const auto dir = test::scratch_dir("studio_register");
  test::TinySequence tiny = test::write_tiny_sequence(dir, 3);
  RegisterController reg(load_sequence(dir), 0);
  REQUIRE(reg.error().empty());
  const CameraModel cam(tiny.config.K, tiny.config.distortion);
  const SE3 truth = corner_view();

  // The greeting: info, the mesh (8 vertices, 12 triangles), frame 0 as JPEG.
  const std::vector<Outgoing> hello = reg.greeting();
  REQUIRE(hello.size() == 3);
  CHECK(text_of(hello[0]).find("\"mode\":\"register\"") != std::string::npos);
  CHECK(text_of(hello[0]).find("\"width\":64") != std::string::npos);
  REQUIRE(hello[1].binary);
  CHECK(hello[1].bytes->size() == 8 + 8 + 12 * 8 + 12 * 12);
  CHECK((*hello[1].bytes)[0] == static_cast<char>(BinaryKind::kMesh));
  REQUIRE(hello[2].binary);
  CHECK((*hello[2].bytes)[0] == static_cast<char>(BinaryKind::kFrame));
  CHECK(static_cast<unsigned char>((*hello[2].bytes)[8]) == 0xff);  // JPEG SOI
  CHECK(static_cast<unsigned char>((*hello[2].bytes)[9]) == 0xd8);

  // Seven corners at their projections: the pose comes back exactly.
  const std::vector<Outgoing> out = reg.handle(pairs_command("register", cam, truth, visible_corners(truth)));
  REQUIRE(out.size() == 2);
  const std::string json = text_of(out[0]);
  CHECK(json.find("\"ok\":true") != std::string::npos);
  CHECK(json.find("\"inliers\":7") != std::string::npos);
  REQUIRE(out[1].binary);
  CHECK((*out[1].bytes)[0] == static_cast<char>(BinaryKind::kOverlay));
  CHECK(out[1].bytes->size() > 8 + 8);  // a PNG
  CHECK(out[1].bytes->substr(9, 3) == "PNG");

  // Save: sequence.yaml gets the pose, the old file is kept, the pairs beside.
  const std::vector<Outgoing> saved = reg.handle(pairs_command("save", cam, truth, visible_corners(truth)));
  REQUIRE(saved.size() == 3);
  CHECK(text_of(saved[2]).find("\"type\":\"saved\"") != std::string::npos);
  auto yaml = read_file(dir / "sequence.yaml", 1 << 20);
  REQUIRE(yaml.ok());
  auto cfg = parse_sequence_yaml(yaml.value());
  REQUIRE(cfg.ok());
  const PoseDelta d = pose_delta(cfg->T_camera_model_init.inverse(), truth.inverse());
  CHECK(d.angle_deg < 1e-3);
  CHECK(d.distance_mm < 1e-3);
  CHECK(std::filesystem::exists(dir / "sequence.yaml.bak"));
  auto pairs = read_file(dir / "registration_pairs.txt", 1 << 20);
  REQUIRE(pairs.ok());
  CHECK(parse_registration_pairs(pairs.value()).ok());
  CHECK(load_checked_sequence(dir).ok());

  // Another frame: shown, and the last pairs registered again for it; save refused there.
  const std::vector<Outgoing> f2 = reg.handle("frame 2");
  REQUIRE(f2.size() == 3);
  CHECK((*f2[0].bytes)[0] == static_cast<char>(BinaryKind::kFrame));
  CHECK((*f2[0].bytes)[4] == 2);
  const std::vector<Outgoing> refused = reg.handle(pairs_command("save", cam, truth, visible_corners(truth)));
  CHECK(text_of(refused.back()).find("frame 0") != std::string::npos);
  CHECK(text_of(reg.handle("frame 9")[0]).find("past the end") != std::string::npos);
}

TEST_CASE("studio: pairs that cannot fix a pose, and a pose behind the organ, are refused with a reason") {
  const auto dir = test::scratch_dir("studio_register_bad");
  test::TinySequence tiny = test::write_tiny_sequence(dir, 1);
  RegisterController reg(load_sequence(dir), 0);
  REQUIRE(reg.error().empty());
  const CameraModel cam(tiny.config.K, tiny.config.distortion);
  const SE3 truth = corner_view();
  const auto answer = [&](const std::string& command) { return text_of(reg.handle(command)[0]); };

  const std::vector<Vec3> corners = visible_corners(truth);
  CHECK(answer(pairs_command("register", cam, truth, {corners[0], corners[1], corners[2]}))
            .find("at least 4 pairs") != std::string::npos);
  const std::vector<Vec3> spot = {Vec3(20, 20, -20), Vec3(19.5, 20, -20), Vec3(20, 19.5, -20), Vec3(19.6, 19.6, -20)};
  CHECK(answer(pairs_command("register", cam, truth, spot)).find("one spot") != std::string::npos);
  const std::vector<Vec3> line = {Vec3(-20, 20, -20), Vec3(-10, 20, -20), Vec3(0, 20, -20), Vec3(10, 20, -20),
                                  Vec3(20, 20, -20)};
  CHECK(answer(pairs_command("register", cam, truth, line)).find("one line") != std::string::npos);
  CHECK(answer("register\n1 2 3\n").find("not readable") != std::string::npos);
  CHECK(answer("bogus \xff\x01").find("unknown command") != std::string::npos);
  CHECK(answer("frame -1").find("frame number") != std::string::npos);
  // Every reply is valid JSON text: no raw control or non-UTF-8 bytes.
  for (const char c : answer("bogus \xff\x01")) CHECK((static_cast<unsigned char>(c) >= 0x20));

  // The plausibility of a pose that fits: the camera at the cube's centre
  // has the organ's centre on it; one looking at the far faces sees the
  // picked surface from inside.
  ClosestPointIndex surface;
  REQUIRE(surface.configure(tiny.mesh).ok());
  std::vector<RegistrationPair> picks;
  for (const Vec3& p : corners) picks.push_back({Vec2::Zero(), p, 0});
  const std::vector<bool> all(picks.size(), true);
  CHECK(implausible_pose(truth, tiny.mesh, surface, picks, all).empty());
  CHECK(implausible_pose(SE3(Mat3::Identity(), Vec3(0, 0, -5)), tiny.mesh, surface, picks, all)
            .find("behind the camera") != std::string::npos);
  // Picks on the face z = +20 seen by a camera on the -z side, beyond it: from behind the surface.
  std::vector<RegistrationPair> back;
  for (const Vec3& p : {Vec3(15, 15, 20), Vec3(-15, 15, 20), Vec3(15, -15, 20), Vec3(-15, -15, 20)})
    back.push_back({Vec2::Zero(), p, 0});
  CHECK(implausible_pose(SE3(Mat3::Identity(), Vec3(0, 0, 150)), tiny.mesh, surface, back,
                         std::vector<bool>(4, true))
            .find("behind the organ's surface") != std::string::npos);
}

TEST_CASE("studio: a sequence that cannot be used is explained to every page") {
  const auto dir = test::scratch_dir("studio_register_refused");
  test::write_tiny_sequence(dir, 1);
  std::filesystem::remove(dir / "organ.ply");
  RegisterController reg(load_sequence(dir), 0);
  CHECK(!reg.error().empty());
  const std::vector<Outgoing> hello = reg.greeting();
  REQUIRE(hello.size() == 1);
  CHECK(text_of(hello[0]).find("\"type\":\"error\"") != std::string::npos);
  CHECK(text_of(hello[0]).find("organ.ply") != std::string::npos);
  CHECK(text_of(reg.handle("register\n")[0]).find("\"type\":\"error\"") != std::string::npos);
  CHECK(!load_checked_sequence(dir).ok());
}

TEST_CASE("studio: JSON strings are escaped and kept valid UTF-8, binary headers carry kind and frame") {
  CHECK(json_string("a\"b\\c\n") == "\"a\\\"b\\\\c\\n\"");
  CHECK(json_string(std::string("x\x01y", 3)) == "\"x\\u0001y\"");
  CHECK(json_string("\xc3\xa9") == "\"\xc3\xa9\"");     // é kept
  CHECK(json_string("\xff\xc3") == "\"??\"");           // not UTF-8: replaced
  CHECK(json_number(1.5) == "1.5");
  CHECK(json_number(std::nan("")) == "null");
  const std::string h = binary_header(BinaryKind::kOverlay, 0x01020304u);
  REQUIRE(h.size() == 8);
  CHECK(h[0] == 3);
  CHECK(h[4] == 4);
  CHECK(h[7] == 1);
}
#endif  // SCOPETRACK_HAVE_STUDIO
