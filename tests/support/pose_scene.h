// Synthetic 2D-3D correspondence scenes on the real CT liver mesh
// (../shared/data/liver/liver.ply) for the pose solvers' tests and bench:
// a laparoscope 50-150 mm from the organ surface, fx ~ 1000, 1280x720.
// Test-only: allocates freely.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/geometry/camera.h"
#include "core/pose/correspondences.h"
#include "core/mesh/mesh.h"
#include "core/geometry/se3.h"

namespace st::test {

struct LiverMesh {
  std::vector<Vec3> vertices;                 // mm, CT frame
  std::vector<std::array<int, 3>> triangles;  // outward normals
};
// Reads the binary little-endian PLY (float x y z, uchar-int faces). Empty
// mesh when the file is missing or not in that form.
LiverMesh load_liver_mesh();

struct PoseSceneOptions {
  int num_points = 300;
  double outlier_ratio = 0.0;  // fraction of correspondences replaced by gross outliers
  double noise_px = 0.0;       // level-0 pixel noise sigma (scaled by 1.2^octave)
  int max_octave = 7;          // octaves drawn uniformly in [0, max_octave]
  double distance_mm = 100.0;  // camera to the looked-at surface point
  std::uint32_t seed = 1;
};

struct PoseScene {
  Pinhole K{1000.0, 1000.0, 639.5, 359.5, 1280, 720};
  SE3 T_camera_model;  // ground truth
  std::vector<Vec3> p_model;
  std::vector<Vec2> px_ideal;
  std::vector<double> information;
  std::vector<int> octave;
  std::vector<std::uint8_t> is_outlier;

  Correspondences view() const {
    return {p_model.data(), px_ideal.data(), information.data(), static_cast<int>(p_model.size())};
  }
};

// Camera looking at a random front-facing point of the liver from
// distance_mm along its normal (tilted up to ~30 deg, random roll); points
// sampled on triangles that face the camera, lie 50-150 mm deep and project
// into the image (self-occlusion is ignored: pose maths does not need it).
PoseScene make_liver_scene(const PoseSceneOptions& opt);

// Distance between the camera centres of two poses T_camera_model, mm:
// independent of where the model frame's origin lies (the CT frame's origin
// is far from the liver, so pose_delta's translation mixes in rotation error).
inline double camera_centre_distance_mm(const SE3& a, const SE3& b) {
  return (a.inverse().translation() - b.inverse().translation()).norm();
}

// A pose perturbed by rotation_deg about a random axis and translation_mm
// in a random direction (a constant-velocity prediction error).
SE3 perturb(const SE3& T, double rotation_deg, double translation_mm, std::uint32_t seed);

// Mean image distance (px) between where every stride-th vertex of mesh
// projects at T and at truth (both T_camera_model), over the vertices in
// front of both cameras that the truth puts inside the image; their number
// into *count if not null (0: the result is meaningless).
double vertex_reprojection_px(const Mesh& mesh, const Pinhole& K, const SE3& T, const SE3& truth, int stride,
                              int* count = nullptr);

}  // namespace st::test
