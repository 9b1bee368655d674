// Camera placements around a mesh, shared by the rasteriser tests and the
// raster bench stage (header-only: the bench includes it without a build
// change).
#pragma once

#include <algorithm>
#include <cmath>

#include "core/geometry/camera.h"
#include "core/mesh/mesh.h"
#include "core/raster/rasterizer.h"
#include "core/geometry/se3.h"

namespace st::test {

// Centre of the axis-aligned bounding box (the liver is not centred).
inline Vec3 bbox_centre(const Mesh& m) {
  const auto [x0, x1] = std::minmax_element(m.x.begin(), m.x.end());
  const auto [y0, y1] = std::minmax_element(m.y.begin(), m.y.end());
  const auto [z0, z1] = std::minmax_element(m.z.begin(), m.z.end());
  return {0.5 * (double{*x0} + double{*x1}), 0.5 * (double{*y0} + double{*y1}),
          0.5 * (double{*z0} + double{*z1})};
}

// T_camera_model of a camera at distance_mm from target_model looking at it
// along view_dir_model (unit, from the camera towards the target), rolled by
// roll_rad about the optical axis. Camera axes: x right, y down, z forward.
inline SE3 look_at(const Vec3& target_model, const Vec3& view_dir_model, double distance_mm,
                   double roll_rad) {
  const Vec3 z = view_dir_model.normalized();
  const Vec3 helper = std::abs(z.z()) < 0.9 ? Vec3(0, 0, 1) : Vec3(1, 0, 0);
  const Vec3 x = helper.cross(z).normalized();
  const Vec3 y = z.cross(x);
  Mat3 R_model_camera;
  R_model_camera.col(0) = x;
  R_model_camera.col(1) = y;
  R_model_camera.col(2) = z;
  R_model_camera = R_model_camera * so3_exp(Vec3(0, 0, roll_rad));
  const Vec3 eye_model = target_model - distance_mm * z;
  return SE3(R_model_camera, eye_model).inverse();
}

// A full-resolution raster of K's image size, other settings default.
inline RasterConfig raster_config(const Pinhole& K) {
  RasterConfig cfg;
  cfg.width = K.width;
  cfg.height = K.height;
  return cfg;
}

// The bench view: 1280x720, fx = fy = 1000, principal point at the centre.
inline Pinhole bench_pinhole() { return {1000.0, 1000.0, 639.5, 359.5, 1280, 720}; }

}  // namespace st::test
