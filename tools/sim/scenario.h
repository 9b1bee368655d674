// Scenarios: what the scope and the organ do over a sequence. Every pose is
// a smooth function of the (fractional) frame index, so motion blur can
// sample sub-frame poses and the ground truth is exact by construction:
// T_model_camera = T_world_model^-1 * T_world_camera.
#pragma once

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "core/base/result.h"
#include "core/geometry/se3.h"
#include "tools/sim/noise.h"
#include "tools/sim/scene.h"

namespace st::sim {

// Fraction of the frame interval the shutter is open (motion blur).
inline constexpr double kDefaultShutter = 0.5;

enum class ScenarioKind { Orbit, Fast, OutOfView, Manipulation, InVivo, NewView };

Result<ScenarioKind> parse_scenario(std::string_view name);
const char* scenario_name(ScenarioKind kind);

// The world at one instant. World z is up (towards the scope).
struct WorldState {
  SE3 T_world_camera;
  SE3 T_world_model;       // the organ (moves only in manipulation)
  SE3 T_world_instrument;  // instrument frame: jaw tip at z = -12, shaft along +z
  // Breathing phase (breathing.h): 0 at rest, 1 at the full displacement;
  // the renderer scales it by its amplitude (none by default).
  double breath = 0.0;
  SE3 T_model_camera() const { return T_world_model.inverse() * T_world_camera; }
};

class Trajectory {
 public:
  Trajectory(ScenarioKind kind, const Scene& scene, int frames, std::uint64_t seed);

  // The state at a fractional frame index in [-1, frames] (sub-frames).
  WorldState at(double frame) const;
  // Sub-frames to average for frame i, the shutter open for `shutter` of
  // the frame interval (0..1) centred on the frame time: 1, or 5..9 (odd)
  // where the image moves fast in that time, more for a longer smear.
  int blur_subframes(int frame, double shutter = kDefaultShutter) const;
  int frames() const { return frames_; }
  ScenarioKind kind() const { return kind_; }

 private:
  struct View {  // a scope pose as a look-at: position, target, roll
    Vec3 eye, target;
    double roll_rad;
  };
  View orbit_view(double u) const;
  View fast_view(double u) const;
  View outofview_view(double u) const;
  View newview_view(double u) const;
  View close_view(double u) const;  // newview after the return: near, from the far side
  View manipulation_view(double u) const;
  SE3 organ_motion(double u) const;  // T_world_model
  SE3 instrument_pose(double u, const SE3& T_world_model) const;
  SE3 to_pose(const View& v, double t) const;

  ScenarioKind kind_;
  int frames_;
  Box box_;             // organ box at rest, world
  SE3 T_world_model_rest_;
  Vec3 grasp_model_;    // instrument contact point on the organ, model frame
  Vec3 hover_world_;    // where the instrument tip waits when not grasping
  Vec3 trocar_world_;   // the instrument's port in the abdominal wall
  std::vector<Vec3> organ_world_;  // newview: organ vertices at rest, world (every 4th)
  View arrival_{};                 // newview: close_view at the end of the travel
  double scale_ = 1.0;  // organ size / 150 mm: bigger organs are viewed from farther
  double azimuth0_;
  double phase_;
  Noise3 tremor_;
};

// Look-at pose: camera at eye looking at target, image "up" towards world
// +z, then rolled about the optical axis (OpenCV camera axes).
SE3 look_at(const Vec3& eye, const Vec3& target, double roll_rad);

}  // namespace st::sim
