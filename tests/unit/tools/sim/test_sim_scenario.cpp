#include <doctest/doctest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/geometry/camera.h"
#include "tools/sim/liver_mesh.h"
#include "tools/sim/scenario.h"
#include "tools/sim/scene.h"

using namespace st;
using namespace st::sim;

namespace {

const Scene& test_scene() {
  static const Scene scene = make_scene(make_liver_mesh(), 5);
  return scene;
}

// Distance from the camera to the nearest organ vertex, and whether the
// organ's box centre lies in front of the camera inside a 70 deg cone.
double nearest_organ_mm(const WorldState& s) {
  const SE3 T_camera_model = s.T_model_camera().inverse();
  double best = 1e9;
  const Mesh& m = test_scene().organ;
  for (int i = 0; i < m.vertex_count(); i += 7) best = std::min(best, (T_camera_model * m.vertex(i)).norm());
  return best;
}

int organ_vertices_in_view(const WorldState& s, const Pinhole& K) {
  const SE3 T_camera_model = s.T_model_camera().inverse();
  const Mesh& m = test_scene().organ;
  int n = 0;
  for (int i = 0; i < m.vertex_count(); i += 3) {
    const Vec3 p = T_camera_model * m.vertex(i);
    if (p.z() > 1.0 && K.in_image(K.project(p))) ++n;
  }
  return n;
}

const Pinhole kK{921.6, 921.6, 639.5, 359.5, 1280, 720};

}  // namespace

TEST_CASE("sim: look_at gives an OpenCV camera looking at the target, image up = world up") {
  const SE3 T = look_at(Vec3(100, 0, 100), Vec3(0, 0, 0), 0.0);
  const Vec3 p_cam = T.inverse() * Vec3(0, 0, 0);
  CHECK(p_cam.x() == doctest::Approx(0).epsilon(1e-12));
  CHECK(p_cam.y() == doctest::Approx(0).epsilon(1e-12));
  CHECK(p_cam.z() == doctest::Approx(std::sqrt(2.0) * 100));
  CHECK(T.rotation().determinant() == doctest::Approx(1.0));
  // A point above the target appears above the image centre (y < 0).
  CHECK((T.inverse() * Vec3(0, 0, 10)).y() < 0);
}

TEST_CASE("sim: every scenario keeps a sane, smooth scope path looking at the organ") {
  for (const char* name : {"orbit", "fast", "outofview", "manipulation", "invivo", "newview"}) {
    CAPTURE(name);
    const auto kind = parse_scenario(name);
    REQUIRE(kind.ok());
    const Trajectory traj(kind.value(), test_scene(), 300, 3);
    double min_d = 1e9, max_d = 0, max_step_deg = 0;
    int out_frames = 0, blurred = 0, min_sub = 99, max_sub = 0;
    for (int i = 0; i < 300; ++i) {
      const WorldState s = traj.at(i);
      if (organ_vertices_in_view(s, kK) == 0) {
        ++out_frames;
      } else {
        min_d = std::min(min_d, nearest_organ_mm(s));
        max_d = std::max(max_d, nearest_organ_mm(s));
      }
      if (i > 0) max_step_deg = std::max(max_step_deg, pose_delta(traj.at(i - 1).T_model_camera(), s.T_model_camera()).angle_deg);
      // Blurred frames: an odd count (a sub-frame at the frame time), more
      // for a longer smear, within the render budget.
      const int n = traj.blur_subframes(i);
      CHECK((n == 1 || (n >= 5 && n <= 9 && n % 2 == 1)));
      if (n > 1) {
        ++blurred;
        min_sub = std::min(min_sub, n);
        max_sub = std::max(max_sub, n);
      }
    }
    MESSAGE(std::string(name) << ": organ distance " << min_d << ".." << max_d << " mm, out of view " << out_frames
                 << " frames, largest step " << max_step_deg << " deg, blurred " << blurred);
    CHECK(organ_vertices_in_view(traj.at(0), kK) > 500);
    CHECK(min_d > 30.0);
    CHECK(max_d < 160.0);
    // The swings of fast and outofview (2-7 deg per frame) reach the most
    // sub-frames; their onsets fewer.
    if (blurred > 0) {
      CHECK(max_sub == 9);
      CHECK(min_sub < 9);
    }
    if (std::string(name) == "outofview" || std::string(name) == "newview") {
      CHECK(out_frames >= 30);  // >= 1 s at 30 fps
      CHECK(out_frames <= (std::string(name) == "newview" ? 75 : 60));  // <= 2 s (newview: 2.5 s, it travels)
      // outofview comes back to a view seen before.
      if (std::string(name) == "outofview")
        CHECK(pose_delta(traj.at(0.66 * 299).T_model_camera(), traj.at(0.21 * 299).T_model_camera()).angle_deg < 5.0);
    } else {
      CHECK(out_frames == 0);
    }
    if (std::string(name) == "fast") {
      CHECK(max_step_deg > 2.0);
      CHECK(blurred >= 10);
    } else if (std::string(name) != "outofview" && std::string(name) != "newview") {
      CHECK(max_step_deg < 2.0);
    }
  }
}

// newview's return (the first frame after the spell away with a tenth of
// the organ's sampled vertices in view, and the 10 frames after it): at
// least 35 deg round the organ from every earlier frame that saw it, and at most
// 1/1.5 of their nearest organ distance; the path never comes within 25 mm
// of the organ.
TEST_CASE("sim: newview comes back from a new side, closer than before") {
  for (std::uint64_t seed : {1u, 2u, 3u}) {
    CAPTURE(seed);
    const Trajectory traj(ScenarioKind::NewView, test_scene(), 300, seed);
    const int organ_n = (test_scene().organ.vertex_count() + 2) / 3;
    std::vector<int> seen;
    double nearest_before = 1e9, nearest_ever = 1e9;
    int away = -1, back = -1;
    for (int i = 0; i < 300; ++i) {
      const WorldState s = traj.at(i);
      nearest_ever = std::min(nearest_ever, nearest_organ_mm(s));
      const int in_view = organ_vertices_in_view(s, kK);
      if (away < 0) {
        if (in_view == 0) away = i;
        else {
          seen.push_back(i);
          nearest_before = std::min(nearest_before, nearest_organ_mm(s));
        }
      } else if (back < 0 && 10 * in_view >= organ_n) {
        back = i;
      }
    }
    REQUIRE(away > 0);
    REQUIRE(back > away);
    double min_angle = 1e9, max_nearest = 0;
    for (int i = back; i <= back + 10; ++i) {
      const WorldState s = traj.at(i);
      max_nearest = std::max(max_nearest, nearest_organ_mm(s));
      // The side the organ is seen from: the camera centre's direction from
      // the organ's centre (the model origin is at its box centre).
      const Vec3 side = s.T_model_camera().translation().normalized();
      for (int j : seen) {
        const Vec3 before = traj.at(j).T_model_camera().translation().normalized();
        min_angle = std::min(min_angle, std::acos(std::clamp(side.dot(before), -1.0, 1.0)) * 180.0 / M_PI);
      }
    }
    MESSAGE("away at " << away << ", back at " << back << ": " << min_angle << " deg from every earlier view, nearest organ "
                       << max_nearest << " mm (before: " << nearest_before << " mm), nearest ever " << nearest_ever << " mm");
    CHECK(min_angle >= 35.0);
    CHECK(max_nearest * 1.5 <= nearest_before);
    CHECK(nearest_ever > 25.0);
  }
}

TEST_CASE("sim: manipulation moves the organ against the background, others do not") {
  const Trajectory manip(ScenarioKind::Manipulation, test_scene(), 100, 1);
  const PoseDelta d = pose_delta(manip.at(0).T_world_model, manip.at(55).T_world_model);
  MESSAGE("organ moved " << d.angle_deg << " deg, " << d.distance_mm << " mm");
  CHECK(d.angle_deg > 15.0);
  const Trajectory orbit(ScenarioKind::Orbit, test_scene(), 100, 1);
  CHECK(pose_delta(orbit.at(0).T_world_model, orbit.at(55).T_world_model).angle_deg == 0.0);
  // The instrument tip stays on the grasp point as the organ moves.
  const SE3 a = manip.at(20).T_world_model.inverse() * manip.at(20).T_world_instrument;
  const SE3 b = manip.at(60).T_world_model.inverse() * manip.at(60).T_world_instrument;
  CHECK((a * Vec3(0, 0, -12) - b * Vec3(0, 0, -12)).norm() < 1e-9);
}

TEST_CASE("sim: trajectories are deterministic for a seed") {
  const Trajectory a(ScenarioKind::InVivo, test_scene(), 50, 9), b(ScenarioKind::InVivo, test_scene(), 50, 9),
      c(ScenarioKind::InVivo, test_scene(), 50, 10);
  CHECK((a.at(17).T_world_camera.matrix() - b.at(17).T_world_camera.matrix()).norm() == 0.0);
  CHECK((a.at(17).T_world_camera.matrix() - c.at(17).T_world_camera.matrix()).norm() > 1.0);
  CHECK_FALSE(parse_scenario("spin").ok());
}

TEST_CASE("sim: the shutter sets the motion blur: none at 0, fewer and shorter smears when shorter") {
  const Trajectory traj(ScenarioKind::OutOfView, test_scene(), 300, 1);
  int blurred[3] = {0, 0, 0}, sub_sum[3] = {0, 0, 0};
  const double shutters[3] = {0.0, 0.25, kDefaultShutter};
  for (int i = 0; i < 300; ++i)
    for (int s = 0; s < 3; ++s) {
      const int n = traj.blur_subframes(i, shutters[s]);
      blurred[s] += n > 1 ? 1 : 0;
      sub_sum[s] += n;
    }
  MESSAGE("blurred frames at shutter 0 / 0.25 / 0.5: " << blurred[0] << " / " << blurred[1] << " / " << blurred[2]);
  CHECK(blurred[0] == 0);
  CHECK(sub_sum[0] == 300);
  CHECK(blurred[1] > 0);
  CHECK(blurred[1] < blurred[2]);
  CHECK(sub_sum[1] < sub_sum[2]);
  // The default argument is the default shutter.
  for (int i = 100; i < 130; ++i) CHECK(traj.blur_subframes(i) == traj.blur_subframes(i, kDefaultShutter));
}
