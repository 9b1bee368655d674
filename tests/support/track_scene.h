// A small textured renderer of a mesh for the tracker tests, until the real
// simulator (tools/sim) provides sequences: the rasteriser's depth gives the
// model point of every pixel, whose colour is a 3D value-noise texture
// (fixed to the organ, so it moves with it) times a Lambert headlight term;
// the background is dark and flat. Test-only: allocates freely.
#pragma once

#include <cstdint>
#include <vector>

#include "core/geometry/camera.h"
#include "core/image/image.h"
#include "core/mesh/mesh.h"
#include "core/raster/rasterizer.h"
#include "core/tracking/tracker.h"
#include "core/geometry/se3.h"

namespace st::test {

// The CT liver (../shared/data/liver/liver.ply); FAILs the test if missing.
Mesh load_liver_for_tracking();

class TrackSceneRenderer {
 public:
  // K: the ideal pinhole of the frames (no distortion).
  void configure(const Mesh& mesh, const Pinhole& K);
  // Luma of the textured mesh seen from T_camera_model (K.width x K.height).
  void render(const SE3& T_camera_model, Image<std::uint8_t>* luma);

 private:
  MeshRasterizer raster_;
  Pinhole K_;
  std::vector<Vec3> normal_model_;  // per triangle, unit, outward
  Image<std::uint8_t> tmp_;
};

// A smooth camera path around the liver: the camera circles a point near
// the organ's centre at 230-260 mm (the surface ~120-170 mm away), swinging
// +-25 degrees in azimuth and +-10 in elevation with a slow roll.
std::vector<SE3> liver_orbit(const Mesh& mesh, int frames);

// Pinhole of the test frames: 640x360, fx = fy = 500.
inline Pinhole track_test_pinhole() { return {500.0, 500.0, 319.5, 179.5, 640, 360}; }

// The liver seen along liver_orbit(frames), rendered with TrackSceneRenderer
// at track_test_pinhole(): the ground truth and the luma frames.
struct RenderedOrbit {
  Mesh mesh;
  Pinhole K;
  std::vector<SE3> T_camera_model;
  std::vector<Image<std::uint8_t>> frames;
};
RenderedOrbit render_liver_orbit(int frames);
// render_liver_orbit(40), rendered once per test binary run.
const RenderedOrbit& liver_orbit40();

// The tracker's settings for the 640x360 test frames: 1000 features, a
// small map (3000 points, 12 keyframes), a keyframe every 3 degrees (so
// that bundle adjustment has work).
TrackerConfig small_tracker_config(const Pinhole& K);

// Largest distance in pixels between the projections (through s.K) of about
// 40 of the mesh's vertices under a reported pose and under the truth; 1e9
// when one is behind either camera. A pose more than a few pixels off is a
// wrong pose.
double reprojection_gap_px(const RenderedOrbit& s, const SE3& T_camera_model, const SE3& truth);

}  // namespace st::test
