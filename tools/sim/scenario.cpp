#include "tools/sim/scenario.h"

#include <algorithm>
#include <cmath>

#include "tools/sim/breathing.h"
#include "tools/sim/rng.h"

namespace st::sim {
namespace {

constexpr double kDeg = M_PI / 180.0;

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3.0 - 2.0 * t);
}

Vec3 spherical(double azimuth, double elevation, double distance) {
  return distance * Vec3(std::cos(elevation) * std::cos(azimuth),
                         std::cos(elevation) * std::sin(azimuth), std::sin(elevation));
}

}  // namespace

Result<ScenarioKind> parse_scenario(std::string_view name) {
  if (name == "orbit") return ScenarioKind::Orbit;
  if (name == "fast") return ScenarioKind::Fast;
  if (name == "outofview") return ScenarioKind::OutOfView;
  if (name == "manipulation") return ScenarioKind::Manipulation;
  if (name == "invivo") return ScenarioKind::InVivo;
  if (name == "newview") return ScenarioKind::NewView;
  return make_error("unknown scenario '" + std::string(name) +
                    "': use orbit, fast, outofview, manipulation, invivo or newview");
}

const char* scenario_name(ScenarioKind kind) {
  switch (kind) {
    case ScenarioKind::Orbit: return "orbit";
    case ScenarioKind::Fast: return "fast";
    case ScenarioKind::OutOfView: return "outofview";
    case ScenarioKind::Manipulation: return "manipulation";
    case ScenarioKind::InVivo: return "invivo";
    case ScenarioKind::NewView: return "newview";
  }
  return "?";
}

SE3 look_at(const Vec3& eye, const Vec3& target, double roll_rad) {
  const Vec3 z = (target - eye).normalized();
  const Vec3 x = z.cross(Vec3::UnitZ()).normalized();
  const Vec3 y = z.cross(x);
  Mat3 R;
  R << x, y, z;
  const Mat3 roll = Eigen::AngleAxisd(roll_rad, Vec3::UnitZ()).toRotationMatrix();
  return SE3(R * roll, eye);
}

Trajectory::Trajectory(ScenarioKind kind, const Scene& scene, int frames, std::uint64_t seed)
    : kind_(kind),
      frames_(std::max(frames, 2)),
      box_(scene.organ_box_world),
      T_world_model_rest_(scene.T_world_model_rest),
      tremor_(seed + 101) {
  scale_ = std::clamp(box_.size().maxCoeff() / 150.0, 0.7, 2.0);
  Rng rng(mix_seed(seed, 77));
  azimuth0_ = rng.uniform(-M_PI, M_PI);
  phase_ = rng.uniform(0.0, 2.0 * M_PI);
  // Grasp point: the organ vertex highest up in the thinner (+x) half, a
  // spot an instrument can reach from above.
  double best = -1e9;
  for (int i = 0; i < scene.organ.vertex_count(); ++i) {
    const Vec3 p_world = T_world_model_rest_ * scene.organ.vertex(i);
    const double score = p_world.z() + 0.4 * p_world.x() - 0.2 * std::abs(p_world.y());
    if (p_world.x() > 0.15 * box_.size().x() && score > best) {
      best = score;
      grasp_model_ = scene.organ.vertex(i);
    }
  }
  const double side = azimuth0_ - 70.0 * kDeg;  // away from the orbit sweep
  hover_world_ = Vec3(0.05 * box_.size().x(), -0.1 * box_.size().y(), box_.max.z() + 6.0);
  trocar_world_ = Vec3(0, 0, 0) + spherical(side, 50.0 * kDeg, 260.0);
  if (kind_ == ScenarioKind::NewView) {  // close_view's surface distances
    for (int i = 0; i < scene.organ.vertex_count(); i += 4) organ_world_.push_back(T_world_model_rest_ * scene.organ.vertex(i));
    arrival_ = close_view(0.52);  // constant: where the travel ends
  }
}

Trajectory::View Trajectory::orbit_view(double u) const {
  const double w = 2.0 * M_PI * u;
  const double az = azimuth0_ + 100.0 * kDeg * u;
  const double el = (58.0 + 12.0 * std::sin(1.3 * w + phase_)) * kDeg;
  const double dist = scale_ * (128.0 + 28.0 * std::sin(0.9 * w + 1.0 + phase_));
  const Vec3 target(15.0 * std::sin(w), 10.0 * std::cos(0.7 * w), 0.25 * box_.max.z());
  return {target + spherical(az, el, dist), target, 10.0 * kDeg * std::sin(0.8 * w + phase_)};
}

Trajectory::View Trajectory::fast_view(double u) const {
  // Two bursts where the path jumps ahead: ~35 deg of orbit in ~0.4 s.
  const double jump = 0.35 * (smoothstep(0.28, 0.32, u) + smoothstep(0.68, 0.72, u));
  View v = orbit_view(0.5 * u + jump);
  const double burst = std::exp(-std::pow((u - 0.3) / 0.02, 2)) + std::exp(-std::pow((u - 0.7) / 0.02, 2));
  v.roll_rad += burst * 8.0 * kDeg * std::sin(40.0 * u);
  return v;
}

Trajectory::View Trajectory::outofview_view(double u) const {
  // Look away (at the abdominal wall) in [0.42, 0.56], then come back to
  // the view of u - 0.45: a place already seen. While fully away the pose
  // does not depend on the base view, so the switch at 0.5 is seamless.
  const View base = u < 0.5 ? orbit_view(u) : orbit_view(u - 0.45);
  const double away = smoothstep(0.36, 0.42, u) * (1.0 - smoothstep(0.56, 0.62, u));
  const Vec3 away_dir(std::cos(azimuth0_ + 2.2), std::sin(azimuth0_ + 2.2), 0.0);
  const Vec3 away_target = 230.0 * away_dir + Vec3(0, 0, box_.max.z());
  const View start = orbit_view(0.42);
  const Vec3 away_eye = start.eye + 0.35 * (away_target - start.target);
  View v = base;
  v.target = base.target + away * (away_target - base.target);
  v.eye = base.eye + away * (away_eye - base.eye);
  v.roll_rad = base.roll_rad + away * (start.roll_rad - base.roll_rad);
  return v;
}

// newview: orbit the near side for a third of the sequence, turn away to
// the abdominal wall (as outofview does), travel while looking at the wall
// to a place the map never saw from, and turn back to the organ there:
// 100 deg further round it and 12-48 deg lower (more than 35 deg from any
// earlier view), at 38 mm from the nearest surface (the orbit: 80 mm and
// more); then sweep the far side at that distance. Turn away in [0.32,
// 0.38], travel in [0.38, 0.52], pan back in [0.52, 0.62].
Trajectory::View Trajectory::newview_view(double u) const {
  const Vec3 away_dir(std::cos(azimuth0_ + 2.2), std::sin(azimuth0_ + 2.2), 0.0);
  const Vec3 wall = 230.0 * away_dir + Vec3(0, 0, box_.max.z());
  const View start = orbit_view(0.38);
  const Vec3 away_eye = start.eye + 0.35 * (wall - start.target);
  if (u < 0.38) {
    const View base = orbit_view(u);
    const double k = smoothstep(0.32, 0.38, u);
    return {base.eye + k * (away_eye - base.eye), base.target + k * (wall - base.target),
            base.roll_rad + k * (start.roll_rad - base.roll_rad)};
  }
  if (u < 0.52) {
    const double k = smoothstep(0.38, 0.52, u);
    return {away_eye + k * (arrival_.eye - away_eye), wall, start.roll_rad + k * (arrival_.roll_rad - start.roll_rad)};
  }
  // Turning back pans the view (its azimuth and elevation about the eye),
  // not a straight line from the wall to the organ, which passes by the eye.
  const View base = close_view(u);
  const double k = smoothstep(0.52, 0.62, u);
  const Vec3 from = wall - base.eye, to = base.target - base.eye;
  const double az0 = std::atan2(from.y(), from.x()), el0 = std::atan2(from.z(), from.head<2>().norm());
  const double az1 = std::atan2(to.y(), to.x()), el1 = std::atan2(to.z(), to.head<2>().norm());
  const double turn = std::remainder(az1 - az0, 2.0 * M_PI);  // the shorter way round
  return {base.eye, base.eye + spherical(az0 + k * turn, el0 + k * (el1 - el0), to.norm()), base.roll_rad};
}

Trajectory::View Trajectory::close_view(double u) const {
  const double s = std::clamp((u - 0.52) / 0.48, 0.0, 1.0);  // 0 on arrival, 1 at the end
  const double az = azimuth0_ + (38.0 + 100.0 + 50.0 * s) * kDeg;
  const double el = (28.0 + 6.0 * std::sin(M_PI * s)) * kDeg;
  const Vec3 target(0.0, 0.0, 0.25 * box_.max.z());
  // The eye on the ray from the target where the nearest organ vertex is
  // kClose away: coming in from outside in 8 mm steps, then halving the
  // last step.
  constexpr double kClose = 38.0;
  const Vec3 d = spherical(az, el, 1.0);
  const auto nearest = [&](double t) {
    const Vec3 eye = target + t * d;
    double best = 1e30;
    for (const Vec3& p : organ_world_) best = std::min(best, (p - eye).squaredNorm());
    return std::sqrt(best);
  };
  double outside = 400.0, inside = outside;
  while (inside > 0.0 && nearest(inside) > kClose) {
    outside = inside;
    inside -= 8.0;
  }
  for (int i = 0; i < 12; ++i) {
    const double mid = 0.5 * (inside + outside);
    (nearest(mid) > kClose ? outside : inside) = mid;
  }
  return {target + outside * d, target, 8.0 * kDeg * std::sin(2.0 * M_PI * s)};
}

Trajectory::View Trajectory::manipulation_view(double u) const {
  // Close enough that the organ overfills the image: parts leave the edges.
  const double w = 2.0 * M_PI * u;
  const double az = azimuth0_ + 20.0 * kDeg * std::sin(w);
  const Vec3 target(0.1 * box_.size().x(), 0.0, 0.3 * box_.max.z());
  return {target + spherical(az, 62.0 * kDeg, scale_ * (115.0 + 8.0 * std::cos(w))), target,
          5.0 * kDeg * std::sin(w)};
}

SE3 Trajectory::organ_motion(double u) const {
  if (kind_ != ScenarioKind::Manipulation) return T_world_model_rest_;
  // Pulled up at the grasp point and turned: tilt about an axis through the
  // far (-x) lobe, plus a twist about the vertical. Up, hold, back down.
  const double s = smoothstep(0.1, 0.4, u) * (1.0 - smoothstep(0.7, 0.95, u));
  const Vec3 pivot(box_.min.x() + 0.2 * box_.size().x(), 0.0, box_.min.z());
  const Mat3 R = (Eigen::AngleAxisd(-28.0 * kDeg * s, Vec3::UnitY()) *
                  Eigen::AngleAxisd(14.0 * kDeg * s, Vec3::UnitZ()))
                     .toRotationMatrix();
  const SE3 about_pivot(R, pivot - R * pivot + Vec3(0, 0, 8.0 * s));
  return about_pivot * T_world_model_rest_;
}

SE3 Trajectory::instrument_pose(double u, const SE3& T_world_model) const {
  Vec3 tip = hover_world_ + Vec3(6.0 * std::sin(5.0 * u), 4.0 * std::cos(3.0 * u), 0);
  if (kind_ == ScenarioKind::Manipulation) tip = T_world_model * grasp_model_;
  const Vec3 axis = (trocar_world_ - tip).normalized();  // instrument +z
  const Vec3 x = axis.unitOrthogonal();
  Mat3 R;
  R << x, axis.cross(x), axis;
  return SE3(R, tip + 12.0 * axis);  // the jaw tip (z = -12) touches `tip`
}

SE3 Trajectory::to_pose(const View& v, double t) const {
  // Hand tremor: ~1 mm and ~0.5 deg, smooth at ~2 Hz.
  const auto f = static_cast<float>(t * 2.0);
  const Vec3 shake(tremor_.gradient(f, 0.5f, 0.5f), tremor_.gradient(f, 10.5f, 0.5f),
                   tremor_.gradient(f, 20.5f, 0.5f));
  const double roll_shake = 0.6 * kDeg * static_cast<double>(tremor_.gradient(f, 30.5f, 0.5f));
  return look_at(v.eye + 1.2 * shake, v.target + 2.0 * shake.reverse(), v.roll_rad + roll_shake);
}

WorldState Trajectory::at(double frame) const {
  const double u = frame / (frames_ - 1);
  const double t_s = frame / 30.0;
  View v;
  switch (kind_) {
    case ScenarioKind::Fast: v = fast_view(u); break;
    case ScenarioKind::OutOfView: v = outofview_view(u); break;
    case ScenarioKind::NewView: v = newview_view(u); break;
    case ScenarioKind::Manipulation: v = manipulation_view(u); break;
    case ScenarioKind::Orbit:
    case ScenarioKind::InVivo: v = orbit_view(u); break;
  }
  WorldState s;
  s.T_world_camera = to_pose(v, t_s);
  s.T_world_model = organ_motion(u);
  s.T_world_instrument = instrument_pose(u, s.T_world_model);
  s.breath = BreathingField::phase(t_s);
  return s;
}

int Trajectory::blur_subframes(int frame, double shutter) const {
  // Blur where the scope turns more than 1 deg or moves > 2 mm while the
  // shutter is open (a ~10 px smear at 1280x720; by default half the frame
  // interval). The sub-frames sample the exposure densely enough for a
  // continuous smear, as a real sensor integrates it: about 0.3 deg of view
  // apart (~5 px at 1280x720), up to 9 sub-frames (the simulator's 20
  // frames/s budget), rather than always 5 ghost copies (5 sub-frames of a
  // 60 px smear were 15 px apart, each copy with sharp corners of its own).
  // Odd, so one sub-frame sits at the frame time (the labels come from it).
  if (!(shutter > 0.0)) return 1;  // an instantaneous exposure: no smear
  const WorldState a = at(frame - 0.5 * shutter), b = at(frame + 0.5 * shutter);
  const PoseDelta d = pose_delta(a.T_model_camera(), b.T_model_camera());
  if (!(d.angle_deg > 1.0 || d.distance_mm > 2.0)) return 1;
  const double depth_mm = std::max(30.0, at(frame).T_model_camera().translation().norm());
  const double sweep_deg = d.angle_deg + d.distance_mm / depth_mm * 180.0 / M_PI;
  const int n = std::clamp(static_cast<int>(std::ceil(sweep_deg / 0.3)) + 1, 5, 9);
  return n | 1;
}

}  // namespace st::sim
